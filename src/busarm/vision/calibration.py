"""Camera calibration for the wrist camera: intrinsics, calibration boards, hand-eye.

Conventions (every public function):

- Millimetres and degrees; radians only inside.
- Transforms are 4x4 float64 homogeneous matrices named ``a2b``: ``p_b = a2b @ p_a``
  (``board2cam``, ``cam2link``, ``link2base``, ``board2base``).
- The OpenCV camera frame: x right, y down, z forward (out of the lens). Pixel
  coordinates are OpenCV's: the *centre* of pixel (u, v) is at (u, v), so a 640x480
  image spans -0.5 .. 639.5 by -0.5 .. 479.5 (the centroid of a mask's pixel indices is
  in the same coordinates).
- Board frames: origin at the pattern's outer top-left corner (chessboard and ChArUco:
  the corner of the square grid; tag board: the outer corner of the first tag's black
  border), x along the columns, y along the rows (down the printed page), z = x cross y
  pointing into the board, the surface at z = 0. A camera in front of the board sees
  the board's z axis pointing away from it. ``board_image`` documents the relation
  between the printable image's pixels and this frame exactly.

The flow:

1. Intrinsics: 10..30 images of a ChArUco board (or a chessboard) covering the whole
   image at tilts up to about 45 deg; ``find_board`` on each, ``calibrate_intrinsics``,
   ``save_intrinsics``.
2. Hand-eye (eye-in-hand: the camera rides on the wrist-pitch link): a tag board (or a
   ChArUco board) fixed on the table, the arm at 8..20 poses that turn the base *and*
   tilt the wrist; for each pose ``link2base`` (forward kinematics of the measured
   joints, DH frame 4) and ``find_board``; then ``calibrate_hand_eye``, ``save_hand_eye``.
   A chessboard cannot be used here: its pose is ambiguous under a half turn.
"""

from __future__ import annotations

import datetime as _dt
import functools
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Union

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from busarm.errors import CalibrationError, ConfigError, VisionError
from busarm.fileio import read_versioned_json, write_text_atomic
from busarm.units import check_int_range

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
UInt8Array = npt.NDArray[np.uint8]

MODELS = ("pinhole", "fisheye")
INTRINSICS_FORMAT = "busarm.camera_intrinsics"
HAND_EYE_FORMAT = "busarm.hand_eye"
FORMAT_VERSION = 1
TAG_DICTIONARY = "DICT_APRILTAG_36h11"
"""The tag family of ``TagBoardSpec`` (the vendor's AprilTags are 36h11 as well)."""

UNDISTORT_TOL_PX = 0.01
"""An undistorted point re-distorts to within this of its pixel, or it is refused."""
_POLISH_PX = 1e-4
"""OpenCV's undistortion is polished with Newton steps when it is off by more than this."""
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-6)
RIGID_TOL = 1e-6
"""Largest |R R^T - I| entry (and bottom-row error) accepted for a rigid transform."""
MIN_INTRINSIC_VIEWS = 6
MIN_HAND_EYE_VIEWS = 3
OUTLIER_VIEW_PX = 1.0
"""A view is an outlier if its rms exceeds 3x the median and this."""
_MIN_MOTION_DEG = 3.0
"""Relative rotations smaller than this tell nothing about the hand-eye rotation axis."""
_MIN_AXIS_SPREAD_DEG = 10.0
"""Two motion axes at least this far apart make a hand-eye calibration well posed."""


# --------------------------------------------------------------------------- helpers


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def _array(name: str, value: object, shape: tuple[int, ...] | None = None) -> FloatArray:
    """``value`` as a finite float64 array (of ``shape``), else ConfigError naming ``name``."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be an array of numbers, got {value!r:.80}") from None
    if shape is not None and arr.shape != shape:
        raise ConfigError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ConfigError(f"{name} must be finite, got {arr.tolist()!r:.120}")
    return arr


def _points(name: str, value: object, dim: int) -> FloatArray:
    """(N, dim) finite float64 points; a single point may be given flat."""
    arr = _array(name, value)
    if arr.ndim == 1 and arr.shape[0] == dim:
        arr = arr.reshape(1, dim)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ConfigError(f"{name} must be an (N, {dim}) array, got shape {arr.shape}")
    return arr


def _readonly(arr: FloatArray) -> FloatArray:
    out = np.array(arr, dtype=np.float64)
    out.setflags(write=False)
    return out


def as_transform(name: str, value: object) -> FloatArray:
    """``value`` as a rigid 4x4 transform (a copy), else ConfigError naming ``name``."""
    t = _array(name, value, (4, 4))
    # Plain floats: this check runs once per located frame, and numpy's small-array
    # overhead (np.linalg.det alone) would cost more than the arithmetic.
    (a, b, c, _), (d, e, f, _), (g, h, i, _), bottom = t.tolist()
    worst = max(
        abs(a * a + b * b + c * c - 1.0), abs(d * d + e * e + f * f - 1.0),
        abs(g * g + h * h + i * i - 1.0), abs(a * d + b * e + c * f),
        abs(a * g + b * h + c * i), abs(d * g + e * h + f * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    off = max(abs(bottom[0]), abs(bottom[1]), abs(bottom[2]), abs(bottom[3] - 1.0))
    if not (worst <= RIGID_TOL and det > 0.0 and off <= RIGID_TOL):
        raise ConfigError(
            f"{name} is not a rigid transform (rotation must be orthonormal with det +1 "
            f"within {RIGID_TOL:g}, bottom row 0 0 0 1)"
        )
    return t


def invert_transform(a2b: FloatArray) -> FloatArray:
    """b2a of a rigid a2b."""
    out = np.eye(4)
    r = a2b[:3, :3]
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ a2b[:3, 3]
    return out


def _transform(rotation: FloatArray, translation: FloatArray) -> FloatArray:
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


def _rotvec_matrix(rotvec: FloatArray) -> FloatArray:
    out: FloatArray = Rotation.from_rotvec(rotvec).as_matrix()
    return out


def _mean_rotation(rotations: FloatArray) -> FloatArray:
    """Chordal mean of (N, 3, 3) rotations (nearest rotation to their sum)."""
    u, _, vt = np.linalg.svd(rotations.sum(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    out: FloatArray = u @ np.diag([1.0, 1.0, d]) @ vt
    return out


# --------------------------------------------------------------------------- intrinsics


@dataclass(frozen=True, eq=False)
class CameraIntrinsics:
    """A camera's projection: model, image size, camera matrix and distortion.

    ``model`` ``"pinhole"``: OpenCV's model, distortion k1 k2 p1 p2 [k3 [k4 k5 k6]]
    (4, 5 or 8 values). ``"fisheye"``: OpenCV's fisheye (equidistant) model, k1..k4.
    ``calibrated`` False marks values not measured on this camera (``vendor_default``).
    Arrays are stored read-only; equality compares every value exactly.
    """

    model: str
    width_px: int
    height_px: int
    camera_matrix: FloatArray
    distortion: FloatArray
    calibrated: bool = True
    _coef: tuple[float, ...] = field(init=False, repr=False, default=())
    _focal: FloatArray = field(init=False, repr=False, default_factory=lambda: np.ones(2))
    _principal: FloatArray = field(init=False, repr=False, default_factory=lambda: np.zeros(2))
    _tangential: FloatArray = field(
        init=False, repr=False, default_factory=lambda: np.zeros((2, 2))
    )
    _focal_h: FloatArray = field(init=False, repr=False, default_factory=lambda: np.ones(3))
    _principal_h: FloatArray = field(init=False, repr=False, default_factory=lambda: np.ones(3))
    _tangential_h: FloatArray = field(
        init=False, repr=False, default_factory=lambda: np.zeros((2, 3))
    )
    _cache: dict[str, Any] = field(init=False, repr=False, default_factory=dict)

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ConfigError(f"camera model {self.model!r} is not one of {', '.join(MODELS)}")
        check_int_range("width_px", self.width_px, 1, 100_000)
        check_int_range("height_px", self.height_px, 1, 100_000)
        k = _array("camera_matrix", self.camera_matrix, (3, 3))
        if k[0, 1] != 0.0 or k[1, 0] != 0.0 or k[2, 0] != 0.0 or k[2, 1] != 0.0 or k[2, 2] != 1.0:
            raise ConfigError(
                f"camera_matrix must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), "
                f"got {k.tolist()}"
            )
        fx, fy, cx, cy = float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])
        for name, value in (("fx", fx), ("fy", fy)):
            if not 0.0 < value <= 1e6:
                raise ConfigError(f"camera_matrix {name} = {value!r} px is out of range 0..1e6")
        if not 0.0 <= cx <= self.width_px or not 0.0 <= cy <= self.height_px:
            raise ConfigError(
                f"principal point ({cx:g}, {cy:g}) px is outside the {self.width_px}x"
                f"{self.height_px} image (cx 0..{self.width_px}, cy 0..{self.height_px})"
            )
        d = _array("distortion", self.distortion).ravel()
        allowed = (4, 5, 8) if self.model == "pinhole" else (4,)
        if d.size not in allowed:
            raise ConfigError(
                f"{self.model} distortion must have {' or '.join(map(str, allowed))} "
                f"coefficients, got {d.size}"
            )
        if not isinstance(self.calibrated, bool):
            raise ConfigError(f"calibrated must be True or False, got {self.calibrated!r}")
        object.__setattr__(self, "camera_matrix", _readonly(k))
        object.__setattr__(self, "distortion", _readonly(d))
        # Plain floats for the hot projection path: k1..k6, p1, p2 (pinhole) or k1..k4.
        if self.model == "pinhole":
            full = np.zeros(8)
            full[: d.size] = d
            k1, k2, p1, p2, k3, k4, k5, k6 = (float(v) for v in full)
            coef: tuple[float, ...] = (fx, fy, cx, cy, k1, k2, k3, k4, k5, k6, p1, p2)
        else:
            coef = (fx, fy, cx, cy, *(float(v) for v in d))
        object.__setattr__(self, "_coef", coef)
        object.__setattr__(self, "_focal", np.array([fx, fy]))
        object.__setattr__(self, "_principal", np.array([cx, cy]))
        object.__setattr__(self, "_focal_h", np.array([fx, fy, 0.0]))
        object.__setattr__(self, "_principal_h", np.array([cx, cy, 1.0]))
        if self.model == "pinhole":
            # Rows: the x y term's (p1, p2) and the r^2 + 2 x^2 (y^2) term's (p2, p1).
            object.__setattr__(self, "_tangential", np.array([[p1, p2], [p2, p1]]))
            object.__setattr__(
                self, "_tangential_h", np.array([[2.0 * p1, 2.0 * p2, 0.0], [p2, p1, 0.0]])
            )

    # Values, not identity: two loads of one file are equal.
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, CameraIntrinsics):
            return NotImplemented
        return (
            self.model == other.model and self.width_px == other.width_px
            and self.height_px == other.height_px and self.calibrated == other.calibrated
            and np.array_equal(self.camera_matrix, other.camera_matrix)
            and np.array_equal(self.distortion, other.distortion)
        )

    def __hash__(self) -> int:
        return hash((self.model, self.width_px, self.height_px, self._coef, self.calibrated))

    @property
    def fx(self) -> float:
        return self._coef[0]

    @property
    def fy(self) -> float:
        return self._coef[1]

    @property
    def cx(self) -> float:
        return self._coef[2]

    @property
    def cy(self) -> float:
        return self._coef[3]

    @property
    def size(self) -> tuple[int, int]:
        """(width_px, height_px)."""
        return (self.width_px, self.height_px)

    @classmethod
    def vendor_default(cls) -> CameraIntrinsics:
        """The vendor's calibration file for its 640x480 camera, marked not calibrated.

        Useful to start with; calibrate the actual camera (``calibrated`` is False).
        """
        k = np.array([[473.45, 0.0, 323.55], [0.0, 474.22, 238.60], [0.0, 0.0, 1.0]])
        d = np.array([-0.0275, -0.0005, -0.0059, -0.0034, -0.0356])
        return cls("pinhole", 640, 480, k, d, calibrated=False)

    def describe(self) -> str:
        d = " ".join(f"{v:.5g}" for v in self.distortion)
        tag = "" if self.calibrated else ", not calibrated for this camera"
        return (
            f"{self.model} {self.width_px}x{self.height_px}: fx {self.fx:.2f} fy {self.fy:.2f} "
            f"cx {self.cx:.2f} cy {self.cy:.2f} px, distortion [{d}]{tag}"
        )

    # ---------------------------------------------------------------- projection

    def _distort(self, xy: FloatArray) -> FloatArray:
        """Undistorted normalised coordinates (..., 2) -> pixels (..., 2). No checks.

        Written for few, small numpy operations: it runs in the block-location loop.
        """
        c = self._coef
        if self.model == "fisheye":
            r = np.sqrt((xy * xy).sum(axis=-1))
            theta = np.arctan(r)
            t2 = theta * theta
            theta_d = theta * (1.0 + t2 * (c[4] + t2 * (c[5] + t2 * (c[6] + t2 * c[7]))))
            # theta_d / r -> 1 as r -> 0; the guard keeps the division finite.
            scale = np.where(r > 1e-12, theta_d / np.maximum(r, 1e-12), 1.0)
            d = xy * scale[..., None]
        else:
            k1, k2, k3, k4, k5, k6, p1, p2 = c[4:]
            sq = xy * xy
            r2 = sq[..., 0] + sq[..., 1]
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            if k4 or k5 or k6:
                radial /= 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
            d = xy * radial[..., None]
            if p1 or p2:
                # x: 2 p1 x y + p2 (r2 + 2 x^2);  y: 2 p2 x y + p1 (r2 + 2 y^2)
                sq *= 2.0
                sq += r2[..., None]
                sq *= self._tangential[1]
                d += sq
                d += (2.0 * xy[..., 0] * xy[..., 1])[..., None] * self._tangential[0]
        d *= self._focal
        d += self._principal
        out: FloatArray = d
        return out

    def _project_h(self, p_cam: FloatArray) -> FloatArray:
        """Camera points (..., 3), z > 0, to homogeneous pixels (u, v, 1). No checks.

        The block-location hot path: the third column lets one matrix product give a
        polygon's area and moments together. Same model as ``_distort``, fewer steps.
        """
        q = p_cam / p_cam[..., 2:3]  # (x, y, 1)
        if self.model == "fisheye":
            out = np.empty(q.shape)
            out[..., :2] = self._distort(q[..., :2])
            out[..., 2] = 1.0
            return out
        k1, k2, k3, k4, k5, k6, p1, p2 = self._coef[4:]
        sq = q * q
        r2 = sq[..., 0] + sq[..., 1]
        radial = r2 * k3
        radial += k2
        radial *= r2
        radial += k1
        radial *= r2
        radial += 1.0
        if k4 or k5 or k6:
            radial /= 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        d = q * radial[..., None]
        if p1 or p2:
            sq *= 2.0
            sq += r2[..., None]
            sq *= self._tangential_h[1]
            d += sq
            d += (q[..., 0] * q[..., 1])[..., None] * self._tangential_h[0]
        d *= self._focal_h  # (fx, fy, 0)
        d += self._principal_h  # (cx, cy, 1)
        return d

    def _project(self, p_cam: FloatArray) -> FloatArray:
        """Camera points (..., 3), z > 0, to distorted pixels (..., 2). No checks."""
        return self._distort(p_cam[..., :2] / p_cam[..., 2:3])

    def pixels_from_camera_points(self, p_cam_mm: npt.ArrayLike) -> FloatArray:
        """(N, 3) points in the camera frame (mm) -> (N, 2) distorted pixels.

        VisionError if a point is not in front of the camera (z <= 0).
        """
        p = _points("p_cam_mm", p_cam_mm, 3)
        behind = np.flatnonzero(p[:, 2] <= 0.0)
        if behind.size:
            i = int(behind[0])
            raise VisionError(
                f"point #{i} {p[i].tolist()} mm is not in front of the camera (z must be > 0)"
            )
        return self._project(p)

    def normalized_from_pixels(self, px: npt.ArrayLike) -> FloatArray:
        """(N, 2) pixels -> (N, 2) undistorted normalised coordinates (x/z, y/z).

        Undone to within 0.01 px (checked by distorting back; typically 1e-6 px).
        VisionError for a pixel the distortion model cannot reach (beyond where a strong
        distortion folds over).
        """
        p = _points("px", px, 2)
        src = p.reshape(-1, 1, 2)
        if self.model == "pinhole":
            out = cv2.undistortPointsIter(
                src, self.camera_matrix, self.distortion, np.eye(3), np.eye(3),
                _UNDISTORT_CRITERIA,
            )
        else:
            out = cv2.fisheye.undistortPoints(
                src, self.camera_matrix, self.distortion, criteria=_UNDISTORT_CRITERIA
            )
        xy = np.asarray(out, dtype=np.float64).reshape(-1, 2)
        err = np.abs(self._distort(xy) - p).max(axis=1)
        bad = ~(err <= _POLISH_PX)
        if np.any(bad):
            xy[bad] = self._polish(xy[bad], p[bad])
            err[bad] = np.abs(self._distort(xy[bad]) - p[bad]).max(axis=1)
        # A strong distortion polynomial turns back beyond some radius; an answer out
        # there (or none) means no ray of the lens reaches that pixel.
        still = np.flatnonzero(~(err <= UNDISTORT_TOL_PX) | ~self._one_to_one(xy))
        if still.size:
            i = int(still[0])
            raise VisionError(
                f"pixel ({p[i, 0]:.2f}, {p[i, 1]:.2f}) (#{i}) cannot be undistorted: it lies "
                f"beyond where the distortion model is one-to-one"
            )
        return xy

    def _one_to_one(self, xy: FloatArray) -> npt.NDArray[np.bool_]:
        """Where the radial distortion still grows with the radius (and keeps its sign)."""
        c = self._coef
        r2 = (xy * xy).sum(axis=-1)
        if self.model == "fisheye":
            t2 = np.arctan(np.sqrt(r2)) ** 2
            k1, k2, k3, k4 = c[4:8]
            slope = 1 + t2 * (3 * k1 + t2 * (5 * k2 + t2 * (7 * k3 + t2 * 9 * k4)))
            out: npt.NDArray[np.bool_] = slope > 0.0
            return out
        k1, k2, k3, k4, k5, k6 = c[4:10]
        num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        den = 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        dnum = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3)
        dden = k4 + r2 * (2.0 * k5 + r2 * 3.0 * k6)
        radial = num / den
        # d(r R(r^2)) / dr = R + 2 r^2 dR/d(r^2)
        slope = radial + 2.0 * r2 * (dnum * den - num * dden) / (den * den)
        ok: npt.NDArray[np.bool_] = (radial > 0.0) & (slope > 0.0) & (den > 0.0)
        return ok

    def _polish(self, xy: FloatArray, target: FloatArray) -> FloatArray:
        """Newton steps (numeric Jacobian) on the distortion: OpenCV's fixed-point
        iteration converges slowly or not at all under strong distortion."""
        h = 1e-7
        start = (target - (self.cx, self.cy)) / (self.fx, self.fy)
        xy = np.array(np.where(np.isfinite(xy), xy, start), dtype=np.float64)
        for _ in range(30):
            probe = np.stack([xy, xy + np.array([h, 0.0]), xy + np.array([0.0, h])], axis=1)
            f = self._distort(probe)
            r = f[:, 0] - target
            if np.abs(r).max() < 1e-7:
                break
            jac = np.stack([(f[:, 1] - f[:, 0]) / h, (f[:, 2] - f[:, 0]) / h], axis=-1)
            try:
                xy = xy - np.linalg.solve(jac, r[..., None])[..., 0]
            except np.linalg.LinAlgError:
                break
        return xy

    def undistort_image(self, image: npt.NDArray[Any]) -> npt.NDArray[Any]:
        """The image as an ideal camera with the same camera matrix would see it.

        Maps are computed once per intrinsics and cached. ConfigError if the image
        size is not this calibration's.
        """
        arr = np.asarray(image)
        if arr.ndim not in (2, 3) or arr.shape[:2] != (self.height_px, self.width_px):
            raise ConfigError(
                f"image is {arr.shape[1] if arr.ndim >= 2 else '?'}x{arr.shape[0]} but these "
                f"intrinsics are for {self.width_px}x{self.height_px}"
            )
        maps = self._cache.get("undistort_maps")
        if maps is None:
            size = (self.width_px, self.height_px)
            if self.model == "pinhole":
                maps = cv2.initUndistortRectifyMap(
                    self.camera_matrix, self.distortion, np.eye(3), self.camera_matrix, size,
                    cv2.CV_16SC2,
                )
            else:
                maps = cv2.fisheye.initUndistortRectifyMap(
                    self.camera_matrix, self.distortion, np.eye(3), self.camera_matrix, size,
                    cv2.CV_16SC2,
                )
            self._cache["undistort_maps"] = maps
        out: npt.NDArray[Any] = cv2.remap(arr, maps[0], maps[1], cv2.INTER_LINEAR)
        return out


# --------------------------------------------------------------------------- boards


def _check_length(name: str, value: float, lo: float = 0.01, hi: float = 10_000.0) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ConfigError(f"{name} must be a number of mm, got {value!r}")
    if not lo <= value <= hi:
        raise ConfigError(f"{name} = {value!r} mm is out of range {lo:g}..{hi:g} mm")


def _dictionary(name: str) -> cv2.aruco.Dictionary:
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        raise ConfigError(f"dictionary {name!r} is not an OpenCV ArUco dictionary (DICT_...)")
    return cv2.aruco.getPredefinedDictionary(code)


def _dictionary_size(name: str) -> int:
    return int(_dictionary(name).bytesList.shape[0])


@dataclass(frozen=True)
class ChessboardSpec:
    """A chessboard with ``inner_cols`` x ``inner_rows`` inner corners.

    Squares: (inner_cols + 1) x (inner_rows + 1), the top-left one black. Inner corner
    (i, j) is at ((i + 1) s, (j + 1) s, 0) in the board frame (s = ``square_mm``).
    Only for intrinsics: its pose is ambiguous under a half turn.
    """

    inner_cols: int
    inner_rows: int
    square_mm: float

    def __post_init__(self) -> None:
        check_int_range("inner_cols", self.inner_cols, 2, 100)
        check_int_range("inner_rows", self.inner_rows, 2, 100)
        _check_length("square_mm", self.square_mm)

    @property
    def object_points(self) -> FloatArray:
        """(N, 3) inner corners, row by row (the order OpenCV reports them)."""
        j, i = np.mgrid[0 : self.inner_rows, 0 : self.inner_cols]
        s = self.square_mm
        return np.stack([(i.ravel() + 1) * s, (j.ravel() + 1) * s, np.zeros(i.size)], axis=1)

    @property
    def extent_mm(self) -> tuple[float, float]:
        """Width and height of the square grid."""
        return ((self.inner_cols + 1) * self.square_mm, (self.inner_rows + 1) * self.square_mm)

    def describe(self) -> str:
        return (
            f"chessboard {self.inner_cols}x{self.inner_rows} inner corners, "
            f"{self.square_mm:g} mm squares"
        )

    def default_margin_mm(self) -> float:
        return self.square_mm

    def board_image(self, px_per_mm: float, margin_mm: float | None = None) -> UInt8Array:
        """The printable image (see ``board_image_frame``); white margin, black squares."""
        frame = _image_frame(self, px_per_mm, margin_mm)
        s = self.square_mm
        rects = [
            (a * s, b * s, (a + 1) * s, (b + 1) * s)
            for b in range(self.inner_rows + 1) for a in range(self.inner_cols + 1)
            if (a + b) % 2 == 0
        ]
        return _raster(frame, px_per_mm, rects, [])


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board (OpenCV's current layout: the top-left square is black).

    ``squares_x`` x ``squares_y`` squares of ``square_mm``; ArUco markers of
    ``marker_mm`` (centred in the white squares) from ``dictionary``, ids 0, 1, ...
    row by row. Corner id k is at ((k % (squares_x-1) + 1) s, (k // (squares_x-1) + 1) s).
    Keep ``marker_mm`` near 0.6 ``square_mm``: OpenCV refines each corner in a window
    that larger markers reach into, which scatters the corners (0.2 px rms at 0.75).
    """

    squares_x: int
    squares_y: int
    square_mm: float
    marker_mm: float
    dictionary: str = "DICT_5X5_100"

    def __post_init__(self) -> None:
        check_int_range("squares_x", self.squares_x, 3, 100)
        check_int_range("squares_y", self.squares_y, 3, 100)
        _check_length("square_mm", self.square_mm)
        _check_length("marker_mm", self.marker_mm, 0.01, 0.95 * self.square_mm)
        need = self.squares_x * self.squares_y // 2
        have = _dictionary_size(self.dictionary)
        if need > have:
            raise ConfigError(
                f"a {self.squares_x}x{self.squares_y} ChArUco board needs {need} markers; "
                f"{self.dictionary} has {have}"
            )

    @property
    def object_points(self) -> FloatArray:
        """(N, 3) chessboard corners by id."""
        return np.asarray(_charuco_board(self).getChessboardCorners(), np.float64).reshape(-1, 3)

    @property
    def extent_mm(self) -> tuple[float, float]:
        return (self.squares_x * self.square_mm, self.squares_y * self.square_mm)

    def describe(self) -> str:
        return (
            f"charuco {self.squares_x}x{self.squares_y} squares, {self.square_mm:g} mm squares, "
            f"{self.marker_mm:g} mm markers, {self.dictionary}"
        )

    def default_margin_mm(self) -> float:
        return self.square_mm / 2.0

    def board_image(self, px_per_mm: float, margin_mm: float | None = None) -> UInt8Array:
        """The printable image (see ``board_image_frame``)."""
        frame = _image_frame(self, px_per_mm, margin_mm)
        board = _cv_board(self)
        markers = _marker_quads(board, self.dictionary)
        s = self.square_mm
        with_marker = {(int(m[0] // s), int(m[1] // s)) for m, _, _ in markers}
        rects = [
            (a * s, b * s, (a + 1) * s, (b + 1) * s)
            for b in range(self.squares_y) for a in range(self.squares_x)
            if (a, b) not in with_marker
        ]
        return _raster(frame, px_per_mm, rects, markers)


@dataclass(frozen=True)
class TagBoardSpec:
    """A grid of AprilTag 36h11 markers (OpenCV's ``aruco.GridBoard``), for hand-eye.

    ``cols`` x ``rows`` tags of ``tag_mm`` (the black border's outer edge) with
    ``gap_mm`` of white between them; ids ``first_id`` + k, row by row. Tag k's corners
    (top-left, top-right, bottom-right, bottom-left as printed) start at
    ((k % cols) p, (k // cols) p) with p = tag_mm + gap_mm.
    """

    cols: int
    rows: int
    tag_mm: float
    gap_mm: float
    first_id: int = 0

    def __post_init__(self) -> None:
        check_int_range("cols", self.cols, 1, 50)
        check_int_range("rows", self.rows, 1, 50)
        _check_length("tag_mm", self.tag_mm)
        # The detector needs a white quiet zone of at least one tag cell (1/8 of the tag).
        _check_length("gap_mm", self.gap_mm, self.tag_mm / 8.0, 10_000.0)
        size = _dictionary_size(TAG_DICTIONARY)
        check_int_range("first_id", self.first_id, 0, size - self.cols * self.rows)

    @property
    def object_points(self) -> FloatArray:
        """(4 N, 3): the corners of every tag, in id order."""
        return np.concatenate(
            [np.asarray(q, np.float64) for q in _cv_board(self).getObjPoints()]
        ).reshape(-1, 3)

    @property
    def extent_mm(self) -> tuple[float, float]:
        p = self.tag_mm + self.gap_mm
        return (self.cols * p - self.gap_mm, self.rows * p - self.gap_mm)

    def describe(self) -> str:
        return (
            f"tag board {self.cols}x{self.rows} AprilTag 36h11, {self.tag_mm:g} mm tags, "
            f"{self.gap_mm:g} mm gaps, ids {self.first_id}.."
            f"{self.first_id + self.cols * self.rows - 1}"
        )

    def default_margin_mm(self) -> float:
        return max(self.gap_mm, self.tag_mm / 4.0)

    def board_image(self, px_per_mm: float, margin_mm: float | None = None) -> UInt8Array:
        """The printable image (see ``board_image_frame``)."""
        frame = _image_frame(self, px_per_mm, margin_mm)
        return _raster(frame, px_per_mm, [], _marker_quads(_cv_board(self), TAG_DICTIONARY))


BoardSpec = Union[ChessboardSpec, CharucoSpec, TagBoardSpec]  # noqa: UP007 (runtime alias, 3.10)


def board_image_frame(
    spec: BoardSpec, px_per_mm: float, margin_mm: float | None = None
) -> tuple[float, float, int, int]:
    """(x_min_mm, y_min_mm, width_px, height_px) of ``spec.board_image(px_per_mm, margin_mm)``.

    The image's rows run along the board's +y, its columns along +x. The *outer corner*
    of pixel (0, 0) (its top-left corner, not its centre) is the board point
    (x_min, y_min, 0) = (-margin, -margin, 0); pixel (u, v) covers board x in
    [x_min + u / px_per_mm, x_min + (u + 1) / px_per_mm) and y likewise, and is black
    when its centre falls on a black cell. So the image is exact when the cells are a
    whole number of pixels, and within half a pixel otherwise. Width and height are the
    pattern plus a margin on every side, rounded up to whole pixels.
    """
    return _image_frame(spec, px_per_mm, margin_mm)


def _image_frame(
    spec: BoardSpec, px_per_mm: float, margin_mm: float | None
) -> tuple[float, float, int, int]:
    if isinstance(px_per_mm, bool) or not isinstance(px_per_mm, int | float):
        raise ConfigError(f"px_per_mm must be a number, got {px_per_mm!r}")
    if not 0.01 <= px_per_mm <= 1000.0:
        raise ConfigError(f"px_per_mm = {px_per_mm!r} is out of range 0.01..1000")
    margin = spec.default_margin_mm() if margin_mm is None else margin_mm
    _check_length("margin_mm", margin, 0.0, 10_000.0)
    w, h = spec.extent_mm
    width = math.ceil((w + 2 * margin) * px_per_mm - 1e-9)
    height = math.ceil((h + 2 * margin) * px_per_mm - 1e-9)
    if width * height > 200_000_000:
        raise ConfigError(f"board image {width}x{height} px is too large; lower px_per_mm")
    return (-float(margin), -float(margin), width, height)


_Quad = tuple[tuple[float, float], float, UInt8Array]
"""A marker: top-left corner (x, y) mm, side mm, cell image (1 px per cell)."""


def _marker_quads(board: cv2.aruco.Board, dictionary: str) -> list[_Quad]:
    d = _dictionary(dictionary)
    cells = int(d.markerSize) + 2
    out: list[_Quad] = []
    ids = np.asarray(board.getIds()).ravel()
    for corners, marker_id in zip(board.getObjPoints(), ids, strict=True):
        q = np.asarray(corners, np.float64).reshape(4, 3)
        side = float(q[1, 0] - q[0, 0])
        # OpenCV's planar boards: corner 0 top-left, 1 to its +x, 3 to its +y.
        assert q[3, 1] - q[0, 1] == side and q[1, 1] == q[0, 1], "unexpected marker layout"
        bits = cv2.aruco.generateImageMarker(d, int(marker_id), cells, borderBits=1)
        out.append(((float(q[0, 0]), float(q[0, 1])), side, np.asarray(bits, np.uint8)))
    return out


def _raster(
    frame: tuple[float, float, int, int], px_per_mm: float,
    rects: list[tuple[float, float, float, float]], markers: list[_Quad],
) -> UInt8Array:
    """Point-sample black rectangles and markers at pixel centres (see board_image_frame)."""
    x_min, y_min, width, height = frame
    xs = x_min + (np.arange(width) + 0.5) / px_per_mm
    ys = y_min + (np.arange(height) + 0.5) / px_per_mm
    img = np.full((height, width), 255, np.uint8)
    for x0, y0, x1, y1 in rects:
        cols = np.flatnonzero((xs >= x0) & (xs < x1))
        rows = np.flatnonzero((ys >= y0) & (ys < y1))
        img[np.ix_(rows, cols)] = 0
    for (x0, y0), side, bits in markers:
        n = bits.shape[0]
        i = np.floor((xs - x0) / side * n).astype(np.int64)
        j = np.floor((ys - y0) / side * n).astype(np.int64)
        cols = np.flatnonzero((i >= 0) & (i < n))
        rows = np.flatnonzero((j >= 0) & (j < n))
        img[np.ix_(rows, cols)] = bits[np.ix_(j[rows], i[cols])]
    return img


@functools.lru_cache(maxsize=64)
def _cv_board(spec: CharucoSpec | TagBoardSpec) -> cv2.aruco.Board:
    if isinstance(spec, CharucoSpec):
        return _charuco_board(spec)
    ids = np.arange(spec.first_id, spec.first_id + spec.cols * spec.rows, dtype=np.int32)
    grid: cv2.aruco.Board = cv2.aruco.GridBoard(
        (spec.cols, spec.rows), float(spec.tag_mm), float(spec.gap_mm),
        _dictionary(TAG_DICTIONARY), ids,
    )
    return grid


@functools.lru_cache(maxsize=64)
def _charuco_board(spec: CharucoSpec) -> cv2.aruco.CharucoBoard:
    return cv2.aruco.CharucoBoard(
        (spec.squares_x, spec.squares_y), float(spec.square_mm), float(spec.marker_mm),
        _dictionary(spec.dictionary),
    )


@functools.lru_cache(maxsize=16)
def _charuco_detector(spec: CharucoSpec) -> cv2.aruco.CharucoDetector:
    return cv2.aruco.CharucoDetector(_charuco_board(spec))


@functools.lru_cache(maxsize=4)
def _tag_detector() -> cv2.aruco.ArucoDetector:
    params = cv2.aruco.DetectorParameters()
    # AprilTag refinement: the corners come from lines fitted to the whole border edges.
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    return cv2.aruco.ArucoDetector(_dictionary(TAG_DICTIONARY), params)


def render_board_view(
    spec: BoardSpec,
    intrinsics: CameraIntrinsics,
    board2cam: npt.ArrayLike,
    *,
    px_per_mm: float = 4.0,
    supersample: int = 2,
    background: int = 96,
) -> UInt8Array:
    """A synthetic grayscale camera image of the board at ``board2cam`` (mm).

    For tests and dry runs of the calibration flows: the board image (``board_image``
    at ``px_per_mm``; choose it so the cells are whole pixels, then every edge is exact)
    is sampled through the full camera model, distortion included, at ``supersample``
    x ``supersample`` rays per pixel, averaged (antialiasing). Rays that miss the board's
    printed area see ``background``. The pixels' rays are cached on ``intrinsics``
    (about 20 MB at 640x480, supersample 2).
    """
    t = as_transform("board2cam", board2cam)
    check_int_range("supersample", supersample, 1, 8)
    check_int_range("background", background, 0, 255)
    texture = spec.board_image(px_per_mm)
    x_min, y_min, _, _ = _image_frame(spec, px_per_mm, None)
    key = f"rays{supersample}"
    rays = intrinsics._cache.get(key)
    if rays is None:
        s = supersample
        v, u = np.mgrid[0 : intrinsics.height_px * s, 0 : intrinsics.width_px * s]
        px = np.stack([(u.ravel() + 0.5) / s - 0.5, (v.ravel() + 0.5) / s - 0.5], axis=1)
        rays = intrinsics.normalized_from_pixels(px)
        intrinsics._cache[key] = rays
    r, origin = t[:3, :3], t[:3, 3]
    normal = r[:, 2]
    denom = rays @ normal[:2] + normal[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        depth = float(normal @ origin) / denom
    hit = np.isfinite(depth) & (depth > 0.0)
    depth = np.where(hit, depth, 0.0)
    p = np.concatenate([rays * depth[:, None], depth[:, None]], axis=1) - origin
    board_xy = p @ r[:, :2]  # R^T (p - t), x and y
    map_x = np.where(hit, (board_xy[:, 0] - x_min) * px_per_mm - 0.5, -1e6)
    map_y = np.where(hit, (board_xy[:, 1] - y_min) * px_per_mm - 0.5, -1e6)
    shape = (intrinsics.height_px * supersample, intrinsics.width_px * supersample)
    big = cv2.remap(
        texture, map_x.reshape(shape).astype(np.float32), map_y.reshape(shape).astype(np.float32),
        cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=background,
    )
    if supersample == 1:
        return np.asarray(big, np.uint8)
    out = cv2.resize(big, (intrinsics.width_px, intrinsics.height_px), interpolation=cv2.INTER_AREA)
    return np.asarray(out, np.uint8)


# --------------------------------------------------------------------------- detection


@dataclass(frozen=True, eq=False)
class BoardObservation:
    """Board points found in one image: object points (board frame, mm) and pixels.

    ``ids``: per point, the chessboard corner index, the ChArUco corner id, or
    4 x (tag id - first_id) + corner for a tag board.
    """

    spec: BoardSpec
    object_points_mm: FloatArray
    image_points_px: FloatArray
    ids: IntArray
    image_size: tuple[int, int]

    def __post_init__(self) -> None:
        obj = _points("object_points_mm", self.object_points_mm, 3)
        img = _points("image_points_px", self.image_points_px, 2)
        ids = np.asarray(self.ids, np.int64).ravel()
        if not obj.shape[0] == img.shape[0] == ids.shape[0]:
            raise ConfigError(
                f"a board observation needs as many object points ({obj.shape[0]}) as image "
                f"points ({img.shape[0]}) and ids ({ids.shape[0]})"
            )
        object.__setattr__(self, "object_points_mm", _readonly(obj))
        object.__setattr__(self, "image_points_px", _readonly(img))
        object.__setattr__(self, "ids", ids)

    @property
    def count(self) -> int:
        return int(self.object_points_mm.shape[0])


def _gray(image: npt.NDArray[Any]) -> npt.NDArray[np.uint8]:
    arr = np.asarray(image)
    if arr.dtype != np.uint8:
        raise ConfigError(f"image must be 8-bit (uint8), got {arr.dtype}")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    if arr.ndim == 2:
        return np.ascontiguousarray(arr)
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if arr.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        return np.asarray(cv2.cvtColor(arr, code), np.uint8)
    raise ConfigError(f"image must be grayscale (H, W) or BGR (H, W, 3), got shape {arr.shape}")


def default_min_points(spec: BoardSpec) -> int:
    """Fewest points a view of ``spec`` must show: the whole chessboard, 6 ChArUco
    corners, or 2 tags."""
    if isinstance(spec, ChessboardSpec):
        return spec.inner_cols * spec.inner_rows
    return 6 if isinstance(spec, CharucoSpec) else 8


def find_board(
    image: npt.NDArray[Any], spec: BoardSpec, *, min_points: int | None = None
) -> BoardObservation | None:
    """The board's points in ``image`` (grayscale or BGR, uint8), or None if not seen.

    Chessboard: ``findChessboardCorners`` + ``cornerSubPix``, falling back to
    ``findChessboardCornersSB``; the whole board must be visible (and its corners may
    come from either end: fine for intrinsics only). ChArUco: ``CharucoDetector``, its
    corners corrected for OpenCV 4.12's half-pixel offset (measured, so a fixed OpenCV
    needs no change). Tag board: ``ArucoDetector`` with AprilTag refinement, then each
    tag's corners re-fitted from its four edges (``_refine_tag_corners``); all four
    corners of every board tag at least 24 px wide. Partial views of these two count
    when they show ``min_points`` points (default ``default_min_points``) not all on
    one line. Corner accuracy on synthetic views: 0.04..0.06 px rms.
    """
    gray = _gray(image)
    size = (int(gray.shape[1]), int(gray.shape[0]))
    need = default_min_points(spec) if min_points is None else check_int_range(
        "min_points", min_points, 4, 100_000
    )
    if isinstance(spec, ChessboardSpec):
        found = _find_chessboard(gray, spec)
        if found is None:
            return None
        img_pts, ids = found
        obj = spec.object_points
    elif isinstance(spec, CharucoSpec):
        corners, corner_ids, _, _ = _charuco_detector(spec).detectBoard(gray)
        if corner_ids is None or len(corner_ids) == 0:
            return None
        ids = np.asarray(corner_ids, np.int64).ravel()
        img_pts = np.asarray(corners, np.float64).reshape(-1, 2) - _charuco_offset_px()
        obj = spec.object_points[ids]
    elif isinstance(spec, TagBoardSpec):
        corners_list, tag_ids, _ = _tag_detector().detectMarkers(gray)
        found_ids = np.asarray(tag_ids if tag_ids is not None else [], np.int64).ravel()
        n_tags = spec.cols * spec.rows
        all_obj = spec.object_points.reshape(n_tags, 4, 3)
        pts, objs, idl = [], [], []
        uniq, counts = np.unique(found_ids, return_counts=True)
        twice = set(uniq[counts > 1].tolist())
        quads = np.asarray(corners_list, np.float64).reshape(-1, 4, 2)
        refined, good = _refine_tag_corners(gray, quads)
        for c, t, ok in zip(refined, found_ids, good, strict=True):
            k = int(t) - spec.first_id
            if not 0 <= k < n_tags or int(t) in twice or not ok:
                continue  # another board's tag, one seen twice, or too small to be accurate
            pts.append(c)
            objs.append(all_obj[k])
            idl.append(4 * k + np.arange(4))
        if not pts:
            return None
        img_pts, obj, ids = np.concatenate(pts), np.concatenate(objs), np.concatenate(idl)
    else:  # a caller without type checking
        raise ConfigError(f"unknown board spec {spec!r}")
    if img_pts.shape[0] < need or _collinear(obj):
        return None
    return BoardObservation(spec, obj, img_pts, ids, size)


TAG_MIN_CELL_PX = 3.0
"""Tags whose cells (1/8 of the tag) are smaller than this in the image are not used:
their edges are too short and blurred to locate the corners to a tenth of a pixel."""


def _refine_tag_corners(
    gray: npt.NDArray[np.uint8], quads: FloatArray, iterations: int = 3
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Corners of detected tags from lines fitted to their four outer edges.

    OpenCV's AprilTag refinement reports corners about half a pixel off (the AprilTag
    library puts pixel centres at +0.5) and scatters them by about 0.13 px; here each
    edge is located at 10 stations by the centroid of the intensity gradient across it
    (inside the black border, outside the white quiet zone, never into the data bits),
    a line is fitted through them and neighbouring lines intersect at the corners
    (about 0.05 px rms on synthetic views). Three passes re-centre the profiles.
    Returns the corners (M, 4, 2) and which tags were refined (large enough, with
    enough contrast on every edge).
    """
    m_tags = quads.shape[0]
    if m_tags == 0:
        return quads, np.zeros(0, bool)
    img = gray.astype(np.float32)
    q = quads.astype(np.float64)
    stations = np.linspace(0.12, 0.88, 10)  # away from the corners, where edges meet
    unit = np.linspace(-1.0, 1.0, 17)
    ok = np.ones(m_tags, bool)
    for _ in range(iterations):
        d = np.roll(q, -1, axis=1) - q  # edge k runs from corner k to corner k + 1
        length = np.linalg.norm(d, axis=-1)
        ok &= length.min(axis=1) >= 8.0 * TAG_MIN_CELL_PX
        e = d / np.maximum(length, 1e-9)[..., None]
        normal = np.stack([e[..., 1], -e[..., 0]], axis=-1)  # outward: corners run clockwise
        # Profiles reach 0.6 cell inward (inside the one-cell black border), at most 4 px.
        half = np.clip(0.6 * length.min(axis=1) / 8.0, 1.5, 4.0)
        s = unit[None, :] * half[:, None]  # (M, P)
        base = q[:, :, None, :] + stations[None, None, :, None] * d[:, :, None, :]
        pts = base[:, :, :, None, :] + s[:, None, None, :, None] * normal[:, :, None, None, :]
        flat = pts.reshape(-1, unit.size, 2).astype(np.float32)
        vals = cv2.remap(
            img, flat[..., 0], flat[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        ).reshape(pts.shape[:-1])
        grad = np.clip(np.diff(vals, axis=-1), 0.0, None)  # dark (inside) to bright (outside)
        mid = 0.5 * (s[:, 1:] + s[:, :-1])
        total = grad.sum(axis=-1)
        offset = (grad * mid[:, None, None, :]).sum(axis=-1) / np.maximum(total, 1e-9)
        weight = (total > 20.0).astype(np.float64)  # a real edge rises by 20+ grey levels
        count = weight.sum(axis=-1)
        ok &= (count >= 4).all(axis=1)
        edge_pts = base + offset[..., None] * normal[:, :, None, :]
        centre = (edge_pts * weight[..., None]).sum(axis=2) / np.maximum(count, 1.0)[..., None]
        c = edge_pts - centre[:, :, None, :]
        cov = np.einsum("mksi,mksj,mks->mkij", c, c, weight)
        direction = np.linalg.eigh(cov)[1][..., :, 1]  # the principal axis of each edge
        # Corner k is where edge k - 1 meets edge k.
        c_prev, d_prev = np.roll(centre, 1, axis=1), np.roll(direction, 1, axis=1)
        det = d_prev[..., 0] * direction[..., 1] - d_prev[..., 1] * direction[..., 0]
        ok &= (np.abs(det) > 0.05).all(axis=1)
        diff = centre - c_prev
        lam = (diff[..., 0] * direction[..., 1] - diff[..., 1] * direction[..., 0]) / np.where(
            np.abs(det) > 1e-9, det, 1.0
        )
        new_q = c_prev + lam[..., None] * d_prev
        # A tag whose fit failed keeps its previous corners (and is reported not ok).
        q = np.where(ok[:, None, None] & np.isfinite(new_q), new_q, q)
    ok &= np.abs(q - quads).max(axis=(1, 2)) < 3.0  # refinement must not wander off
    return q, ok


@functools.lru_cache(maxsize=1)
def _charuco_offset_px() -> FloatArray:
    """The constant OpenCV adds to ChArUco corners, measured once on a synthetic board.

    OpenCV 4.12's CharucoDetector returns corners 0.5 px too far right and down
    (opencv/opencv#25539, fixed in later releases); measuring it on an image with known
    corners keeps the correction right with any OpenCV version. Rounded to 0.5 px.
    """
    spec = CharucoSpec(5, 4, 20.0, 15.0)
    ppm = 2.0
    img = cv2.GaussianBlur(spec.board_image(ppm), (0, 0), 1.0)
    corners, ids, _, _ = _charuco_detector(spec).detectBoard(img)
    if ids is None or len(ids) < 6:  # cannot measure: assume the documented convention
        return np.zeros(2)
    x_min, y_min, _, _ = _image_frame(spec, ppm, None)
    truth = (spec.object_points[np.asarray(ids).ravel(), :2] - (x_min, y_min)) * ppm - 0.5
    mean = (np.asarray(corners, np.float64).reshape(-1, 2) - truth).mean(axis=0)
    out: FloatArray = np.round(mean * 2.0) / 2.0
    return out


def _find_chessboard(
    gray: npt.NDArray[np.uint8], spec: ChessboardSpec
) -> tuple[FloatArray, IntArray] | None:
    """Classic detection + ``cornerSubPix`` first: 50x faster than the sector-based
    detector here and more accurate (0.04 px rms vs 0.1 on synthetic views); the
    sector-based detector is the fallback for images the classic one misses."""
    pattern = (spec.inner_cols, spec.inner_rows)
    n = spec.inner_cols * spec.inner_rows
    ok, corners = cv2.findChessboardCorners(
        gray, pattern, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if ok and corners is not None:
        # The window: a third of the smallest corner spacing, 2..11 px.
        c = np.asarray(corners, np.float32).reshape(-1, 2)
        steps = np.diff(c.reshape(pattern[1], pattern[0], 2), axis=1)
        spacing = float(np.min(np.linalg.norm(steps, axis=-1)))
        win = max(2, min(11, int(spacing / 3)))
        corners = cv2.cornerSubPix(
            gray, corners, (win, win), (-1, -1),
            (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3),
        )
    else:
        ok, corners = cv2.findChessboardCornersSB(gray, pattern, flags=cv2.CALIB_CB_ACCURACY)
        if not ok or corners is None:
            return None
    pts = np.asarray(corners, np.float64).reshape(-1, 2)
    if pts.shape[0] != n:
        return None
    return pts, np.arange(n, dtype=np.int64)


def _collinear(obj: FloatArray) -> bool:
    if obj.shape[0] < 3:
        return True
    s = np.linalg.svd(obj[:, :2] - obj[:, :2].mean(axis=0), compute_uv=False)
    return bool(s[1] <= 1e-6 * s[0])


# --------------------------------------------------------------------------- intrinsics


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


def _found_views(
    observations: Sequence[BoardObservation | None], need: int, what: str
) -> list[int]:
    found = [i for i, o in enumerate(observations) if o is not None]
    if len(found) < need:
        raise VisionError(
            f"board found in {len(found)} of {len(observations)} {what}; need at least {need}"
        )
    return found


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
    boards = sorted({o.spec.describe() for o in found.values()})
    dropped: list[int] = []
    calibrate = _calibrate_pinhole if model == "pinhole" else _calibrate_fisheye
    flags = (cv2.CALIB_FIX_K3 if fix_k3 else 0) | (cv2.CALIB_RATIONAL_MODEL if rational else 0)
    while True:
        if len(used) < min_views:
            raise VisionError(
                f"{len(used)} usable views of {len(observations)} after dropping "
                f"{sorted(dropped)}; need at least {min_views}"
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


# --------------------------------------------------------------------------- board pose


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


# --------------------------------------------------------------------------- hand-eye


@dataclass(frozen=True, eq=False)
class HandEyeResult:
    """An eye-in-hand calibration.

    ``cam2link``: the camera on the ``link``; ``board2base``: the fixed board. ``rms_px``
    and ``per_view_rms_px``: reprojection error with the link poses *as given* over the
    views used (indices into the lists given). ``pose_rms_deg`` / ``pose_rms_mm``: the
    rms correction the fit gave each view's link pose (what the joint readings were
    off by, seen through the camera). ``translation_std_mm`` / ``rotation_std_deg``:
    1-sigma uncertainty of cam2link under the noise model. ``method``: the OpenCV
    hand-eye method that gave the start.
    """

    cam2link: FloatArray
    board2base: FloatArray
    rms_px: float
    per_view_rms_px: tuple[float, ...]
    views_used: tuple[int, ...]
    intrinsics: CameraIntrinsics
    link: str = "wrist_pitch"
    method: str = ""
    translation_std_mm: float = 0.0
    rotation_std_deg: float = 0.0
    pose_rms_deg: float = 0.0
    pose_rms_mm: float = 0.0
    created: str = ""


_HAND_EYE_METHODS = (
    ("tsai", cv2.CALIB_HAND_EYE_TSAI),
    ("park", cv2.CALIB_HAND_EYE_PARK),
    ("horaud", cv2.CALIB_HAND_EYE_HORAUD),
    ("andreff", cv2.CALIB_HAND_EYE_ANDREFF),
    ("daniilidis", cv2.CALIB_HAND_EYE_DANIILIDIS),
)
_LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


def _check_motion(rotations: FloatArray) -> None:
    """VisionError unless the link rotates about at least two different axes."""
    n = rotations.shape[0]
    i, j = np.triu_indices(n, 1)
    rel = np.einsum("nji,njk->nik", rotations[i], rotations[j])  # R_i^T R_j, in link frame i
    rv = Rotation.from_matrix(rel).as_rotvec()
    angle = np.linalg.norm(rv, axis=1)
    big = angle >= math.radians(_MIN_MOTION_DEG)
    if not np.any(big):
        raise VisionError(
            f"degenerate motion: the camera link turns at most {math.degrees(angle.max()):.1f} "
            f"deg between views; need rotations of at least {_MIN_MOTION_DEG:g} deg about two "
            f"different axes (turn the base and tilt the wrist)"
        )
    axes = rv[big] / angle[big, None]
    if axes.shape[0] > 200:
        axes = axes[np.linspace(0, axes.shape[0] - 1, 200).astype(int)]
    spread = np.linalg.norm(np.cross(axes[:, None, :], axes[None, :, :]), axis=-1).max()
    if spread < math.sin(math.radians(_MIN_AXIS_SPREAD_DEG)):
        a = axes[0] * np.sign(axes[0][np.argmax(np.abs(axes[0]))])
        raise VisionError(
            f"degenerate motion: every rotation between views is about one axis "
            f"({a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f} in the link frame, within "
            f"{math.degrees(math.asin(min(1.0, spread))):.1f} deg); rotate about a second axis "
            f"as well (turn the base and tilt the wrist)"
        )


def calibrate_hand_eye(
    link2base: Sequence[npt.ArrayLike],
    observations: Sequence[BoardObservation | None],
    intrinsics: CameraIntrinsics,
    *,
    link: str = "wrist_pitch",
    min_views: int = MIN_HAND_EYE_VIEWS,
    pixel_noise_px: float = 0.2,
    pose_noise_deg: float = 0.15,
    pose_noise_mm: float = 0.5,
    loss: str = "soft_l1",
    reject_outliers: bool = True,
) -> HandEyeResult:
    """Eye-in-hand calibration: the camera's pose on the link, from a fixed board.

    ``link2base[i]``: forward kinematics of the measured joints at view i (DH frame 4
    for the wrist-pitch link); ``observations[i]``: the board in that view's image
    (None: not found, skipped).

    1. A start from ``cv2.calibrateHandEye`` (every method; the best by reprojection).
    2. cam2link and board2base refined by least squares on the reprojection error of
       every board point in every view.
    3. Measured joints are off by a fraction of a degree (a servo reads in 0.24 deg
       steps), which moves each view's link pose. Step 2 alone would bend cam2link to
       explain those errors as pixels (several mm with 0.1 deg joint noise), so each
       view also gets a small pose correction, held to ``pose_noise_deg`` /
       ``pose_noise_mm`` (1 sigma) by a prior, with pixels at ``pixel_noise_px``
       (a maximum a posteriori fit; about 3x smaller errors). ``pose_noise_deg = 0``
       and ``pose_noise_mm = 0`` skip it (exact link poses: pixel noise only).

    ``loss`` (scipy's) makes the fits robust to stray points, at 3 sigma. With
    ``reject_outliers`` a view whose rms is above 3x the median and 1 px, or whose pose
    correction is beyond 4 sigma, is dropped once and the fit redone. VisionError for
    fewer than ``min_views`` views or rotations about a single axis.
    """
    if len(link2base) != len(observations):
        raise ConfigError(
            f"link2base has {len(link2base)} poses but observations has {len(observations)}"
        )
    check_int_range("min_views", min_views, MIN_HAND_EYE_VIEWS, 10_000)
    if loss not in _LOSSES:
        raise ConfigError(f"loss {loss!r} is not one of {', '.join(_LOSSES)}")
    for name, value, hi in (
        ("pixel_noise_px", pixel_noise_px, 10.0), ("pose_noise_deg", pose_noise_deg, 10.0),
        ("pose_noise_mm", pose_noise_mm, 50.0),
    ):
        if isinstance(value, bool) or not isinstance(value, int | float) or not 0 <= value <= hi:
            raise ConfigError(f"{name} = {value!r} is out of range 0..{hi:g}")
    if pixel_noise_px < 0.01:
        raise ConfigError(f"pixel_noise_px = {pixel_noise_px!r} is out of range 0.01..10")
    if (pose_noise_deg > 0) != (pose_noise_mm > 0):
        raise ConfigError(
            f"pose_noise_deg ({pose_noise_deg!r}) and pose_noise_mm ({pose_noise_mm!r}) must "
            f"both be > 0 (uncertain link poses) or both 0 (exact ones)"
        )
    used = _found_views(observations, min_views, "views")
    links = {i: as_transform(f"link2base[{i}]", link2base[i]) for i in used}
    obs: dict[int, BoardObservation] = {}
    for i in used:
        o = observations[i]
        assert o is not None
        if isinstance(o.spec, ChessboardSpec):
            raise ConfigError(
                "a chessboard cannot calibrate hand-eye: its pose is ambiguous under a half "
                "turn; use a TagBoardSpec or CharucoSpec board"
            )
        obs[i] = o
    _check_motion(np.stack([links[i][:3, :3] for i in used]))
    board2cam = {i: board_pose(obs[i], intrinsics)[0] for i in used}

    best: tuple[float, str, FloatArray, FloatArray] | None = None
    start = _HandEyeProblem(links, obs, used, intrinsics)
    for name, method in _HAND_EYE_METHODS:
        try:
            r_cv, t_cv = cv2.calibrateHandEye(
                [links[i][:3, :3] for i in used], [links[i][:3, 3] for i in used],
                [board2cam[i][:3, :3] for i in used], [board2cam[i][:3, 3] for i in used],
                method=method,
            )
        except cv2.error:
            continue
        r = np.asarray(r_cv, np.float64)
        t = np.asarray(t_cv, np.float64).ravel()
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))):
            continue
        if np.abs(r @ r.T - np.eye(3)).max() > 1e-3:
            continue
        c2l = _transform(_mean_rotation(r[None]), t)
        b2b = _board2base(c2l, links, board2cam, used)
        rms = _rms(start.residual(c2l, b2b))
        if best is None or rms < best[0]:
            best = (rms, name, c2l, b2b)
    if best is None:
        raise VisionError("no hand-eye method gave a solution (check the poses and images)")
    _, method_name, c2l, b2b = best

    noise = (pixel_noise_px, math.radians(pose_noise_deg), pose_noise_mm)
    while True:
        problem = _HandEyeProblem(links, obs, used, intrinsics)
        fit = problem.solve(c2l, b2b, noise, loss)
        c2l, b2b = fit.cam2link, fit.board2base
        if reject_outliers:
            per_view = fit.per_view_rms
            limit = max(OUTLIER_VIEW_PX, 3.0 * float(np.median(per_view)))
            bad = [
                k for k, (e, m) in enumerate(zip(per_view, fit.pose_sigmas, strict=True))
                if e > limit or m > 4.0
            ]
            if bad and len(used) - len(bad) >= min_views:
                used = [u for k, u in enumerate(used) if k not in bad]
                reject_outliers = False
                continue
        break
    total = sum(obs[i].count for i in used)
    sq = sum(e * e * obs[i].count for i, e in zip(used, fit.per_view_rms, strict=True))
    return HandEyeResult(
        c2l, b2b, math.sqrt(sq / total), tuple(fit.per_view_rms), tuple(used), intrinsics, link,
        method_name, fit.translation_std_mm, fit.rotation_std_deg, fit.pose_rms_deg,
        fit.pose_rms_mm, _now(),
    )


def _board2base(
    c2l: FloatArray, links: dict[int, FloatArray], board2cam: dict[int, FloatArray],
    used: list[int],
) -> FloatArray:
    poses = np.stack([links[i] @ c2l @ board2cam[i] for i in used])
    return _transform(_mean_rotation(poses[:, :3, :3]), poses[:, :3, 3].mean(axis=0))


@dataclass
class _HandEyeFit:
    cam2link: FloatArray
    board2base: FloatArray
    per_view_rms: list[float]
    pose_sigmas: list[float]
    translation_std_mm: float
    rotation_std_deg: float
    pose_rms_deg: float
    pose_rms_mm: float


class _HandEyeProblem:
    """Every board point of every view, and the fits of cam2link and board2base."""

    def __init__(
        self, links: dict[int, FloatArray], obs: dict[int, BoardObservation], used: list[int],
        intr: CameraIntrinsics,
    ) -> None:
        self.intr = intr
        self.views = len(used)
        self.obj = np.concatenate([obs[i].object_points_mm for i in used])
        self.img = np.concatenate([obs[i].image_points_px for i in used])
        self.counts = [obs[i].count for i in used]
        self.view = np.repeat(np.arange(self.views), self.counts)
        self.link_r = np.stack([links[i][:3, :3] for i in used])
        self.link_t = np.stack([links[i][:3, 3] for i in used])

    def residual(
        self, c2l: FloatArray, b2b: FloatArray, link_r: FloatArray | None = None,
        link_t: FloatArray | None = None,
    ) -> FloatArray:
        """(N, 2) reprojection errors, px (with corrected link poses if given)."""
        rot = self.link_r if link_r is None else link_r
        org = self.link_t if link_t is None else link_t
        p_base = self.obj @ b2b[:3, :3].T + b2b[:3, 3]
        # base -> link: R^T (p - t), per point with its view's link pose.
        p_link = np.einsum("nji,nj->ni", rot[self.view], p_base - org[self.view])
        p_cam = (p_link - c2l[:3, 3]) @ c2l[:3, :3]  # link -> camera: R^T (p - t)
        p_cam[:, 2] = np.maximum(p_cam[:, 2], 1e-6)  # behind the camera: a large error
        out: FloatArray = self.intr._project(p_cam) - self.img
        return out

    def per_view_rms(self, err: FloatArray) -> list[float]:
        return [_rms(e) for e in np.split(err, np.cumsum(self.counts)[:-1])]

    def solve(
        self, c2l0: FloatArray, b2b0: FloatArray, noise: tuple[float, float, float], loss: str
    ) -> _HandEyeFit:
        sigma_px, sigma_rad, sigma_mm = noise
        views = self.views
        with_poses = sigma_rad > 0.0
        n_global = 12
        n_params = n_global + (6 * views if with_poses else 0)

        def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
            c2l = _transform(_rotvec_matrix(x[0:3]) @ c2l0[:3, :3], c2l0[:3, 3] + x[3:6])
            b2b = _transform(_rotvec_matrix(x[6:9]) @ b2b0[:3, :3], b2b0[:3, 3] + x[9:12])
            if not with_poses:
                return c2l, b2b, self.link_r, self.link_t
            xi = x[n_global:].reshape(views, 6)
            # A view's corrected link pose: link2base @ [exp(w), v], w and v in the link frame.
            rot = self.link_r @ Rotation.from_rotvec(xi[:, :3]).as_matrix()
            org = self.link_t + np.einsum("nij,nj->ni", self.link_r, xi[:, 3:])
            return c2l, b2b, rot, org

        def fun(x: FloatArray) -> FloatArray:
            err = self.residual(*unpack(x)).ravel() / sigma_px
            if not with_poses:
                return err
            xi = x[n_global:].reshape(views, 6)
            priors = [(xi[:, :3] / sigma_rad).ravel(), (xi[:, 3:] / sigma_mm).ravel()]
            return np.concatenate([err, *priors])

        n_pix = 2 * self.img.shape[0]
        rows_of_view = [
            np.flatnonzero(np.repeat(self.view == k, 2)) for k in range(views)
        ]

        def jac(x: FloatArray) -> FloatArray:
            # Forward differences grouped by structure: a view's correction moves only that
            # view's residuals, so one probe per correction component serves every view.
            f0 = fun(x)
            out = np.zeros((f0.size, n_params))
            h = 1e-6
            for j in range(n_global):
                xp = x.copy()
                xp[j] += h
                out[:, j] = (fun(xp) - f0) / h
            if with_poses:
                for c in range(6):
                    xp = x.copy()
                    xp[n_global + c :: 6] += h
                    diff = (fun(xp) - f0) / h
                    prior = n_pix + (c if c < 3 else 3 * views + c - 3)
                    scale = 1.0 / (sigma_rad if c < 3 else sigma_mm)
                    for k in range(views):
                        col = n_global + 6 * k + c
                        out[rows_of_view[k], col] = diff[rows_of_view[k]]
                        out[prior + 3 * k, col] = scale
            return out

        res = least_squares(
            fun, np.zeros(n_params), jac=jac, method="trf", tr_solver="exact", loss=loss,
            f_scale=3.0, x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=100,
        )
        c2l, b2b, rot, org = unpack(res.x)
        err = self.residual(c2l, b2b)  # with the link poses as given
        # 1-sigma from the Gauss-Newton covariance at the solution, scaled by the fit's
        # own noise level when it is worse than assumed.
        j = np.asarray(res.jac)
        dof = max(1, res.fun.size - n_params)
        chi2 = max(1.0, float((res.fun * res.fun).sum()) / dof)
        try:
            cov = np.linalg.pinv(j.T @ j)[:6, :6] * chi2
            std_r = math.degrees(math.sqrt(max(0.0, float(np.trace(cov[0:3, 0:3])))))
            std_t = math.sqrt(max(0.0, float(np.trace(cov[3:6, 3:6]))))
        except np.linalg.LinAlgError:
            std_r = std_t = math.inf
        if with_poses:
            xi = res.x[n_global:].reshape(views, 6)
            w = np.linalg.norm(xi[:, :3], axis=1)
            v = np.linalg.norm(xi[:, 3:], axis=1)
            sigmas = np.sqrt(((w / sigma_rad) ** 2 + (v / sigma_mm) ** 2) / 2.0)
            pose_deg = math.degrees(float(np.sqrt((w * w).mean())))
            pose_mm = float(np.sqrt((v * v).mean()))
        else:
            sigmas, pose_deg, pose_mm = np.zeros(views), 0.0, 0.0
        return _HandEyeFit(
            c2l, b2b, self.per_view_rms(err), [float(m) for m in sigmas], std_t, std_r,
            pose_deg, pose_mm,
        )


# --------------------------------------------------------------------------- files


def _dumps(data: dict[str, Any], what: str) -> str:
    try:
        return json.dumps(data, indent=1, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"cannot write {what}: {exc} (meta values must be JSON data)") from None


def _intrinsics_json(intr: CameraIntrinsics) -> dict[str, Any]:
    return {
        "model": intr.model, "width_px": intr.width_px, "height_px": intr.height_px,
        "camera_matrix": intr.camera_matrix.tolist(), "distortion": intr.distortion.tolist(),
        "calibrated": intr.calibrated,
    }


def save_intrinsics(
    path: Path | str, result_or_intrinsics: IntrinsicsResult | CameraIntrinsics, **meta: Any
) -> None:
    """Write intrinsics (with the calibration's rms, views and board) atomically.

    ``meta`` (JSON values) is kept under "meta"; ``board=`` sets the board description.
    """
    if isinstance(result_or_intrinsics, IntrinsicsResult):
        r = result_or_intrinsics
        intr, rms, views, board = r.intrinsics, r.rms_px, len(r.views_used), r.board
    elif isinstance(result_or_intrinsics, CameraIntrinsics):
        intr, rms, views, board = result_or_intrinsics, None, None, ""
    else:
        raise ConfigError(
            f"save_intrinsics needs an IntrinsicsResult or CameraIntrinsics, got "
            f"{type(result_or_intrinsics).__name__}"
        )
    board = str(meta.pop("board", board))
    data = {
        "format": INTRINSICS_FORMAT, "version": FORMAT_VERSION, "created": _now(),
        **_intrinsics_json(intr), "rms_px": rms, "views": views, "board": board, "meta": meta,
    }
    write_text_atomic(path, _dumps(data, f"camera intrinsics {path}"), "camera intrinsics")


def _read(path: Path | str, what: str, fmt: str) -> tuple[dict[str, Any], str]:
    return read_versioned_json(path, what, fmt, FORMAT_VERSION, CalibrationError)


def _key(data: dict[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise CalibrationError(f"{where}: missing key {key!r}")
    return data[key]


def _number_array(
    data: dict[str, Any], key: str, where: str, shape: tuple[int, ...] | None
) -> FloatArray:
    value = _key(data, key, where)

    def numbers(v: Any) -> bool:
        if isinstance(v, list):
            return all(numbers(x) for x in v)
        return isinstance(v, int | float) and not isinstance(v, bool)

    if not isinstance(value, list) or not numbers(value):
        raise CalibrationError(f"{where}: key {key!r} must be a list of numbers")
    try:
        arr = np.array(value, dtype=np.float64)
    except ValueError:
        raise CalibrationError(f"{where}: key {key!r} is not a rectangular array") from None
    if shape is not None and arr.shape != shape:
        raise CalibrationError(f"{where}: key {key!r} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{where}: key {key!r} has non-finite numbers")
    return arr


def _optional_number(data: dict[str, Any], key: str, where: str) -> float | None:
    value = data.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise CalibrationError(f"{where}: key {key!r} must be a finite number, got {value!r}")
    return float(value)


def _intrinsics_from_json(data: dict[str, Any], where: str) -> CameraIntrinsics:
    model = _key(data, "model", where)
    if model not in MODELS:
        raise CalibrationError(f"{where}: key 'model' is {model!r}, not one of {', '.join(MODELS)}")
    size = []
    for key in ("width_px", "height_px"):
        v = _key(data, key, where)
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 100_000:
            raise CalibrationError(f"{where}: key {key!r} = {v!r} is not a size 1..100000 px")
        size.append(v)
    k = _number_array(data, "camera_matrix", where, (3, 3))
    d = _number_array(data, "distortion", where, None)
    calibrated = data.get("calibrated", True)
    if not isinstance(calibrated, bool):
        raise CalibrationError(f"{where}: key 'calibrated' must be true or false")
    try:
        return CameraIntrinsics(model, size[0], size[1], k, d, calibrated)
    except ConfigError as exc:
        raise CalibrationError(f"{where}: {exc}") from None


def load_intrinsics(
    path: Path | str, *, expect_size: tuple[int, int] | None = None
) -> CameraIntrinsics:
    """Read a ``busarm.camera_intrinsics`` file.

    ``expect_size`` (width, height): the camera's image size; a file made for another
    size raises CalibrationError saying so. Any problem names the file and the key.
    """
    data, where = _read(path, "camera intrinsics", INTRINSICS_FORMAT)
    intr = _intrinsics_from_json(data, where)
    _optional_number(data, "rms_px", where)
    if expect_size is not None and intr.size != tuple(expect_size):
        w, h = expect_size
        raise CalibrationError(
            f"{where}: made for {intr.width_px}x{intr.height_px} images (keys 'width_px', "
            f"'height_px'), but the camera delivers {w}x{h}: calibrate this camera at {w}x{h}"
        )
    return intr


def save_hand_eye(path: Path | str, result: HandEyeResult, **meta: Any) -> None:
    """Write a hand-eye calibration atomically, with the intrinsics it was made with.

    ``link=`` overrides the link name; other ``meta`` (JSON values) is kept under "meta".
    """
    if not isinstance(result, HandEyeResult):
        raise ConfigError(f"save_hand_eye needs a HandEyeResult, got {type(result).__name__}")
    link = meta.pop("link", result.link)
    if not isinstance(link, str) or not link:
        raise ConfigError(f"link must be a link name, got {link!r}")
    as_transform("cam2link", result.cam2link)
    data = {
        "format": HAND_EYE_FORMAT, "version": FORMAT_VERSION, "created": result.created or _now(),
        "link": link, "cam2link": result.cam2link.tolist(),
        "board2base": result.board2base.tolist(), "rms_px": result.rms_px,
        "per_view_rms_px": list(result.per_view_rms_px), "views_used": list(result.views_used),
        "method": result.method, "translation_std_mm": result.translation_std_mm,
        "rotation_std_deg": result.rotation_std_deg, "pose_rms_deg": result.pose_rms_deg,
        "pose_rms_mm": result.pose_rms_mm,
        "intrinsics": _intrinsics_json(result.intrinsics), "meta": meta,
    }
    write_text_atomic(path, _dumps(data, f"hand-eye {path}"), "hand-eye calibration")


def _rigid_from_json(data: dict[str, Any], key: str, where: str) -> FloatArray:
    t = _number_array(data, key, where, (4, 4))
    try:
        return as_transform(key, t)
    except ConfigError as exc:
        raise CalibrationError(f"{where}: key {key!r}: {exc}") from None


def load_hand_eye(
    path: Path | str, *, intrinsics: CameraIntrinsics | None = None
) -> HandEyeResult:
    """Read a ``busarm.hand_eye`` file.

    With ``intrinsics``: CalibrationError unless they are the ones the hand-eye was made
    with (a hand-eye is only valid with its intrinsics). Any problem names the file
    and the key.
    """
    data, where = _read(path, "hand-eye", HAND_EYE_FORMAT)
    link = _key(data, "link", where)
    if not isinstance(link, str) or not link:
        raise CalibrationError(f"{where}: key 'link' must be a link name, got {link!r}")
    c2l = _rigid_from_json(data, "cam2link", where)
    b2b = _rigid_from_json(data, "board2base", where) if "board2base" in data else np.eye(4)
    raw_intr = _key(data, "intrinsics", where)
    if not isinstance(raw_intr, dict):
        raise CalibrationError(f"{where}: key 'intrinsics' must be an object")
    file_intr = _intrinsics_from_json(raw_intr, f"{where} (key 'intrinsics')")
    if intrinsics is not None and not _same_intrinsics(file_intr, intrinsics):
        raise CalibrationError(
            f"{where}: made with other camera intrinsics (key 'intrinsics': "
            f"{file_intr.describe()}) than the ones given ({intrinsics.describe()}): redo the "
            f"hand-eye calibration with these intrinsics"
        )
    rms = _optional_number(data, "rms_px", where)
    per_view = data.get("per_view_rms_px", [])
    views = data.get("views_used", [])
    if not isinstance(per_view, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        for v in per_view
    ):
        raise CalibrationError(f"{where}: key 'per_view_rms_px' must be a list of numbers")
    if not isinstance(views, list) or not all(
        isinstance(v, int) and not isinstance(v, bool) for v in views
    ):
        raise CalibrationError(f"{where}: key 'views_used' must be a list of integers")
    method = data.get("method", "")
    return HandEyeResult(
        c2l, b2b, math.nan if rms is None else rms, tuple(float(v) for v in per_view),
        tuple(views), file_intr, link, str(method),
        _optional_number(data, "translation_std_mm", where) or 0.0,
        _optional_number(data, "rotation_std_deg", where) or 0.0,
        _optional_number(data, "pose_rms_deg", where) or 0.0,
        _optional_number(data, "pose_rms_mm", where) or 0.0, str(data.get("created", "")),
    )


def _same_intrinsics(a: CameraIntrinsics, b: CameraIntrinsics) -> bool:
    return (
        a.model == b.model and a.size == b.size and a.distortion.shape == b.distortion.shape
        and np.allclose(a.camera_matrix, b.camera_matrix, rtol=1e-9, atol=1e-9)
        and np.allclose(a.distortion, b.distortion, rtol=1e-9, atol=1e-12)
    )


__all__ = [
    "FORMAT_VERSION",
    "HAND_EYE_FORMAT",
    "INTRINSICS_FORMAT",
    "TAG_DICTIONARY",
    "BoardObservation",
    "BoardSpec",
    "CameraIntrinsics",
    "CharucoSpec",
    "ChessboardSpec",
    "HandEyeResult",
    "IntrinsicsResult",
    "TagBoardSpec",
    "as_transform",
    "board_image_frame",
    "board_pose",
    "calibrate_hand_eye",
    "calibrate_intrinsics",
    "default_min_points",
    "find_board",
    "invert_transform",
    "load_hand_eye",
    "load_intrinsics",
    "render_board_view",
    "save_hand_eye",
    "save_intrinsics",
]
