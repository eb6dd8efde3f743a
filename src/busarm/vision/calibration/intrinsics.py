"""Intrinsic calibration: a camera model fitted to board observations."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from busarm.errors import ConfigError, VisionError
from busarm.units import check_int_range, listing
from busarm.vision.calibration.camera_model import MODELS, CameraIntrinsics
from busarm.vision.calibration.core import _rotvec_matrix
from busarm.vision.calibration.detection import BoardObservation, _found_views
from busarm.vision.calibration.pose import OUTLIER_VIEW_PX

__all__ = [
    "MIN_INTRINSIC_VIEWS",
    "IntrinsicsResult",
    "calibrate_intrinsics",
]


MIN_INTRINSIC_VIEWS = 6


@dataclass(frozen=True)
class IntrinsicsResult:
    """A calibration: the intrinsics, rms and per-view rms reprojection error (px), and
    which input views were used (indices into the list given) or dropped as outliers or
    ill-conditioned."""

    intrinsics: CameraIntrinsics
    rms_px: float
    per_view_rms_px: tuple[float, ...]
    views_used: tuple[int, ...]
    views_dropped: tuple[int, ...] = ()
    board: str = ""


def calibrate_intrinsics(
    observations: Sequence[BoardObservation | None],
    image_size: tuple[int, int],
    model: str = "pinhole",
    *,
    fix_k3: bool = False,
    rational: bool = False,
    min_views: int = MIN_INTRINSIC_VIEWS,
    reject_outliers: bool = True,
) -> IntrinsicsResult:
    """Intrinsics from board observations (None entries, boards not found, are skipped).

    ``image_size`` is (width, height). Pinhole: ``cv2.calibrateCamera`` with k1 k2 p1 p2
    k3 (``fix_k3`` keeps k3 = 0; ``rational`` adds k4..k6). Fisheye:
    ``cv2.fisheye.calibrate``; a view it finds ill-conditioned is dropped and the
    calibration retried. With ``reject_outliers`` a view whose rms exceeds both 3x the
    median and 1 px is dropped once and the calibration redone. VisionError when fewer
    than ``min_views`` views remain.
    """
    if model not in MODELS:
        raise ConfigError(f"camera model {model!r} is not one of {', '.join(MODELS)}")
    width = check_int_range("image_size width", image_size[0], 1, 100_000)
    height = check_int_range("image_size height", image_size[1], 1, 100_000)
    check_int_range("min_views", min_views, 1, 10_000)
    used = _found_views(observations, min_views, "images")
    found = _views_of_size(observations, used, (width, height))
    boards = sorted({o.spec.describe() for o in found.values()})
    dropped: list[int] = []
    calibrate = _calibrate_pinhole if model == "pinhole" else _calibrate_fisheye
    flags = (cv2.CALIB_FIX_K3 if fix_k3 else 0) | (cv2.CALIB_RATIONAL_MODEL if rational else 0)
    while True:
        if len(used) < min_views:
            raise VisionError(
                f"{len(used)} usable views of {len(observations)} after dropping "
                f"{listing(sorted(dropped))}; need at least {min_views}"
            )
        try:
            intr, per_view = calibrate([found[i] for i in used], (width, height), flags)
        except _IllConditioned as exc:
            dropped.append(used.pop(exc.index))
            continue
        if reject_outliers:
            limit = max(OUTLIER_VIEW_PX, 3.0 * float(np.median(per_view)))
            bad = [k for k, e in enumerate(per_view) if e > limit]
            if bad and len(used) - len(bad) >= min_views:
                dropped.extend(used[k] for k in bad)
                used = [u for k, u in enumerate(used) if k not in bad]
                reject_outliers = False  # once: the second pass must converge to a result
                continue
        break
    total = sum(found[i].count for i in used)
    sq = sum(e * e * found[i].count for i, e in zip(used, per_view, strict=True))
    return IntrinsicsResult(
        intr, math.sqrt(sq / total), tuple(float(e) for e in per_view), tuple(used),
        tuple(sorted(dropped)), "; ".join(boards),
    )


def _views_of_size(
    observations: Sequence[BoardObservation | None], used: list[int], size: tuple[int, int]
) -> dict[int, BoardObservation]:
    """The used observations; ConfigError for one from an image of another size."""
    width, height = size
    found: dict[int, BoardObservation] = {}
    for i in used:
        o = observations[i]
        assert o is not None
        found[i] = o
        if o.image_size != (width, height):
            raise ConfigError(
                f"observation #{i} comes from a {o.image_size[0]}x{o.image_size[1]} image, "
                f"not {width}x{height}"
            )
    return found


class _IllConditioned(Exception):
    def __init__(self, index: int) -> None:
        super().__init__(index)
        self.index = index


def _calibrate_pinhole(
    obs: list[BoardObservation], size: tuple[int, int], flags: int
) -> tuple[CameraIntrinsics, list[float]]:
    objp = [o.object_points_mm.astype(np.float32) for o in obs]
    imgp = [o.image_points_px.astype(np.float32).reshape(-1, 1, 2) for o in obs]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    try:
        _, k, d, _, _, _, _, per_view = cv2.calibrateCameraExtended(
            objp, imgp, size, np.eye(3), np.zeros(8 if flags & cv2.CALIB_RATIONAL_MODEL else 5),
            flags=flags, criteria=criteria,
        )
    except cv2.error as exc:
        raise VisionError(f"camera calibration failed: {exc.err}") from None
    dist = np.asarray(d, np.float64).ravel()[: 8 if flags & cv2.CALIB_RATIONAL_MODEL else 5]
    kk = np.asarray(k, np.float64)
    kk[0, 1] = 0.0  # OpenCV's pinhole calibration has no skew; make the zero exact
    try:
        intr = CameraIntrinsics("pinhole", size[0], size[1], kk, dist)
    except ConfigError as exc:
        raise VisionError(f"camera calibration gave unusable intrinsics: {exc}") from None
    return intr, [float(e) for e in np.asarray(per_view).ravel()]


def _calibrate_fisheye(
    obs: list[BoardObservation], size: tuple[int, int], flags: int
) -> tuple[CameraIntrinsics, list[float]]:
    del flags  # the pinhole options do not apply
    objp = [o.object_points_mm.reshape(1, -1, 3) for o in obs]
    imgp = [o.image_points_px.reshape(1, -1, 2) for o in obs]
    fe_flags = (
        cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
        | cv2.fisheye.CALIB_CHECK_COND
    )
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    try:
        _, k, d, rvecs, tvecs = cv2.fisheye.calibrate(
            objp, imgp, size, np.eye(3), np.zeros(4), flags=fe_flags, criteria=criteria
        )
    except cv2.error as exc:
        # "CALIB_CHECK_COND - Ill-conditioned matrix for input array N": drop view N.
        m = re.search(r"input array (\d+)", str(exc))
        if m and int(m.group(1)) < len(obs):
            raise _IllConditioned(int(m.group(1))) from None
        raise VisionError(f"fisheye calibration failed: {exc.err}") from None
    kk = np.asarray(k, np.float64)
    kk[0, 1] = 0.0
    try:
        intr = CameraIntrinsics("fisheye", size[0], size[1], kk, np.asarray(d, np.float64).ravel())
    except ConfigError as exc:
        raise VisionError(f"fisheye calibration gave unusable intrinsics: {exc}") from None
    per_view = []
    for o, rv, tv in zip(obs, rvecs, tvecs, strict=True):
        rot = _rotvec_matrix(np.asarray(rv, np.float64).ravel())
        p_cam = o.object_points_mm @ rot.T + np.asarray(tv, np.float64).ravel()
        e = intr._project(p_cam) - o.image_points_px
        per_view.append(float(np.sqrt((e * e).sum(axis=1).mean())))
    return intr, per_view
