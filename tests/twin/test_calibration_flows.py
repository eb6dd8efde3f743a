"""The camera calibration flows and the block locator, end to end on the twin.

``busarm camera calibrate`` and ``busarm camera handeye`` run as a user would run them
(the CLI, the twin's servos through the bus, its camera through its lens); their files
are then used to locate blocks, scored against the twin's ground truth, which the flows
never read."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bench.locate import localisation_accuracy
from busarm.cli.main import cli
from busarm.errors import ConfigError, VisionError
from busarm.robot.camera_calibration import GRIPPER_IN_VIEW, calibration_views, sees_points
from busarm.twin.boards import BOARD_SPECS, board2base, calibration_board
from busarm.twin.lens import LensSpec
from busarm.twin.model import AS_BUILT_MOUNT_ERROR
from busarm.vision.calibration import CameraIntrinsics, load_hand_eye, load_intrinsics

pytestmark = pytest.mark.slow  # camera calibration flows on the twin


def run(*args: str, port: str = "twin") -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", port, *args])


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, Path]]:
    out = tmp_path_factory.mktemp("cal")
    intr, he = out / "camera.json", out / "hand_eye.json"
    result = run("camera", "calibrate", "--views", "14", "-o", str(intr))
    assert result.exit_code == 0, result.stderr
    assert "wrote" in result.stdout
    result = run("camera", "handeye", "--intrinsics", str(intr), "--views", "12",
                 "-o", str(he))
    assert result.exit_code == 0, result.stderr
    yield intr, he


def test_intrinsics_flow_finds_the_twin_lens(calibrated: tuple[Path, Path]) -> None:
    data = json.loads(calibrated[0].read_text())
    assert data["format"] == "busarm.camera_intrinsics" and data["version"] == 1
    found = load_intrinsics(calibrated[0], expect_size=(640, 480))
    truth = LensSpec()
    assert found.fx == pytest.approx(truth.fx_px, abs=3.0)
    assert found.fy == pytest.approx(truth.fy_px, abs=3.0)
    assert found.cx == pytest.approx(truth.cx_px, abs=3.0)
    assert found.cy == pytest.approx(truth.cy_px, abs=3.0)
    # The lens bends the picture (tens of pixels near the border): the calibration must
    # undo it as the true lens does, to about a pixel, where the board was seen (the
    # gripper hides the bottom corners; the extreme corners are extrapolation).
    pixels = np.array([[64.0, 48.0], [576.0, 48.0], [24.0, 240.0], [616.0, 240.0],
                       [100.0, 330.0], [540.0, 330.0]])
    error_px = np.linalg.norm(found.normalized_from_pixels(pixels)
                              - truth.normalized_from_pixels(pixels), axis=1) * truth.fx_px
    assert np.all(error_px < 1.5), error_px


def test_hand_eye_flow_finds_where_the_camera_really_sits(
        calibrated: tuple[Path, Path]) -> None:
    intr = load_intrinsics(calibrated[0])
    he = load_hand_eye(calibrated[1], intrinsics=intr)
    truth = CameraMount.jetauto().offset(*AS_BUILT_MOUNT_ERROR).cam2link
    nominal = CameraMount.jetauto().cam2link
    delta = np.linalg.inv(truth) @ he.cam2link
    assert np.linalg.norm(delta[:3, 3]) < 1.5
    assert math.degrees(math.acos(min(1.0, (np.trace(delta[:3, :3]) - 1) / 2))) < 0.3
    # ... and it found the as-built error, not the drawing.
    assert np.linalg.norm(nominal[:3, 3] - he.cam2link[:3, 3]) > 2.0


def test_blocks_are_located_to_millimetres(calibrated: tuple[Path, Path]) -> None:
    report = localisation_accuracy(*calibrated, placements=40, seed=3).summary()
    assert report.missed == 0 and report.wrong_color == 0, report
    assert report.median_mm <= 2.0, report
    assert report.p95_mm <= 5.0, report


def test_views_keep_the_board_whole_and_clear_of_the_gripper() -> None:
    cfg = load_arm_config()
    kin = ArmKinematics.from_config(cfg)
    spec = BOARD_SPECS["chessboard"]
    where = board2base(calibration_board("chessboard"), cfg.table_z_mm)
    poses = calibration_views(kin, spec, where, 12, seed=4)
    assert len(poses) == 12 and len(set(poses)) == 12
    guess = CameraIntrinsics.vendor_default()
    w, h = spec.extent_mm
    corners = (where @ np.array([[0, 0, 0, 1], [w, 0, 0, 1], [w, h, 0, 1], [0, h, 0, 1]],
                                float).T).T[:, :3]
    for q in poses:
        cfg.check_joints(q)
        cam2base = kin.frames(q)[3] @ CameraMount.jetauto().cam2link
        assert sees_points(corners, cam2base, guess)
    # A point where the gripper hides the picture is refused.
    x0, y0, x1, y1 = GRIPPER_IN_VIEW
    hidden_px = np.array([(x0 + x1) / 2 * 640, (y0 + y1) / 2 * 480])
    ray = guess.normalized_from_pixels(hidden_px[None])[0]
    cam2base = kin.frames(poses[0])[3] @ CameraMount.jetauto().cam2link
    p = cam2base @ np.array([ray[0] * 300, ray[1] * 300, 300.0, 1.0])
    assert not sees_points(p[None, :3], cam2base, guess)


def test_a_board_out_of_reach_is_a_clear_error() -> None:
    cfg = load_arm_config()
    kin = ArmKinematics.from_config(cfg)
    far = board2base(calibration_board("chessboard", (900.0, 0.0)), cfg.table_z_mm)
    with pytest.raises(VisionError, match="move the board"):
        calibration_views(kin, BOARD_SPECS["chessboard"], far, 10)
    with pytest.raises(ConfigError, match="views"):
        calibration_views(kin, BOARD_SPECS["chessboard"], far, 1)


def test_camera_commands_refuse_bad_input(tmp_path: Path) -> None:
    bad = tmp_path / "camera.json"
    bad.write_text("{not json")
    result = run("camera", "handeye", "--intrinsics", str(bad))
    assert result.exit_code == 2, result.stderr
    assert result.stderr.startswith("error: ") and len(result.stderr.strip().splitlines()) == 1
    result = run("camera", "calibrate", "--board-at", "1,2,3", port="sim")
    assert result.exit_code == 2 and "--board-at" in result.stderr
    result = run("camera", "calibrate", port="sim")
    assert result.exit_code == 2 and "needs the wrist camera (--camera)" in result.stderr


def test_vision_locate_prints_where_the_blocks_are(calibrated: tuple[Path, Path],
                                                    tmp_path: Path) -> None:
    from busarm.twin.scene import random_scene

    intr, he = calibrated
    result = run("vision", "locate", "--intrinsics", str(intr), "--hand-eye", str(he),
                 "--frames", "2", "--json", "--save", str(tmp_path),
                 port="twin://?seed=4&blocks=5")
    assert result.exit_code == 0, result.stderr
    found = json.loads(result.stdout)["blocks"]
    truth = random_scene(4, 5).blocks
    assert len(found) == len(truth)
    for block in truth:
        best = min(found, key=lambda f: math.hypot(f["x_mm"] - block.x_mm,
                                                    f["y_mm"] - block.y_mm))
        assert best["color"] == block.color
        assert math.hypot(best["x_mm"] - block.x_mm, best["y_mm"] - block.y_mm) < 2.0
        assert best["reachable"] and best["frames"] == 2
    assert (tmp_path / "locate.png").stat().st_size > 10_000


def test_vision_locate_refuses_mismatched_calibrations(calibrated: tuple[Path, Path],
                                                        tmp_path: Path) -> None:
    intr, he = calibrated
    data = json.loads(intr.read_text())
    data["width_px"], data["height_px"] = 1280, 720
    other = tmp_path / "other.json"
    other.write_text(json.dumps(data))
    result = run("vision", "locate", "--intrinsics", str(other), "--hand-eye", str(he))
    assert result.exit_code == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr


def test_a_hand_eye_with_the_wrong_intrinsics_is_refused(calibrated: tuple[Path, Path],
                                                         tmp_path: Path) -> None:
    data = json.loads(calibrated[0].read_text())
    data["camera_matrix"][0][0] *= 1.12  # another lens
    data["camera_matrix"][1][1] *= 1.12
    wrong = tmp_path / "wrong.json"
    wrong.write_text(json.dumps(data))
    out = tmp_path / "he.json"
    result = run("camera", "handeye", "--intrinsics", str(wrong), "--views", "8",
                 "-o", str(out))
    assert result.exit_code == 1, (result.stdout, result.stderr)
    assert "hand-eye fit is poor" in result.stderr
    assert not out.exists()


def test_calibrate_from_a_folder_of_pictures(tmp_path: Path) -> None:
    """`camera calibrate --images DIR`: pictures taken any other way, no arm."""
    import cv2

    from busarm.twin.scene import Scene
    from busarm.twin.twin import Twin

    cfg = load_arm_config()
    kin = ArmKinematics.from_config(cfg)
    board = calibration_board("chessboard")
    poses = calibration_views(kin, BOARD_SPECS["chessboard"],
                              board2base(board, cfg.table_z_mm), 10, seed=7)
    folder = tmp_path / "pictures"
    folder.mkdir()
    for i, q in enumerate(poses):
        with Twin(cfg, Scene(boards=(board,)), realtime=False, start_joints_deg=q) as tw:
            cv2.imwrite(str(folder / f"view{i:02d}.png"), tw.render_camera())
    out = tmp_path / "camera.json"
    result = run("camera", "calibrate", "--images", str(folder), "-o", str(out), port="sim")
    assert result.exit_code == 0, result.stderr
    found = load_intrinsics(out)
    assert found.fx == pytest.approx(LensSpec().fx_px, abs=4.0)
    assert "over 10 views" in result.stdout
