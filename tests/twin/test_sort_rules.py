"""Sorting by size class and by tag id (issue 32), on the twin, scored against its truth:
each block ends in the bin its size class or its tag's place names, and the run's report
says so (and nothing it did not do)."""

from __future__ import annotations

import math
from pathlib import Path

from busarm.apps.pick_sort.rules import SortRule
from busarm.apps.pick_sort.sorter import IN_BIN_MM, PickSorter
from busarm.apps.pick_sort.tag_sort import TagSortJob
from busarm.perception.size_classes import size_class
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.lookalike import sized_scene, tagged_scene
from busarm.twin.spec import TwinSpec


def _robot(scene: object, calibration: tuple[Path, Path]) -> Robot:
    return Robot.open(RobotConfig(TwinSpec(scene=scene), camera=CameraSpec(
        intrinsics=calibration[0], hand_eye=calibration[1])))


def test_blocks_of_every_size_class_go_to_their_class_bins(
        twin_calibration: tuple[Path, Path]) -> None:
    scene = sized_scene(7)  # 23, 30, 31 and 42.5 mm: two medium ones share a bin
    said: list[str] = []
    with _robot(scene, twin_calibration) as robot:
        twin = robot.twin
        assert twin is not None
        report = PickSorter(robot, rule=SortRule("size"), progress=said.append).run()
        truth, bins = twin.blocks(), dict(robot.bins)
    assert set(bins) == {"small", "medium", "large"}
    for block in truth:
        where = bins[size_class(scene.blocks[block.index].size_mm)]
        assert math.dist((block.x_mm, block.y_mm), where) < IN_BIN_MM, (block, said)
    assert sorted(b.place for b in report.blocks) == sorted(
        size_class(b.size_mm) for b in scene.blocks), [b.to_dict() for b in report.blocks]
    assert all(b.outcome == "sorted" for b in report.blocks), said
    assert any("into the large bin" in line for line in said), said


def test_tagged_blocks_go_where_their_ids_are_mapped_whatever_their_colour(
        twin_calibration: tuple[Path, Path]) -> None:
    scene = tagged_scene(7)  # tags 4, 5, 6 and 9
    tags = sorted(b.tag_id for b in scene.blocks if b.tag_id is not None)
    places = {tags[0]: "red", tags[1]: "blue", tags[2]: "blue"}  # the last goes nowhere
    said: list[str] = []
    with _robot(scene, twin_calibration) as robot:
        twin = robot.twin
        assert twin is not None
        report = TagSortJob(robot, rule=SortRule("tag", places), progress=said.append).run()
        truth, bins = twin.blocks(), dict(robot.bins)
    for block in truth:
        tag = scene.blocks[block.index].tag_id
        start = scene.blocks[block.index]
        if tag in places:
            assert math.dist((block.x_mm, block.y_mm), bins[places[tag]]) < IN_BIN_MM, said
        else:  # no place for it: left where it stood
            assert math.dist((block.x_mm, block.y_mm), (start.x_mm, start.y_mm)) < 2.0, said
    outcomes = {b.color: (b.outcome, b.place) for b in report.blocks}
    assert outcomes == {**{f"tag {t}": ("sorted", p) for t, p in places.items()},
                        f"tag {tags[3]}": ("skipped", "")}, said
    assert any(f"no place for tag {tags[3]}" in line for line in said), said
