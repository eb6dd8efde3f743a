"""Places in a bin for blocks of any size (busarm.apps.pick_sort.bins): blocks of the usual
size fill the seven places in order; of mixed sizes, every block put in a bin lies inside
its tray, none overlaps another of its layer, and one of the second layer stands on a block
no smaller than itself less the slack."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.apps.pick_sort.bins import (
    BIN_PLACES,
    BIN_SLOTS_MM,
    SLOT_GAP_MM,
    TOP_SLACK_MM,
    TRAY_INSIDE_MM,
    BinPlaces,
)
from busarm.apps.pick_sort.grasp import GraspPlanner
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics

CONFIG = load_arm_config()
PLANNER = GraspPlanner(ArmKinematics.from_config(CONFIG), 0.0, 30.0, 60.0, 75.0)
BIN = (60.0, 180.0)


def test_blocks_of_the_usual_size_fill_the_seven_places_in_order() -> None:
    places = BinPlaces({"red": BIN}, PLANNER)
    for slot, layer in BIN_PLACES:
        x, y, got_layer, _ = places.next_spot("red", size_mm=30.0)
        assert (round(x - BIN[0], 6), round(y - BIN[1], 6), got_layer) == (
            *BIN_SLOTS_MM[slot], layer)
    assert places.is_full("red", 30.0) and places.count("red") == len(BIN_PLACES)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(20.0, 45.0), min_size=1, max_size=10))
def test_blocks_of_any_size_fit_the_tray_and_each_other(sizes: list[float]) -> None:
    places = BinPlaces({"red": BIN}, PLANNER)
    put: list[tuple[float, float, int, float]] = []
    for size in sizes:
        if places.is_full("red", size):
            continue
        x, y, layer, _ = places.next_spot("red", size_mm=size)
        dx, dy = x - BIN[0], y - BIN[1]
        assert max(abs(dx), abs(dy)) + size / 2 <= TRAY_INSIDE_MM, (size, dx, dy)
        for ox, oy, other_layer, other in put:
            if other_layer == layer:
                reach = (size + other) / 2 + SLOT_GAP_MM - 1e-9
                assert abs(dx - ox) >= reach or abs(dy - oy) >= reach, (put, size, dx, dy)
        if layer == 1:  # on a block of the first layer, about centred, not much smaller
            assert any(other_layer == 0 and other + TOP_SLACK_MM >= size
                       and abs(ox - dx) < 5 and abs(oy - dy) < 5
                       for ox, oy, other_layer, other in put), (put, size, dx, dy)
        put.append((dx, dy, layer, size))
