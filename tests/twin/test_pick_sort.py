"""Pick-and-sort on the twin through the real path (bus, camera, calibration files made by
our own flows), scored against the twin's ground truth."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from busarm.apps.locate import BlockLocator
from busarm.apps.pick_sort import PickSorter, PickSortSettings
from busarm.arm import Arm
from busarm.cli.main import cli
from busarm.errors import ConfigError
from busarm.twin.twin import active_twin
from busarm.vision.calibration import load_hand_eye, load_intrinsics
from busarm.vision.camera import open_camera
from busarm.vision.color import ColorDetector, default_thresholds


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    out = tmp_path_factory.mktemp("cal")
    intr, he = out / "camera.json", out / "hand_eye.json"
    runner = CliRunner(mix_stderr=False)
    assert runner.invoke(cli, ["--port", "twin", "camera", "calibrate", "--views", "12",
                               "-o", str(intr)]).exit_code == 0
    assert runner.invoke(cli, ["--port", "twin", "camera", "handeye", "--intrinsics", str(intr),
                               "--views", "10", "-o", str(he)]).exit_code == 0
    return intr, he


def test_every_block_ends_in_its_colours_bin(calibration: tuple[Path, Path]) -> None:
    intr = load_intrinsics(calibration[0])
    he = load_hand_eye(calibration[1], intrinsics=intr)
    with Arm.open("twin://?seed=5&blocks=4") as arm, open_camera("twin") as camera:
        twin = active_twin()
        assert twin is not None
        bins = {b.color: (b.x_mm, b.y_mm) for b in twin.scene.bins}
        locator = BlockLocator(arm.kin, intr, he, ColorDetector(default_thresholds()))
        report = PickSorter(arm, camera, locator, bins).run()
        truth = twin.blocks()
    assert report.totals()["sorted"] == 4, [b.to_dict() for b in report.blocks]
    for block in truth:
        bx, by = bins[block.color]
        assert math.hypot(block.x_mm - bx, block.y_mm - by) < 35.0, block
    for outcome in report.blocks:
        assert outcome.outcome == "sorted" and outcome.attempts == 1
        assert 0 < outcome.seconds < 8.0


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match="approach_mm"):
        PickSortSettings(approach_mm=5.0)
    with pytest.raises(ConfigError, match="max_attempts"):
        PickSortSettings(max_attempts=0)


def test_the_pick_sort_command_sorts_and_reports(calibration: tuple[Path, Path],
                                                 tmp_path: Path) -> None:
    import json

    report = tmp_path / "report"
    result = CliRunner(mix_stderr=False).invoke(cli, [
        "pick-sort", "--seed", "2", "--blocks", "3", "--intrinsics", str(calibration[0]),
        "--hand-eye", str(calibration[1]), "--report", str(report), "--json"])
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["format"] == "busarm.pick_sort_report"
    assert data["totals"]["sorted"] == 3 and data["totals"]["failed"] == 0
    assert data["totals"]["median_cycle_s"] <= 8.0
    for name in ("report.json", "before.png", "after.png", "camera.gif"):
        assert (report / name).stat().st_size > 1000, name
    assert len(list((report / "picks").glob("*.png"))) == 3


def test_the_pick_sort_command_refuses_bad_input(tmp_path: Path) -> None:
    runner = CliRunner(mix_stderr=False)
    for args, expected in (
        (["--port", "/dev/ttyUSB9", "pick-sort", "--seed", "2"], "for the twin"),
        (["--port", "/dev/ttyUSB9", "pick-sort"], "needs --camera"),
        (["pick-sort", "--colors", "red,mauve"], "mauve"),
        (["pick-sort", "--bins", "red:1,2"], "COLOUR=X,Y"),
    ):
        result = runner.invoke(cli, args)
        assert result.exit_code == 2, (args, result.stdout, result.stderr)
        assert expected in result.stderr, (args, result.stderr)
        assert len(result.stderr.strip().splitlines()) == 1, result.stderr


def _sorter(calibration: tuple[Path, Path], arm: Arm, camera: Any,
            on_step: Any) -> PickSorter:
    intr = load_intrinsics(calibration[0])
    he = load_hand_eye(calibration[1], intrinsics=intr)
    twin = active_twin()
    assert twin is not None
    bins = {b.color: (b.x_mm, b.y_mm) for b in twin.scene.bins}
    return PickSorter(arm, camera, BlockLocator(arm.kin, intr, he,
                                                ColorDetector(default_thresholds())),
                      bins, on_step=on_step)


def test_a_block_that_slips_out_during_the_carry_is_picked_again(
        calibration: tuple[Path, Path]) -> None:
    with Arm.open("twin://?seed=5&blocks=2") as arm, open_camera("twin") as camera:
        twin = active_twin()
        assert twin is not None
        slipped: list[int] = []

        def drop_it(step: str) -> None:
            if step == "lift" and not slipped:
                held = max(twin.blocks(), key=lambda b: b.z_mm)
                twin.place_block(held.index, held.x_mm, held.y_mm + 60.0)  # it falls away
                slipped.append(held.index)

        report = _sorter(calibration, arm, camera, drop_it).run()
        truth = twin.blocks()
        bins = {b.color: (b.x_mm, b.y_mm) for b in twin.scene.bins}
    assert slipped
    assert report.totals()["sorted"] == 2, [b.to_dict() for b in report.blocks]
    for block in truth:
        assert math.hypot(block.x_mm - bins[block.color][0],
                          block.y_mm - bins[block.color][1]) < 35.0
    assert any(b.attempts == 2 and b.outcome == "sorted" for b in report.blocks) or any(
        b.outcome == "moved" for b in report.blocks)


def test_a_block_moved_while_the_arm_approaches_is_found_again(
        calibration: tuple[Path, Path]) -> None:
    with Arm.open("twin://?seed=5&blocks=2") as arm, open_camera("twin") as camera:
        twin = active_twin()
        assert twin is not None
        moved: list[int] = []

        def move_it(step: str) -> None:
            if step == "above" and not moved:
                tool = arm.read_pose()
                target = min(twin.blocks(), key=lambda b: math.hypot(b.x_mm - tool.x_mm,
                                                                     b.y_mm - tool.y_mm))
                twin.place_block(target.index, 200.0, -40.0, 10.0)
                moved.append(target.index)

        report = _sorter(calibration, arm, camera, move_it).run()
        truth = twin.blocks()
        bins = {b.color: (b.x_mm, b.y_mm) for b in twin.scene.bins}
    assert moved
    outcomes = [b.outcome for b in report.blocks]
    assert outcomes.count("moved") == 1 and outcomes.count("sorted") == 2, outcomes
    for block in truth:
        assert math.hypot(block.x_mm - bins[block.color][0],
                          block.y_mm - bins[block.color][1]) < 35.0


def test_a_servo_that_stops_answering_stops_the_run_cleanly(
        calibration: tuple[Path, Path]) -> None:
    from busarm.errors import BusTimeoutError

    with Arm.open("twin://?seed=5&blocks=2") as arm, open_camera("twin") as camera:
        twin = active_twin()
        assert twin is not None

        def brown_out(step: str) -> None:
            if step == "lift":
                twin.servos[2].supply_mv = 5000  # the elbow goes silent (under 6 V)

        with pytest.raises(BusTimeoutError, match="servo 3"):
            _sorter(calibration, arm, camera, brown_out).run()
        # The others were stopped and hold where they are (the silent elbow has no torque
        # and sags, as a browned-out servo does).
        held = twin.joints_deg()
        time.sleep(0.5)
        now = twin.joints_deg()
        for k in (0, 1, 3, 4):
            assert twin.servos[k].is_loaded
            assert abs(held[k] - now[k]) < 1.0, (k, held, now)
