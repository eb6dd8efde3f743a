"""A twin's camera calibrated by our own flows, as on hardware: pictures of boards lying
on its table, taken at measured joints, solved by busarm.vision.calibration.

The boards lie on twins of their own that share the job twin's arm, lens and camera
mount, so the calibration found is the job twin's camera's. Those twins run on a
simulated clock: calibrating takes as long as the CPU needs, not as long as the moves.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from busarm.arm.arm import Arm
from busarm.arm.camera_mount import CameraMount
from busarm.bus.driver import ServoBus
from busarm.errors import ConfigError
from busarm.progress import Progress, quiet
from busarm.robot.calibration_store import MadeFor
from busarm.robot.camera_calibration import (
    CalibrationView,
    calibration_views,
    capture_views,
    hand_eye_from_views,
    intrinsics_from_views,
)
from busarm.twin.boards import BOARD_SPECS
from busarm.twin.camera import TwinCamera
from busarm.twin.spec import TwinSpec
from busarm.twin.transport import TwinTransport
from busarm.twin.twin import Twin
from busarm.vision.calibration import load_intrinsics, save_hand_eye, save_intrinsics

__all__ = [
    "HAND_EYE_VIEWS",
    "INTRINSICS_VIEWS",
    "TwinCalibration",
    "calibrate_twin_camera",
]


INTRINSICS_VIEWS = 12
HAND_EYE_VIEWS = 10


@dataclass(frozen=True)
class TwinCalibration:
    """What calibrating a twin's camera wrote and found (errors against the twin's truth)."""

    intrinsics_path: Path
    hand_eye_path: Path
    intrinsics_rms_px: float | None
    intrinsics_views: int
    hand_eye_rms_px: float
    hand_eye_views: int
    hand_eye_error_mm: float
    """How far the calibrated camera is from where the twin really put it."""
    hand_eye_error_deg: float

    def to_dict(self) -> dict[str, object]:
        out = asdict(self)
        out["intrinsics_path"], out["hand_eye_path"] = (str(self.intrinsics_path),
                                                         str(self.hand_eye_path))
        return out


def _board_twin(job: Twin, board: str) -> Twin:
    """A twin like ``job`` (arm, lens, camera mount) with only ``board`` on its table."""
    return Twin(job.config, TwinSpec(board=board).make_scene(), lens=job.lens,
                mount=job.mount, realtime=False)


def _pictures(job: Twin, board: str, views: int, seed: int, progress: Progress,
              what: str) -> list[CalibrationView]:
    twin = _board_twin(job, board)
    with Arm(ServoBus(TwinTransport(twin)), twin.config) as arm, TwinCamera(twin) as camera:
        spec = BOARD_SPECS[board]
        poses = calibration_views(arm.kin, spec, twin.board2base(0), views, seed=seed,
                                  mount=CameraMount.from_config(twin.config.camera))
        return capture_views(
            arm, camera, poses, spec,
            progress=lambda i, n, v: progress(f"{what} view {i + 1}/{n}"))


def calibrate_twin_camera(job: Twin, out_dir: Path, *,
                          intrinsics: Path | None = None,
                          intrinsics_views: int = INTRINSICS_VIEWS,
                          hand_eye_views: int = HAND_EYE_VIEWS, seed: int = 0,
                          progress: Progress = quiet,
                          made_for: MadeFor | None = None) -> TwinCalibration:
    """Calibrate ``job``'s camera (intrinsics unless given, then hand-eye) into
    ``out_dir``/camera.json and hand_eye.json, each recording ``made_for`` (default: the
    twin's camera, robot ``twin``; see busarm.robot.calibration_store)."""
    if made_for is None:
        made_for = MadeFor.of("twin", (job.lens.width_px, job.lens.height_px), job.config, job)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot make the calibration folder {out_dir}: {exc.strerror}"
                          ) from None
    he_path = out_dir / "hand_eye.json"
    rms: float | None = None
    n_intr = 0
    if intrinsics is None:
        intrinsics = out_dir / "camera.json"
        views = _pictures(job, "chessboard", intrinsics_views, seed, progress, "intrinsics")
        result = intrinsics_from_views(views)
        save_intrinsics(intrinsics, result, made_for=made_for.intrinsics())
        rms, n_intr = result.rms_px, len(views)
    intr = load_intrinsics(intrinsics)
    views = _pictures(job, "tags", hand_eye_views, seed + 1, progress, "hand-eye")
    he = hand_eye_from_views(views, intr)
    save_hand_eye(he_path, he, made_for=made_for.hand_eye())
    delta = np.linalg.inv(job.mount.cam2link) @ he.cam2link
    cos = max(-1.0, min(1.0, (float(np.trace(delta[:3, :3])) - 1) / 2))
    return TwinCalibration(intrinsics, he_path, rms, n_intr, he.rms_px, len(he.views_used),
                           float(np.linalg.norm(delta[:3, 3])), math.degrees(math.acos(cos)))
