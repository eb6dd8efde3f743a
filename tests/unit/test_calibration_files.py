"""Versioned JSON files of camera intrinsics and hand-eye calibrations."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from busarm.errors import CalibrationError, ConfigError
from busarm.vision.calibration import (
    HAND_EYE_FORMAT,
    INTRINSICS_FORMAT,
    CameraIntrinsics,
    HandEyeResult,
    IntrinsicsResult,
    load_hand_eye,
    load_intrinsics,
    save_hand_eye,
    save_intrinsics,
)

K = np.array([[471.2, 0.0, 321.7], [0.0, 472.9, 240.3], [0.0, 0.0, 1.0]])
INTR = CameraIntrinsics("pinhole", 640, 480, K, np.array([-0.03, 0.01, -0.005, -0.003, -0.02]))


def transform(rotvec_deg: list[float], t: list[float]) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = Rotation.from_rotvec(rotvec_deg, degrees=True).as_matrix()
    out[:3, 3] = t
    return out


def hand_eye(intr: CameraIntrinsics = INTR) -> HandEyeResult:
    return HandEyeResult(
        transform([5.0, -80.0, 3.0], [-51.2, -63.8, 2.9]), transform([180.0, 0, 0], [170, 55, 0]),
        0.21, (0.2, 0.22), (0, 2), intr, method="park", translation_std_mm=0.4,
        rotation_std_deg=0.05, pose_rms_deg=0.08, pose_rms_mm=0.3,
        created="2026-11-23T10:00:00+00:00",
    )


def edit(path: Path, change: object) -> None:
    data = json.loads(path.read_text())
    change(data)  # type: ignore[operator]
    path.write_text(json.dumps(data))


# --------------------------------------------------------------------------- intrinsics


def test_intrinsics_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    result = IntrinsicsResult(INTR, 0.123, (0.1, 0.14), (0, 3), (1, 2), "charuco 9x7")
    save_intrinsics(path, result, camera="wrist", serial=17)
    data = json.loads(path.read_text())
    assert data["format"] == INTRINSICS_FORMAT and data["version"] == 1
    assert data["model"] == "pinhole" and (data["width_px"], data["height_px"]) == (640, 480)
    assert data["rms_px"] == 0.123 and data["views"] == 2 and data["board"] == "charuco 9x7"
    assert data["meta"] == {"camera": "wrist", "serial": 17} and data["created"]
    loaded = load_intrinsics(path, expect_size=(640, 480))
    assert loaded == INTR  # every value exact
    assert [p.name for p in tmp_path.iterdir()] == ["camera.json"]  # no temporary left


def test_plain_intrinsics_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "vendor.json"
    save_intrinsics(path, CameraIntrinsics.vendor_default(), board="none: vendor values")
    data = json.loads(path.read_text())
    assert data["rms_px"] is None and data["calibrated"] is False
    assert data["board"] == "none: vendor values"
    assert load_intrinsics(path) == CameraIntrinsics.vendor_default()
    save_intrinsics(path, INTR)  # replaces the file
    assert load_intrinsics(path) == INTR


def test_intrinsics_for_another_size_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "hd.json"
    k = np.array([[900.0, 0.0, 640.0], [0.0, 900.0, 360.0], [0.0, 0.0, 1.0]])
    save_intrinsics(path, CameraIntrinsics("pinhole", 1280, 720, k, np.zeros(5)))
    with pytest.raises(CalibrationError) as err:
        load_intrinsics(path, expect_size=(640, 480))
    message = str(err.value)
    assert "hd.json" in message and "1280x720" in message and "640x480" in message
    assert "width_px" in message


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda d: d.update(format="busarm.calibration"), "'format'"),
        (lambda d: d.update(version=2), "'version' is 2"),
        (lambda d: d.pop("camera_matrix"), "missing key 'camera_matrix'"),
        (lambda d: d.update(camera_matrix=[[1, 0], [0, 1]]), "'camera_matrix' must have shape"),
        (lambda d: d.update(camera_matrix=[[470, 0, 320], [0, "x", 240], [0, 0, 1]]),
         "'camera_matrix' must be a list of numbers"),
        (lambda d: d.update(distortion=[0.1, 0.2, 0.3]), "distortion must have 4 or 5 or 8"),
        (lambda d: d.update(model="spherical"), "'model'"),
        (lambda d: d.update(width_px=64.5), "'width_px'"),
        (lambda d: d.update(calibrated="yes"), "'calibrated'"),
        (lambda d: d.update(rms_px="low"), "'rms_px'"),
    ],
)
def test_bad_intrinsics_files(tmp_path: Path, change: object, match: str) -> None:
    path = tmp_path / "camera.json"
    save_intrinsics(path, INTR)
    edit(path, change)
    with pytest.raises(CalibrationError, match=match) as err:
        load_intrinsics(path)
    assert "camera.json" in str(err.value)


def test_non_finite_and_unreadable_files(tmp_path: Path) -> None:
    path = tmp_path / "camera.json"
    save_intrinsics(path, INTR)
    text = path.read_text().replace("471.2", "NaN", 1)
    path.write_text(text)
    with pytest.raises(CalibrationError, match="'camera_matrix' has non-finite numbers"):
        load_intrinsics(path)
    path.write_text(text.replace("NaN", "Infinity"))
    with pytest.raises(CalibrationError, match="non-finite"):
        load_intrinsics(path)
    path.write_text('{"format": "busarm.camera_intrinsics", "version": 1,')
    with pytest.raises(CalibrationError, match="camera.json: unreadable"):
        load_intrinsics(path)
    path.write_text("[1, 2]")
    with pytest.raises(CalibrationError, match="'format'"):
        load_intrinsics(path)
    with pytest.raises(CalibrationError, match="no such file"):
        load_intrinsics(tmp_path / "missing.json")


def test_save_refuses_what_is_not_json(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="meta values must be JSON"):
        save_intrinsics(tmp_path / "c.json", INTR, when=object())
    with pytest.raises(ConfigError, match="IntrinsicsResult or CameraIntrinsics"):
        save_intrinsics(tmp_path / "c.json", "camera")  # type: ignore[arg-type]
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- hand-eye


def test_hand_eye_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "hand_eye.json"
    result = hand_eye()
    save_hand_eye(path, result, operator="lead")
    data = json.loads(path.read_text())
    assert data["format"] == HAND_EYE_FORMAT and data["version"] == 1
    assert data["link"] == "wrist_pitch" and data["meta"] == {"operator": "lead"}
    assert data["intrinsics"]["camera_matrix"] == K.tolist()
    loaded = load_hand_eye(path, intrinsics=INTR)
    assert np.array_equal(loaded.cam2link, result.cam2link)
    assert np.array_equal(loaded.board2base, result.board2base)
    assert loaded.intrinsics == INTR and loaded.link == "wrist_pitch"
    assert (loaded.rms_px, loaded.per_view_rms_px, loaded.views_used) == (0.21, (0.2, 0.22), (0, 2))
    assert (loaded.method, loaded.translation_std_mm, loaded.pose_rms_mm) == ("park", 0.4, 0.3)
    assert loaded.created == result.created
    save_hand_eye(path, result, link="forearm")
    assert load_hand_eye(path).link == "forearm"


def test_hand_eye_made_with_other_intrinsics_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "hand_eye.json"
    save_hand_eye(path, hand_eye())
    other = CameraIntrinsics("pinhole", 640, 480, K + np.diag([0.5, 0.0, 0.0]), INTR.distortion)
    with pytest.raises(CalibrationError, match="made with other camera intrinsics") as err:
        load_hand_eye(path, intrinsics=other)
    assert "hand_eye.json" in str(err.value) and "'intrinsics'" in str(err.value)
    # Intrinsics loaded back from their own file are the very same values.
    camera = tmp_path / "camera.json"
    save_intrinsics(camera, INTR)
    load_hand_eye(path, intrinsics=load_intrinsics(camera))


@pytest.mark.parametrize(
    ("change", "match"),
    [
        (lambda d: d.update(version=0), "'version' is 0"),
        (lambda d: d.pop("cam2link"), "missing key 'cam2link'"),
        (lambda d: d.pop("intrinsics"), "missing key 'intrinsics'"),
        (lambda d: d.update(link=""), "'link'"),
        (lambda d: d["cam2link"][0].__setitem__(0, 2.0), "'cam2link'.*not a rigid transform"),
        (lambda d: d["cam2link"][3].__setitem__(0, 1.0), "'cam2link'.*not a rigid transform"),
        (lambda d: d.update(board2base=[[1, 0, 0, 0]] * 4), "'board2base'.*not a rigid"),
        (lambda d: d["intrinsics"].update(width_px=300), "key 'intrinsics'.*principal point"),
        (lambda d: d.update(views_used=[0.5]), "'views_used'"),
    ],
)
def test_bad_hand_eye_files(tmp_path: Path, change: object, match: str) -> None:
    path = tmp_path / "hand_eye.json"
    save_hand_eye(path, hand_eye())
    edit(path, change)
    with pytest.raises(CalibrationError, match=match) as err:
        load_hand_eye(path)
    assert "hand_eye.json" in str(err.value)


def test_non_finite_hand_eye_file(tmp_path: Path) -> None:
    path = tmp_path / "hand_eye.json"
    save_hand_eye(path, hand_eye())
    data = json.loads(path.read_text())
    data["cam2link"][0][3] = float("nan")
    path.write_text(json.dumps(data))  # Python writes the NaN token
    with pytest.raises(CalibrationError, match="'cam2link' has non-finite numbers"):
        load_hand_eye(path)
