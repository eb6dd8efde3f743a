"""Pick-and-sort on tables like real ones: full bins, neighbours close by (issue 12).
Scored against the twin's truth, which the sorter never reads."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from busarm.apps.pick_sort.bins import TRAY_FLOOR_MM, in_tray
from busarm.apps.pick_sort.sorter import BIN_SLOTS_MM, IN_BIN_MM, PickSorter, RunReport
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.clutter import clutter_scene
from busarm.twin.scene import DEFAULT_BINS, Block, Distractor, Lighting, Scene
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import BlockState

pytestmark = pytest.mark.slow  # whole pick-sort runs on the twin


@pytest.fixture(scope="module")
def calibration(twin_calibration: tuple[Path, Path]) -> tuple[Path, Path]:
    """The twin's camera calibration, made once per run by our flows (tests/conftest.py)."""
    return twin_calibration


def _robot(calibration: tuple[Path, Path], scene: Scene) -> Robot:
    """The twin with ``scene`` on its table, its camera calibrated by ``calibration``."""
    return Robot.open(RobotConfig(TwinSpec(scene=scene),
                                  camera=CameraSpec(intrinsics=calibration[0],
                                                    hand_eye=calibration[1])))


def test_a_colour_with_more_blocks_than_a_layer_is_stacked_in_its_bin(
        calibration: tuple[Path, Path]) -> None:
    spots = [(150.0, -90.0), (150.0, -30.0), (150.0, 30.0), (150.0, 90.0),
             (215.0, -60.0), (215.0, 0.0)]
    scene = Scene(blocks=tuple(Block("red", x, y, 10.0 * i) for i, (x, y) in enumerate(spots)),
                  bins=DEFAULT_BINS[:1])
    with _robot(calibration, scene) as robot:
        report = PickSorter(robot, colors=["red"]).run()
        assert robot.twin is not None
        truth = robot.twin.blocks()
        bx, by = robot.bins["red"]
    assert report.totals()["sorted"] == len(spots), [b.to_dict() for b in report.blocks]
    for block in truth:  # all in the bin, the last two on top of the first layer
        assert math.hypot(block.x_mm - bx, block.y_mm - by) < IN_BIN_MM, block
    layers = sorted(b.z_mm for b in truth)
    floor = layers[0]  # the first layer stands on the tray's floor
    assert all(abs(z - floor) < 1.0 for z in layers[: len(BIN_SLOTS_MM)]), layers
    # ... the second square on it, one block higher, not tipped over.
    assert all(abs(z - floor - 30.0) < 1.5 for z in layers[len(BIN_SLOTS_MM):]), layers
    assert all(b.is_upright for b in truth)


def test_a_full_bin_leaves_the_rest_on_the_table_with_a_reason(
        calibration: tuple[Path, Path]) -> None:
    spots = [(x, y) for x in (135.0, 185.0, 235.0) for y in (-75.0, -20.0, 35.0)]
    scene = Scene(blocks=tuple(Block("red", x, y, 0.0) for x, y in spots),
                  bins=DEFAULT_BINS[:1])
    with _robot(calibration, scene) as robot:
        sorter = PickSorter(robot, colors=["red"])
        report = sorter.run()
        assert robot.twin is not None
        truth = robot.twin.blocks()
        bx, by = robot.bins["red"]
    outcomes = [b.outcome for b in report.blocks]
    # Four, and three on them (a fourth on top would leave no room for the fingers).
    assert outcomes.count("sorted") == sorter.places.capacity == 7, outcomes
    skipped = [b for b in report.blocks if b.outcome == "skipped"]
    assert len(skipped) == 2 and all(b.reason.startswith("bin full") for b in skipped), skipped
    in_bin = [b for b in truth if math.hypot(b.x_mm - bx, b.y_mm - by) < IN_BIN_MM]
    assert len(in_bin) == 7  # and the others were never dropped beside it
    left = [b for b in truth if b not in in_bin]
    assert len(left) == 2
    assert all(math.hypot(b.x_mm - bx, b.y_mm - by) > 100 for b in left)


def test_a_block_set_down_to_be_taken_again_is_carried_over_a_cup(
        calibration: tuple[Path, Path]) -> None:
    # The far block is taken tilted once the first layer is full; it would lean on the
    # second, so it is set down near the base first, and the cup stands on that way.
    spots = [(150.0, -90.0), (150.0, -30.0), (150.0, 30.0), (150.0, 90.0), (290.0, -60.0)]
    cup = Distractor("cylinder", "white", 205.0, -95.0, 40.0, 40.0, 70.0, 0.0, 80.0)
    scene = Scene(blocks=tuple(Block("red", x, y, 0.0) for x, y in spots),
                  bins=DEFAULT_BINS[:1], distractors=(cup,))
    with _robot(calibration, scene) as robot:
        assert robot.twin is not None
        before = robot.twin.distractor_positions_mm()[0]
        said: list[str] = []
        report = PickSorter(robot, colors=["red"], progress=said.append).run()
        after = robot.twin.distractor_positions_mm()[0]
        truth = robot.twin.blocks()
        bx, by = robot.bins["red"]
    assert any("set down at" in m for m in said), said  # the far one was restaged
    assert report.totals()["sorted"] == len(spots), [b.to_dict() for b in report.blocks]
    assert all(math.hypot(b.x_mm - bx, b.y_mm - by) < IN_BIN_MM for b in truth), truth
    assert math.dist(before[:2], after[:2]) < 2.0, (before, after)


def test_blocks_the_survey_cannot_make_out_are_looked_for_facing_them(
        calibration: tuple[Path, Path]) -> None:
    # Eight green blocks; once a 2 x 2 group has been pushed apart, the survey's picture
    # shows six of them, turned two ways, as one blob it cannot split: facing them, they
    # are seen one by one. Seven fit the bin, the eighth is left with "bin full".
    scene = clutter_scene(1008, 9, ("red", "green", "blue"))
    assert [b.color for b in scene.blocks].count("green") == 8
    with _robot(calibration, scene) as robot:
        report = PickSorter(robot, colors=["red", "green", "blue"]).run()
    outcomes = [(b.outcome, b.reason) for b in report.blocks]
    assert [o for o, _ in outcomes].count("sorted") == 7, outcomes
    assert [r for o, r in outcomes if o != "sorted"] == [
        "bin full: the green bin holds 7 blocks"], outcomes


Sorted = tuple[RunReport, list[BlockState], dict[str, tuple[float, float]]]


def _touching(calibration: tuple[Path, Path], colors: list[str],
              offsets: list[tuple[float, float]], yaw_deg: float) -> Sorted:
    """Sort blocks of ``colors`` put side by side (``offsets`` in block sides, turned
    ``yaw_deg``, around (190, -20) mm); the report, the truth after, the bins."""
    parked = [(130.0, -100.0), (130.0, -20.0), (130.0, 60.0), (210.0, -100.0)]
    scene = Scene(blocks=tuple(Block(c, x, y, 0.0) for c, (x, y) in zip(colors, parked,
                                                                         strict=False)),
                  bins=tuple(b for b in DEFAULT_BINS if b.color in colors))
    a = math.radians(yaw_deg)
    with _robot(calibration, scene) as robot:
        assert robot.twin is not None
        robot.twin.place_blocks({  # touching: closer than a scene file may put them
            k: (190.0 + 30.0 * (u * math.cos(a) - v * math.sin(a)),
                -20.0 + 30.0 * (u * math.sin(a) + v * math.cos(a)), yaw_deg, None)
            for k, (u, v) in enumerate(offsets)})
        robot.clock.sleep(0.3)
        report = PickSorter(robot, colors=sorted(set(colors))).run()
        return report, list(robot.twin.blocks()), dict(robot.bins)


@pytest.mark.parametrize("yaw", [0.0, -60.0])
def test_a_row_of_four_touching_blocks_of_one_colour_is_all_sorted(
        calibration: tuple[Path, Path], yaw: float) -> None:
    report, truth, bins = _touching(calibration, ["red"] * 4,
                                    [(-1.5, 0), (-0.5, 0), (0.5, 0), (1.5, 0)], yaw)
    assert [b.outcome for b in report.blocks] == ["sorted"] * 4
    for block in truth:
        assert math.hypot(block.x_mm - bins["red"][0],
                          block.y_mm - bins["red"][1]) < IN_BIN_MM


@pytest.mark.parametrize(("colors", "yaw"), [(["red", "green", "blue", "red"], 0.0),
                                             (["green"] * 4, 25.0)])
def test_a_touching_2x2_group_is_pushed_apart_and_all_sorted(
        calibration: tuple[Path, Path], colors: list[str], yaw: float) -> None:
    report, truth, bins = _touching(calibration, colors,
                                    [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)], yaw)
    outcomes = [b.outcome for b in report.blocks]
    assert outcomes.count("sorted") == 4 and len(outcomes) == 4, outcomes
    for block in truth:
        bx, by = bins[block.color]
        assert math.hypot(block.x_mm - bx, block.y_mm - by) < IN_BIN_MM


def test_a_descent_onto_an_unseen_obstacle_backs_off_and_the_run_goes_on(
        calibration: tuple[Path, Path]) -> None:
    parked = ((140.0, 200.0), (190.0, 170.0))
    scene = Scene(blocks=(Block("red", 190.0, -40.0, 10.0),
                          *(Block("yellow", x, y) for x, y in parked)),
                  bins=DEFAULT_BINS[:1])
    with _robot(calibration, scene) as robot:
        twin = robot.twin
        assert twin is not None
        events: list[str] = []

        def obstacle(step: str) -> None:
            events.append(step)
            red = twin.blocks()[0]
            a = math.radians(red.yaw_deg)
            if step == "above" and events.count("above") == 1:
                # Once the camera has looked: blocks land against two sides of the red
                # one, where the fingers go down whichever way they close.
                twin.place_blocks({
                    1: (red.x_mm + 30.5 * math.cos(a), red.y_mm + 30.5 * math.sin(a),
                        red.yaw_deg, None),
                    2: (red.x_mm - 30.5 * math.sin(a), red.y_mm + 30.5 * math.cos(a),
                        red.yaw_deg, None)})
            elif step == "survey" and events.count("above") == 1:
                twin.place_blocks({1: (*parked[0], 0.0, None), 2: (*parked[1], 0.0, None)})

        report = PickSorter(robot, colors=["red"], on_step=obstacle).run()
        truth = twin.blocks()[0]
        bx, by = robot.bins["red"]
    (red,) = report.blocks
    assert red.outcome == "sorted" and red.attempts == 2, red.to_dict()
    assert math.hypot(truth.x_mm - bx, truth.y_mm - by) < IN_BIN_MM
    assert report.stopped == ""


def test_a_block_whose_shape_its_neighbours_hide_waits_for_them_and_is_sorted(
        calibration: tuple[Path, Path]) -> None:
    # The clutter family's seed 42: a green block touching three blue ones, a diamond.
    # Hidden by them in most pictures and unsure of its height in one, the green one
    # was once left alone as "not a block"; it waits until they have gone, and once no
    # picture shows it as anything but a block's height, it is sorted.
    light = Lighting(intensity=1.04, key_azimuth_deg=-65.61, key_elevation_deg=59.19,
                     key_share=0.27, color_temp_k=5730.0)
    spots = [("green", 238.0, 71.07), ("blue", 258.19, 93.29), ("blue", 260.22, 50.87),
             ("blue", 280.42, 73.1)]
    scene = Scene(blocks=tuple(Block(c, x, y, -42.26) for c, x, y in spots),
                  bins=tuple(b for b in DEFAULT_BINS if b.color in ("green", "blue")),
                  lighting=light)
    with _robot(calibration, scene) as robot:
        report = PickSorter(robot, colors=["green", "blue"]).run()
        assert robot.twin is not None
        truth = robot.twin.blocks()
        bins = dict(robot.bins)
    assert [b.outcome for b in report.blocks].count("sorted") == 4, report.blocks
    for block in truth:
        assert math.hypot(block.x_mm - bins[block.color][0],
                          block.y_mm - bins[block.color][1]) < IN_BIN_MM, block


def test_two_large_blocks_stand_level_one_on_the_other_in_their_tray(
        calibration: tuple[Path, Path]) -> None:
    # Side by side they do not fit a tray: the first goes to a corner with 1.5 mm to the
    # walls. Dropped there from the usual height, a 43.5 mm cube bounced off a wall (here
    # it landed 9 mm off its place, under the second's; on lookalike seed 1001 it stayed
    # leaning on the wall, and the second, set on it, fell off).
    sizes = (43.5, 44.5)
    wooden = [0.7 * (size / 10.0) ** 3 for size in sizes]  # g: 60 for a 44 mm cube
    scene = Scene(blocks=(Block("green", 116.0, 73.0, 43.3, sizes[0], wooden[0]),
                          Block("green", 175.0, -45.0, -15.0, sizes[1], wooden[1])),
                  bins=tuple(b for b in DEFAULT_BINS if b.color == "green"))
    with _robot(calibration, scene) as robot:
        report = PickSorter(robot, colors=["green"]).run()
        assert robot.twin is not None
        truth = robot.twin.blocks()
        bx, by = robot.bins["green"]
    assert [b.outcome for b in report.blocks] == ["sorted"] * 2, report.blocks
    below, above = sorted(truth, key=lambda b: b.z_mm)
    assert all(b.is_upright and in_tray(b.x_mm, b.y_mm, (bx, by)) for b in truth), truth
    # Level: each at its own half-height over the one below (a lean raises it).
    assert abs(below.z_mm - (TRAY_FLOOR_MM + below.size_mm / 2)) < 1.0, below
    assert abs(above.z_mm - (TRAY_FLOOR_MM + below.size_mm + above.size_mm / 2)) < 1.0, above
    assert math.hypot(above.x_mm - below.x_mm, above.y_mm - below.y_mm) < 6.0, truth


def test_a_block_gone_from_its_bin_when_the_bins_are_checked_is_reported_failed(
        calibration: tuple[Path, Path]) -> None:
    scene = Scene(blocks=(Block("blue", 160.0, -40.0, 10.0), Block("blue", 170.0, 40.0, -5.0)),
                  bins=tuple(b for b in DEFAULT_BINS if b.color == "blue"))
    with _robot(calibration, scene) as robot:
        sorter = PickSorter(robot, colors=["blue"])
        report = sorter.run()
        assert [b.outcome for b in report.blocks] == ["sorted"] * 2, report.blocks
        assert robot.twin is not None
        robot.twin.place_block(1, 200.0, 150.0)  # a hand takes one out of the tray
        sorter.verify_bins(report)
    assert sorted(b.outcome for b in report.blocks) == ["failed", "sorted"], report.blocks
    assert [b.reason for b in report.blocks if b.outcome == "failed"] == [
        "not in its bin when the bins were checked (it fell out?)"]
