"""Tag stacking on the twin through the real path (bus, camera, calibration files made by
our own flows), scored against the twin's ground truth."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from busarm.apps.stack.job import StackJob, check_ids
from busarm.apps.stack.settings import StackSettings
from busarm.apps.stack.tag_view import Keepout
from busarm.bench.stack import MAX_OFF_MM, score_tower
from busarm.cli.main import cli
from busarm.errors import ConfigError
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.lookalike import tagged_scene
from busarm.twin.scene import Scene
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import BlockState

pytestmark = pytest.mark.slow  # whole stacking runs on the twin


def _robot(calibration: tuple[Path, Path], scene: Scene) -> Robot:
    return Robot.open(RobotConfig(TwinSpec(scene=scene), camera=CameraSpec(
        intrinsics=calibration[0], hand_eye=calibration[1])))


def _truth(robot: Robot) -> list[BlockState]:
    assert robot.sim is not None
    return robot.sim.blocks()


def _unmoved(before: list[BlockState], after: list[BlockState]) -> bool:
    return all(math.hypot(a.x_mm - b.x_mm, a.y_mm - b.y_mm) < 0.5 and abs(a.z_mm - b.z_mm) < 0.5
               for a, b in zip(before, after, strict=True))


def test_five_tagged_blocks_are_stacked_in_id_order_with_the_last_beyond_the_tower(
        twin_calibration: tuple[Path, Path]) -> None:
    # Seed 16: every free spot stands in the arm's way to some block; the tower goes at
    # (140, 0) mm and the last block lies beyond it. The look at that block keeps the tool
    # over the four-high tower (the look chosen without it has the fingers in the tower),
    # each block rises as high as straight up reaches before it is carried over the
    # tower (a slanting rise went through it), and the tower stands whole.
    scene = tagged_scene(16)
    ids = sorted(b.tag_id for b in scene.blocks if b.tag_id is not None)
    with _robot(twin_calibration, scene) as robot:
        lines: list[str] = []
        job = StackJob(robot, progress=lines.append)
        report = job.run()
        truth = _truth(robot)
        at_home = all(abs(a - b) < 2.0 for a, b in
                      zip(robot.arm.read_joints_deg(), robot.config.pose("home"), strict=True))
        last, place = report.tower[-1], report.place_mm
        assert place is not None and len(report.tower) == 5, report.text()
        top_z = robot.config.table_z_mm + sum(b.size_mm for b in report.tower[:-1])
        tower = Keepout(*place, 60.0, top_z + 25.0)
        assert tower.deck(*last.found_mm)[0] > 0.0  # the tower stands in the way
        surface_z = robot.config.table_z_mm + last.size_mm
        kin, look_mm = robot.arm.kin, job.settings.look_mm
        plain = kin.fk(job.view.pose_for(*last.found_mm, surface_z, look_mm))
        kept = kin.fk(job.view.pose_for(*last.found_mm, surface_z, look_mm, tower))
    assert math.hypot(plain.x_mm - place[0], plain.y_mm - place[1]) < tower.radius_mm
    assert plain.z_mm < top_z
    assert kept.z_mm >= tower.clear_z_mm
    assert report.end == "complete", report.text()
    assert report.order == ids and report.ids == ids
    complete, errors = score_tower(truth, [b.tag_id for b in scene.blocks], 0.0)
    assert complete and max(errors) < MAX_OFF_MM / 2, (errors, truth)
    # What it looked at agrees with the truth: the height is the sides added up, each
    # block within the re-placing tolerance of the axis, each side measured to a mm.
    assert report.height_mm == pytest.approx(sum(b.size_mm for b in scene.blocks), abs=2.0)
    assert all(b.error_mm <= 4.0 and b.placements >= 1 for b in report.tower)
    assert all(b.size_mm == pytest.approx(scene.blocks[0].size_mm, abs=1.0)
               for b in report.tower)
    bottom = next(t for t in truth if scene.blocks[t.index].tag_id == ids[0])
    assert math.hypot(bottom.x_mm - place[0], bottom.y_mm - place[1]) < 5.0
    assert at_home and any("on the tower" in line for line in lines)
    data = report.to_dict()
    assert data["order"] == ids and data["end"] == "complete"


def test_a_tower_too_tall_stops_cleanly_before_the_next_pick(
        twin_calibration: tuple[Path, Path]) -> None:
    scene = tagged_scene(3, 4)
    with _robot(twin_calibration, scene) as robot:
        report = StackJob(robot, settings=StackSettings(max_height_mm=70.0)).run()
        truth = _truth(robot)
    assert report.end == "too tall", report.text()
    size = scene.blocks[0].size_mm  # 2 blocks of this size make the tallest under 70 mm
    assert len(report.tower) == 2 and report.height_mm == pytest.approx(2 * size, abs=2.0)
    assert "more than the 70 mm allowed" in report.why
    stands = re.search(r"it stands (\d+) mm tall", report.why)
    assert stands is not None and abs(int(stands.group(1)) - 2 * size) <= 1.5
    stacked = set(report.order)
    for t in truth:  # the blocks not stacked were not touched
        block = scene.blocks[t.index]
        if block.tag_id not in stacked:
            assert math.hypot(t.x_mm - block.x_mm, t.y_mm - block.y_mm) < 1.0
    assert "too tall" in report.text() and "tall as looked at" in report.text()


def test_ids_not_on_the_table_are_refused_before_a_block_moves(
        twin_calibration: tuple[Path, Path]) -> None:
    scene = tagged_scene(0, 3)
    absent = next(i for i in range(10) if i not in {b.tag_id for b in scene.blocks})
    with _robot(twin_calibration, scene) as robot:
        before = _truth(robot)
        job = StackJob(robot, ids=[absent, scene.blocks[0].tag_id or 0])
        with pytest.raises(ConfigError, match=rf"--tags {absent}: not on the table \(tags seen"):
            job.run()
        assert _unmoved(before, _truth(robot))
        assert job.report.end == "stopped" and not job.report.tower
    with pytest.raises(ConfigError, match="tag id = 600 is out of range 0..586"):
        check_ids([1, 600])


def test_bad_places_and_ids_are_refused_by_the_command(twin_config_home: Path) -> None:
    runner = CliRunner(mix_stderr=False)
    for args, said in (
            (["--at", "900,0"], "--at (900, 0) mm is off the table"),
            (["--at", "30,0"], "--at (30, 0) mm is out of the arm's reach"),
            (["--at", "195"], "--at '195': expected X,Y"),
            (["--tags", "1,1"], "--tags repeats an id: 1,1"),
            (["--tags", "2,x"], "'x' is not a tag id")):
        result = runner.invoke(cli, ["stack", *args])
        assert result.exit_code != 0 and said in result.stderr, (args, result.stderr)
        assert "Traceback" not in result.stderr
