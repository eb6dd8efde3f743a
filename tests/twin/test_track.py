"""Colour tracking on the twin through the real path (bus, camera, calibration files made
by our own flows), the block slid by the twin's hand, scored against the twin's truth."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from busarm.apps.track.job import TrackJob, TrackSettings, check_color
from busarm.bench.track import truth_error_px
from busarm.cli.main import cli
from busarm.errors import ConfigError
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.mover import BlockMover, eight_path, track_scene, waypoints_path
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

pytestmark = pytest.mark.slow  # tracking runs on the twin


def _robot(calibration: tuple[Path, Path], start_mm: tuple[float, float]) -> Robot:
    return Robot.open(RobotConfig(TwinSpec(scene=track_scene("red", start_mm)),
                                  camera=CameraSpec(intrinsics=calibration[0],
                                                    hand_eye=calibration[1])))


def _twin(robot: Robot) -> Twin:
    assert robot.twin is not None
    return robot.twin


def test_a_block_slid_along_a_curve_at_45_mm_s_is_kept_centred(
        twin_calibration: tuple[Path, Path]) -> None:
    path = eight_path()
    start = path.at(0.0)[:2]
    with _robot(twin_calibration, start) as robot:
        twin = _twin(robot)
        mover = BlockMover(twin, path, 45.0, start_after_s=0.5).attach()
        moving_from = twin.sim_time_s + 0.5
        truth: list[float] = []

        def on_frame(frame: object) -> None:
            if twin.sim_time_s >= moving_from:
                truth.append(truth_error_px(twin))

        job = TrackJob(robot, "red", settings=TrackSettings(seconds=4.0), on_frame=on_frame)
        report = job.run()
        # The hand really moved the block along its path (the twin's truth).
        block = twin.blocks()[0]
        expected = mover.where_mm(twin.sim_time_s)
        moved_mm = math.dist(start, (block.x_mm, block.y_mm))
    assert math.dist((block.x_mm, block.y_mm), expected) < 2.0
    assert moved_mm > 50.0 and block.is_upright
    # Kept centred: >= 90 % of the frames within 40 px, by the truth (not its detection).
    assert len(truth) >= 45
    within = sum(e <= 40.0 for e in truth) / len(truth)
    assert within >= 0.9, sorted(truth)[-10:]
    assert report.stop == "time" and report.why == "4 s are up"
    assert report.frames >= 55 and report.within() >= 0.9
    median, p95 = report.error_stats_px() or (math.inf, math.inf)
    assert median < 15.0 and p95 < 40.0
    assert len(report.latencies_s) >= 50 and all(0 < t < 0.1 for t in report.latencies_s)
    data = report.to_dict()
    assert data["stop"] == "time" and data["frames"] == report.frames


def test_the_block_leaving_the_reach_then_the_view_stops_it_holding(
        twin_calibration: tuple[Path, Path]) -> None:
    path = waypoints_path([(240.0, 0.0), (385.0, 0.0)])  # out past the arm's reach
    with _robot(twin_calibration, (240.0, 0.0)) as robot:
        twin = _twin(robot)
        mover = BlockMover(twin, path, 50.0).attach()
        job = TrackJob(robot, "red", settings=TrackSettings(seconds=8.0))
        report = job.run()
        x_stop = twin.blocks()[0].x_mm
        held = twin.joints_deg()
        robot.clock.sleep(0.5)
        still = twin.joints_deg()
        mover.detach()
        # Lifted off the table's view: not seen, so it has left the view.
        twin.place_block(0, -150.0, 300.0)
        lost = TrackJob(robot, "red", settings=TrackSettings(lost_frames=5)).run()
    assert report.stop == "left the reach", report.why
    assert report.why.startswith("left the reach: the red block at (")
    assert 290.0 < x_stop < 385.0 and report.seconds < 7.5
    assert report.within() > 0.5  # it was followed until it went
    assert max(abs(a - b) for a, b in zip(held, still, strict=True)) < 0.5  # held there
    assert lost.stop == "left the view" and lost.frames == 5
    assert lost.why == "left the view: the red block was not seen for 5 frames"
    assert lost.error_stats_px() is None and lost.within() == 0.0


def test_bad_inputs_are_refused_before_anything_moves(tmp_path: Path) -> None:
    allowed = "allowed: red, green, blue, yellow"
    with pytest.raises(ConfigError, match=f"colour 'purple' is not a block colour; {allowed}"):
        check_color("purple")
    with pytest.raises(ConfigError, match="frame_rate_hz"):
        TrackSettings(frame_rate_hz=0.0)
    with pytest.raises(ConfigError, match="lost_frames"):
        TrackSettings(lost_frames=0)
    with pytest.raises(ConfigError, match="seconds"):
        TrackSettings(seconds=-1.0)
    runner = CliRunner(mix_stderr=False)
    for args, message in [
        (["track", "--color", "purple"],
         "error: Invalid value for '--color': 'purple' is not one of 'red', 'green', 'blue'"),
        (["--port", "sim", "track", "--color", "red", "--twin-mover", "circle"],
         "error: --twin-mover slides a block on the twin's table; sim is not a twin in this "
         "process: slide the block by hand"),
        (["track", "--color", "red", "--twin-mover", "eight", "--speed-mm-s", "500"],
         "error: Invalid value for '--speed-mm-s': --speed-mm-s = 500.0 mm/s is out of range "
         "0..200 mm/s"),
    ]:
        result = runner.invoke(cli, args)
        assert result.exit_code == 2, result.stderr
        assert result.stderr.splitlines() == [message]
        assert result.stdout == ""


@pytest.mark.wallclock("Ctrl+C to a track process while it follows the block")
def test_ctrl_c_holds_the_arm_and_says_the_report_so_far(
        twin_calibration: tuple[Path, Path]) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "track", "--color", "red", "--twin-mover", "circle",
         "--intrinsics", str(twin_calibration[0]), "--hand-eye", str(twin_calibration[1])],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.stderr is not None
    try:
        assert proc.stderr.readline() == (
            "looking down at the table: keeping the red block centred\n")  # under way
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and out == "", err
    assert lines[0].startswith(
        "interrupted: all servos stopped (MOVE_STOP); servos 1-5, 10 holding position "
        "(torque on); the report so far: "), lines
    assert "within 40 px of the centre" in lines[0] and lines[0].endswith(
        "stopped: interrupted")
