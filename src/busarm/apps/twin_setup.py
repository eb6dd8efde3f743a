"""The twin set up for a job: an Arm on a fresh twin, and the twin's camera calibrated by
our own flows (as on hardware: pictures of boards at measured joints), for the commands
and benchmarks that need both."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from busarm.apps.camera_calibration import (
    calibration_views,
    capture_views,
    hand_eye_from_views,
    intrinsics_from_views,
)
from busarm.arm.arm import Arm
from busarm.bus.driver import ServoBus
from busarm.twin.boards import BOARD_SPECS
from busarm.twin.camera import TwinCamera
from busarm.twin.scene import Scene
from busarm.twin.transport import TwinTransport
from busarm.twin.twin import Twin
from busarm.vision.calibration import load_intrinsics, save_hand_eye, save_intrinsics

Progress = Callable[[str], None]


def quiet(_: str) -> None:
    """A progress callback that says nothing."""


def open_twin_arm(url_or_scene: str | Scene) -> tuple[Arm, Twin]:
    """An Arm on a new real-time twin (its transport owns the twin)."""
    if isinstance(url_or_scene, Scene):
        twin = Twin(scene=url_or_scene)
        try:
            return Arm(ServoBus(TwinTransport(twin)), twin.config), twin
        except BaseException:
            twin.close()
            raise
    arm = Arm.open(url_or_scene)
    transport = arm.bus.transport
    assert isinstance(transport, TwinTransport)
    return arm, transport.twin


def calibrate_in_twin(out_dir: Path, *, intrinsics_views: int = 20, hand_eye_views: int = 16,
                      seed: int = 0, progress: Progress = quiet
                      ) -> tuple[Path, Path, dict[str, Any]]:
    """Run both calibration flows in the twin; write and return the two files."""
    out_dir.mkdir(parents=True, exist_ok=True)
    intr_path, he_path = out_dir / "camera.json", out_dir / "hand_eye.json"
    summary: dict[str, Any] = {}
    arm, twin = open_twin_arm("twin://?board=chessboard")
    with arm, TwinCamera(twin) as camera:
        spec = BOARD_SPECS["chessboard"]
        poses = calibration_views(arm.kin, spec, twin.board2base(0), intrinsics_views, seed=seed)
        views = capture_views(arm, camera, poses, spec,
                              progress=lambda i, n, v: progress(f"intrinsics view {i + 1}/{n}"))
        result = intrinsics_from_views(views)
        save_intrinsics(intr_path, result)
        summary["intrinsics"] = {"rms_px": result.rms_px, "views": len(views),
                                 "fx_px": result.intrinsics.fx, "fy_px": result.intrinsics.fy,
                                 "cx_px": result.intrinsics.cx, "cy_px": result.intrinsics.cy}
    intrinsics = load_intrinsics(intr_path)
    arm, twin = open_twin_arm("twin://?board=tags")
    with arm, TwinCamera(twin) as camera:
        spec = BOARD_SPECS["tags"]
        poses = calibration_views(arm.kin, spec, twin.board2base(0), hand_eye_views,
                                  seed=seed + 1)
        views = capture_views(arm, camera, poses, spec,
                              progress=lambda i, n, v: progress(f"hand-eye view {i + 1}/{n}"))
        he = hand_eye_from_views(views, intrinsics)
        save_hand_eye(he_path, he)
        truth = twin.mount.cam2link
        delta = np.linalg.inv(truth) @ he.cam2link
        summary["hand_eye"] = {
            "rms_px": he.rms_px, "views": len(he.views_used),
            "error_vs_truth_mm": float(np.linalg.norm(delta[:3, 3])),
            "error_vs_truth_deg": math.degrees(math.acos(
                max(-1.0, min(1.0, (np.trace(delta[:3, :3]) - 1) / 2)))),
        }
    return intr_path, he_path, summary
