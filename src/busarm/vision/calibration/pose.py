"""A board's pose in one view, and reprojection errors."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.optimize import least_squares

from busarm.errors import ConfigError, VisionError
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.calibration.core import FloatArray, _rotvec_matrix, _transform
from busarm.vision.calibration.detection import BoardObservation, _collinear

__all__ = [
    "OUTLIER_VIEW_PX",
    "board_pose",
]


OUTLIER_VIEW_PX = 1.0
"""A view is an outlier if its rms exceeds 3x the median and this."""


def _reprojection(
    intr: CameraIntrinsics, obj: FloatArray, img: FloatArray, board2cam: FloatArray
) -> FloatArray:
    p = obj @ board2cam[:3, :3].T + board2cam[:3, 3]
    p[:, 2] = np.maximum(p[:, 2], 1e-6)  # behind the camera: a huge error, not a sign flip
    out: FloatArray = intr._project(p) - img
    return out


def _rms(err: FloatArray) -> float:
    return float(np.sqrt((err * err).sum(axis=1).mean()))


def board_pose(
    observation: BoardObservation, intrinsics: CameraIntrinsics
) -> tuple[FloatArray, float]:
    """(board2cam in mm, rms reprojection error px) of one observation.

    The points are undistorted (either model), the planar pose solved in closed form
    (IPPE, the better of its two solutions), then refined by Levenberg-Marquardt on the
    pixel reprojection error through the full distortion model.
    """
    if observation.image_size != intrinsics.size:
        raise ConfigError(
            f"the observation comes from a {observation.image_size[0]}x"
            f"{observation.image_size[1]} image but the intrinsics are for "
            f"{intrinsics.width_px}x{intrinsics.height_px}"
        )
    obj = observation.object_points_mm
    img = observation.image_points_px
    if obj.shape[0] < 4 or _collinear(obj):
        raise VisionError(f"a board pose needs 4 points not on one line, got {obj.shape[0]}")
    norm = intrinsics.normalized_from_pixels(img)
    candidates: list[FloatArray] = []
    for method in (cv2.SOLVEPNP_IPPE, cv2.SOLVEPNP_SQPNP):
        try:
            n, rvecs, tvecs, _ = cv2.solvePnPGeneric(
                obj, norm, np.eye(3), np.zeros(4), flags=method
            )
        except cv2.error:
            continue
        for rv, tv in zip(rvecs[:n], tvecs[:n], strict=True):
            candidates.append(
                _transform(
                    _rotvec_matrix(np.asarray(rv, np.float64).ravel()),
                    np.asarray(tv, np.float64).ravel(),
                )
            )
        if candidates:
            break
    candidates = [c for c in candidates if np.all(np.isfinite(c)) and c[2, 3] > 0.0]
    if not candidates:
        raise VisionError("no board pose fits the observation")
    best = min(candidates, key=lambda c: _rms(_reprojection(intrinsics, obj, img, c)))
    refined = _refine_pose(intrinsics, obj, img, best)
    p = obj @ refined[:3, :3].T + refined[:3, 3]
    if np.any(p[:, 2] <= 0.0):
        raise VisionError("the fitted board pose puts board points behind the camera")
    return refined, _rms(_reprojection(intrinsics, obj, img, refined))


def _refine_pose(
    intr: CameraIntrinsics, obj: FloatArray, img: FloatArray, start: FloatArray
) -> FloatArray:
    r0 = start[:3, :3]

    def residual(x: FloatArray) -> FloatArray:
        t = _transform(_rotvec_matrix(x[:3]) @ r0, start[:3, 3] + x[3:])
        return _reprojection(intr, obj, img, t).ravel()

    res = least_squares(residual, np.zeros(6), method="lm", x_scale="jac")
    x = res.x
    return _transform(_rotvec_matrix(x[:3]) @ r0, start[:3, 3] + x[3:])
