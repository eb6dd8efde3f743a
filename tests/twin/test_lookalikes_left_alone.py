"""Pick-and-sort on a table of cubes of several sizes among things in block colours that
are not blocks (issue 32), scored against the twin's truth: every cube in its bin, no
cup, disc, bar or tall box touched, binned or reported, and each said to be left alone."""

from __future__ import annotations

import math
from pathlib import Path

from busarm.apps.pick_sort.sorter import IN_BIN_MM, PickSorter
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.scene import DEFAULT_BINS, Block, Distractor, Scene
from busarm.twin.spec import TwinSpec

CUBES = (Block("blue", 160.0, -90.0, 10.0, 22.0), Block("red", 235.0, 60.0, -20.0, 42.0),
         Block("green", 150.0, 95.0, 30.0, 33.0))
LOOKALIKES = (Distractor("cylinder", "purple", 140.0, 10.0, 33.0, 33.0, 42.0),
              Distractor("box", "blue", 250.0, -60.0, 28.0, 28.0, 70.0, 15.0),
              Distractor("disc", "green", 225.0, 150.0, 45.0, 45.0, 5.0),
              Distractor("bar", "red", 210.0, -15.0, 100.0, 16.0, 16.0, 70.0))


def test_cubes_of_any_size_are_sorted_and_look_alikes_left_alone(
        twin_calibration: tuple[Path, Path]) -> None:
    scene = Scene(blocks=CUBES, distractors=LOOKALIKES, bins=DEFAULT_BINS)
    said: list[str] = []
    with Robot.open(RobotConfig(TwinSpec(scene=scene), camera=CameraSpec(
            intrinsics=twin_calibration[0], hand_eye=twin_calibration[1]))) as robot:
        twin = robot.twin
        assert twin is not None
        before = twin.distractor_positions_mm()
        report = PickSorter(robot, progress=said.append).run()
        truth, after, bins = twin.blocks(), twin.distractor_positions_mm(), dict(robot.bins)
    for block in truth:  # every cube, whatever its size, in its bin
        bx, by = bins[block.color]
        assert math.hypot(block.x_mm - bx, block.y_mm - by) < IN_BIN_MM, (block, said)
    for start, end in zip(before, after, strict=True):  # nothing else touched
        assert math.dist(start[:2], end[:2]) < 2.0, (start, end, said)
    # The report holds the three cubes, sorted, and nothing else.
    assert sorted(b.color for b in report.blocks) == ["blue", "green", "red"], said
    assert all(b.outcome == "sorted" for b in report.blocks), [b.to_dict() for b in report.blocks]
    left_alone = [line for line in said if "is not a block" in line]
    assert len(left_alone) >= len(LOOKALIKES), said
