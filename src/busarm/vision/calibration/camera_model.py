"""The camera model: intrinsics, lens distortion, projection and undistortion."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError, VisionError
from busarm.units import check_int_range, fixed_number
from busarm.vision.calibration.core import FloatArray, _array, _points, _readonly

__all__ = [
    "DISTORTION_NAMES",
    "MODELS",
    "UNDISTORT_TOL_PX",
    "CameraIntrinsics",
    "distortion_text",
]


MODELS = ("pinhole", "fisheye")

UNDISTORT_TOL_PX = 0.01
"""An undistorted point re-distorts to within this of its pixel, or it is refused."""
_POLISH_PX = 1e-4
"""OpenCV's undistortion is polished with Newton steps when it is off by more than this."""
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-6)
_EYE3 = np.eye(3)
_EYE3.flags.writeable = False  # (OpenCV only reads it: made once, not per call)


DISTORTION_NAMES = {"pinhole": ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6"),
                    "fisheye": ("k1", "k2", "k3", "k4")}
"""OpenCV's names of the distortion coefficients, in their order, per model."""


def distortion_text(coefficients: Sequence[float] | FloatArray, model: str = "pinhole") -> str:
    """Distortion coefficients as a person reads them: ``k1 -0.3044, k2 0.1525, p1
    0.0008, ...`` (OpenCV's names, 4 decimals)."""
    names = DISTORTION_NAMES.get(model, ())
    return ", ".join(f"{names[i] if i < len(names) else f'd{i + 1}'} {fixed_number(float(v), 4)}"
                     for i, v in enumerate(coefficients))


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
        tag = "" if self.calibrated else ", not calibrated for this camera"
        return (
            f"{self.model} {self.width_px}x{self.height_px}: fx {self.fx:.2f} fy {self.fy:.2f} "
            f"cx {self.cx:.2f} cy {self.cy:.2f} px, distortion "
            f"{distortion_text(self.distortion, self.model)}{tag}"
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
        polygon's area and moments together. Same model and arithmetic as ``_distort``,
        on each column as a contiguous array (an operation between (..., 3) and a row of
        three runs numpy's inner loop three elements at a time, several times slower).
        """
        if self.model == "fisheye":
            q = p_cam / p_cam[..., 2:3]  # (x, y, 1)
            out = np.empty(q.shape)
            out[..., :2] = self._distort(q[..., :2])
            out[..., 2] = 1.0
            return out
        return self._project_h_columns(p_cam[..., 0], p_cam[..., 1], p_cam[..., 2])[2]

    def _project_h_columns(self, p_x: FloatArray, p_y: FloatArray, p_z: FloatArray
                           ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``_project_h`` of camera points given as their x, y and z arrays (one shape):
        a caller that builds the points by broadcasting builds each column cheaper.
        Returns u and v (contiguous: cheaper to compute with than columns) and the
        homogeneous pixels (..., 3)."""
        if self.model == "fisheye":
            out = self._project_h(np.stack([p_x, p_y, p_z], axis=-1))
            return out[..., 0], out[..., 1], out
        fx, fy, cx, cy, k1, k2, k3, k4, k5, k6, p1, p2 = self._coef
        z = p_z
        x, y = p_x / z, p_y / z
        r2 = x * x
        r2 += y * y
        radial = r2 * k3
        radial += k2
        radial *= r2
        radial += k1
        radial *= r2
        radial += 1.0
        if k4 or k5 or k6:
            radial /= 1.0 + r2 * (k4 + r2 * (k5 + r2 * k6))
        u, v = x * radial, y * radial
        # 1, or NaN where the point's ray is not finite: (z / z * radial) * 0 + 1, as the
        # homogeneous form (tangential terms and focal length 0 there) gives it.
        w = z / z
        w *= radial
        w *= 0.0
        w += 1.0
        if p1 or p2:
            # x: + (2 x^2 + r^2) p2 + x y 2 p1;  y: + (2 y^2 + r^2) p1 + x y 2 p2
            xy = x * y
            for col, sq, p_sq, p_xy in ((u, x * x, p2, 2.0 * p1), (v, y * y, p1, 2.0 * p2)):
                sq *= 2.0
                sq += r2
                sq *= p_sq
                col += sq
                col += xy * p_xy
        u *= fx
        u += cx
        v *= fy
        v += cy
        out = np.empty((*u.shape, 3))
        out[..., 0], out[..., 1], out[..., 2] = u, v, w
        return u, v, out

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

    def plane_pixel_maps(
        self, grid2cam: FloatArray, cols: int, rows: int, offset_px: tuple[float, float]
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """Where a grid of points falls in the picture, as ``cv2.remap``'s maps (float32).

        Grid place (column c, row r) is the camera point ``grid2cam @ (c, r, 1)`` (mm);
        its distorted pixel less ``offset_px`` is at ``[r, c]`` of the two maps (u, v).
        VisionError if a grid corner is not in front of the camera (z affine in c and r:
        then none is behind it). For a pinhole lens OpenCV computes the maps in one C
        pass (the projective map as a rectification); the same model as ``_distort``.
        """
        m = np.asarray(grid2cam, dtype=np.float64)
        corners = m @ np.array([[0.0, cols - 1.0, 0.0, cols - 1.0],
                                [0.0, 0.0, rows - 1.0, rows - 1.0], [1.0, 1.0, 1.0, 1.0]])
        if not bool(np.all(corners[2] > 0.0)):
            raise VisionError("part of the grid lies behind the camera (z must be > 0)")
        if self.model == "pinhole":
            k = np.array([[self.fx, 0.0, self.cx - offset_px[0]],
                          [0.0, self.fy, self.cy - offset_px[1]], [0.0, 0.0, 1.0]])
            map_u, map_v = cv2.initUndistortRectifyMap(
                k, self.distortion, np.linalg.inv(m), _EYE3, (cols, rows), cv2.CV_32FC1)
            return np.asarray(map_u, np.float32), np.asarray(map_v, np.float32)
        p_cam = ((m[:, 2] + np.arange(cols, dtype=np.float64)[:, None] * m[:, 0])[None]
                 + np.arange(rows, dtype=np.float64)[:, None, None] * m[:, 1])
        px = (self._project(p_cam) - offset_px).astype(np.float32)
        return np.ascontiguousarray(px[..., 0]), np.ascontiguousarray(px[..., 1])

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
                src, self.camera_matrix, self.distortion, _EYE3, _EYE3,
                _UNDISTORT_CRITERIA,
            )
        else:
            out = cv2.fisheye.undistortPoints(
                src, self.camera_matrix, self.distortion, criteria=_UNDISTORT_CRITERIA
            )
        xy = np.asarray(out, dtype=np.float64).reshape(-1, 2)
        err = np.abs(self._distort(xy) - p).max(axis=1)
        bad = ~(err <= _POLISH_PX)
        if bad.any():
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
        if not (k4 or k5 or k6):
            # No rational part: den is 1 and dden 0 below, so the same signs come from
            # fewer passes (where the polynomial overflows, distorting back fails anyway).
            num = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dnum = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3)
            polynomial: npt.NDArray[np.bool_] = (num > 0.0) & (num + 2.0 * r2 * dnum > 0.0)
            return polynomial
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
            right: FloatArray = xy + np.array([h, 0.0])
            down: FloatArray = xy + np.array([0.0, h])
            probe = np.stack([xy, right, down], axis=1)
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
