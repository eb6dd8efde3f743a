"""Places in a bin for blocks of any size (busarm.apps.pick_sort.bins): blocks of the usual
size fill the seven places in order; of mixed sizes, every block put in a bin lies inside
its tray, none overlaps another of its layer, and one of the second layer stands on a block
no smaller than itself less the slack. A block is let go no lower than just over the floor,
its pads over every wall and block they stand above, and, with little room, low."""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st

from busarm.apps.pick_sort.bins import (
    BIN_PLACES,
    BIN_SLOTS_MM,
    SLOT_GAP_MM,
    STACK_DROP_MM,
    TIGHT_ROOM_MM,
    TOP_SLACK_MM,
    TRAY_FLOOR_MM,
    TRAY_INSIDE_MM,
    TRAY_WALL_MM,
    BinPlaces,
)
from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner
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


USUAL_RELEASE_MM = 45.0


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(20.0, 45.0), min_size=1, max_size=8),
       st.floats(0.0, 10.0))
@example([39.0, 45.0, 22.0], 0.0)  # beside a pair whose top block is the wider
def test_a_block_is_let_go_low_where_it_has_little_room_and_its_pads_over_all_under_them(
        sizes: list[float], opening_mm: float) -> None:
    places = BinPlaces({"red": BIN}, PLANNER)
    stood: list[tuple[float, float, float, float]] = []  # x, y, side, top (mm)
    for size in sizes:
        if places.is_full("red", size):
            continue
        x, y, layer, roll = places.next_spot("red", size_mm=size)
        _, release = places.heights_mm("red", size, 75.0, USUAL_RELEASE_MM)
        gap = size + opening_mm
        got = places.release_mm("red", release, roll, gap)
        dx, dy = x - BIN[0], y - BIN[1]
        room = min([TRAY_INSIDE_MM - max(abs(dx), abs(dy)) - size / 2,
                    *(max(abs(x - ox), abs(y - oy)) - (size + side) / 2
                      for ox, oy, side, _ in stood)])
        at = (x, y, got)
        pads = PLANNER.pads(GraspPlan(-90.0, roll, at, at, at), gap, tall=True)
        # The tray's walls, 4 mm thick outside its 82 mm inside, drawn here anew.
        walls = [Footprint.rectangle(BIN[0] + sx * 43.0, BIN[1] + sy * 43.0,
                                     4.0 if sx else 90.0, 90.0 if sx else 4.0, 0.0)
                 for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1))]
        under = [*((w, TRAY_WALL_MM) for w in walls),
                 *((Footprint.square(ox, oy, side, 0.0), top)
                   for ox, oy, side, top in stood  # (not the block it is set on)
                   if not (layer == 1 and abs(ox - x) < 5 and abs(oy - y) < 5))]
        over = [top + STACK_DROP_MM for thing, top in under
                if any(p.overlaps(thing, PLANNER.margin_mm) for p in pads)]
        assert all(got >= top for top in over), (got, over)  # the pads clear what is under
        assert got >= TRAY_FLOOR_MM + size / 2  # never pressed into the floor
        if layer == 0 and room < TIGHT_ROOM_MM:  # as low as the pads let it
            assert got == max([TRAY_FLOOR_MM + STACK_DROP_MM + size / 2, *over]), (got, over)
        else:  # where it was let go before, or higher over a tall neighbour
            assert got == max([release, *over]), (got, release, over)
        below = next((t for ox, oy, _, t in stood if layer and abs(ox - x) < 5
                      and abs(oy - y) < 5), TRAY_FLOOR_MM)
        stood.append((x, y, size, below + size))
