"""The looks a pick makes before its grasp (issue 35): none that an earlier picture
already answered, and no more than help a block hidden among others."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from busarm.apps.pick_sort.sorter import PickSorter
from busarm.apps.pick_sort.table_view import CROWDED_LOOKS, TableView
from busarm.perception.locate import Sighting
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.scene import DEFAULT_BINS, Block, Scene
from busarm.twin.spec import TwinSpec

pytestmark = pytest.mark.slow  # looks on the twin


def _robot(calibration: tuple[Path, Path], scene: Scene) -> Robot:
    return Robot.open(RobotConfig(TwinSpec(scene=scene), camera=CameraSpec(
        intrinsics=calibration[0], hand_eye=calibration[1])))


def _counting_looks(monkeypatch: pytest.MonkeyPatch) -> list[object]:
    """Every ``TableView.look`` from now on, counted."""
    looks: list[object] = []
    look = TableView.look

    def counted(view: TableView, pose: object, **kw: bool) -> object:
        looks.append(pose)
        return look(view, pose, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(TableView, "look", counted)
    return looks


def _nearest(seen: list[Sighting], x_mm: float, y_mm: float) -> Sighting:
    return min(seen, key=lambda v: math.hypot(v.location.x_mm - x_mm, v.location.y_mm - y_mm))


def test_a_block_seen_from_the_side_then_faced_is_judged_from_both_pictures(
        twin_calibration: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    # Far off the survey's bearing: looked at again facing it; the survey's picture saw
    # its sides from another angle, and the two together say it is a cube.
    scene = Scene(blocks=(Block("red", 150.0, 115.0, 10.0),), bins=DEFAULT_BINS)
    with _robot(twin_calibration, scene) as robot:
        sorter = PickSorter(robot, colors=["red"])
        target = sorter.survey()[0]
        closer = sorter.look_closer(target)
        assert closer is not None and closer is not target  # it was faced
        looks = _counting_looks(monkeypatch)
        confirmed = sorter.view.confirm(closer)
    assert looks == []
    assert confirmed is not None and confirmed.shape is not None
    assert confirmed.shape.verdict == "cube"
    assert math.hypot(confirmed.location.x_mm - 150.0, confirmed.location.y_mm - 115.0) < 4.0
    assert abs(confirmed.location.size_mm - 30.0) < 2.0


def test_a_block_hidden_among_others_is_not_looked_at_from_every_pose(
        twin_calibration: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    # A touching 2x2 square of one colour: one blob, split into blocks; from the side and
    # from over it they still touch, and the looks from the survey's height would too.
    square = tuple(Block("green", 200.0 + u, v, 0.0) for u in (-15.0, 15.0)
                   for v in (-15.0, 15.0))
    scene = Scene(blocks=square, bins=DEFAULT_BINS)
    with _robot(twin_calibration, scene) as robot:
        sorter = PickSorter(robot, colors=["green"])
        target = _nearest(sorter.survey(), 185.0, -15.0)
        closer = sorter.look_closer(target) or target
        assert sorter.view._in_a_crowd(closer)
        looks = _counting_looks(monkeypatch)
        confirmed = sorter.view.confirm(closer)
    assert len(looks) == CROWDED_LOOKS
    # Taken as located: a block of the usual size in a crowd of blocks.
    assert confirmed is not None
    assert math.hypot(confirmed.location.x_mm - 185.0, confirmed.location.y_mm + 15.0) < 10.0
