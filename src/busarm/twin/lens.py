"""The twin camera's lens: an ideal render bent by a real distortion model.

MuJoCo renders pinhole images only. To give the vision layer a camera with real
intrinsics and lens distortion, the scene is rendered by an ideal pinhole camera wide
enough to cover every ray the lens sees, then each output pixel fetches the colour of
its ray: output pixel -> undistorted normalised coordinates (OpenCV's model, solved
iteratively) -> render pixel, once into a remap table; per frame it is one cv2.remap.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.units import check_int_range

__all__ = [
    "LENSES",
    "REMAP_TABLES_KEPT",
    "VENDOR_DISTORTION",
    "WIDE_ANGLE_DISTORTION",
    "FloatArray",
    "LensSpec",
    "lens_by_name",
]


FloatArray = npt.NDArray[np.float64]

WIDE_ANGLE_DISTORTION = (-0.30, 0.12, 0.0008, -0.0006, -0.02)
"""k1 k2 p1 p2 k3 of the default twin lens: a cheap wide-angle USB camera's barrel
distortion (about 64 px at the corners), stronger than the vendor's calibration file,
so undistortion and calibration are exercised for real."""


VENDOR_DISTORTION = (-0.0275, -0.0005, -0.0059, -0.0034, -0.0356)
"""The vendor's own calibration file's coefficients (field notes): a mild lens."""


REMAP_TABLES_KEPT = 8
"""Lenses' remap tables kept (about 2 MB each at 640x480), oldest dropped first; equal
lenses share theirs."""
_REMAP_TABLES: dict[tuple[LensSpec, tuple[int, int, float] | None],
                    tuple[npt.NDArray[np.int16], npt.NDArray[np.uint16]]] = {}
_REMAP_LOCK = threading.Lock()


@dataclass(frozen=True)
class LensSpec:
    """A camera's true intrinsics (what calibration has to find): OpenCV pinhole model."""

    width_px: int = 640
    height_px: int = 480
    fx_px: float = 473.45
    fy_px: float = 474.22
    cx_px: float = 323.55
    cy_px: float = 238.60
    distortion: tuple[float, ...] = WIDE_ANGLE_DISTORTION
    oversample: float = 1.0
    """Render pixels per output pixel at the image centre (1 = the same density)."""

    def __post_init__(self) -> None:
        check_int_range("lens width_px", self.width_px, 16, 4096)
        check_int_range("lens height_px", self.height_px, 16, 4096)
        for name in ("fx_px", "fy_px", "cx_px", "cy_px", "oversample"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ConfigError(f"lens {name} = {v!r} must be a positive number")
        bad = ConfigError(f"lens distortion = {self.distortion!r}: expected 4, 5 or 8 "
                          "finite OpenCV coefficients (k1 k2 p1 p2 [k3 [k4 k5 k6]])")
        try:
            distortion = tuple(float(d) for d in self.distortion)
        except (TypeError, ValueError):
            raise bad from None
        if len(distortion) not in (4, 5, 8) or not all(
                math.isfinite(d) and abs(d) < 10 for d in distortion):
            raise bad
        # A tuple of floats whatever was given: equal lenses are equal and hashable (their
        # remap tables are shared).
        object.__setattr__(self, "distortion", distortion)

    @property
    def camera_matrix(self) -> FloatArray:
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px],
                         [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> FloatArray:
        return np.asarray(self.distortion, dtype=float)

    def _border_rays(self) -> FloatArray:
        """Undistorted normalised coordinates of points all around the image border."""
        w, h = self.width_px, self.height_px
        n = 64
        xs = np.linspace(-0.5, w - 0.5, n)
        ys = np.linspace(-0.5, h - 0.5, n)
        border = np.concatenate([
            np.stack([xs, np.full(n, -0.5)], 1), np.stack([xs, np.full(n, h - 0.5)], 1),
            np.stack([np.full(n, -0.5), ys], 1), np.stack([np.full(n, w - 0.5), ys], 1)])
        return self.normalized_from_pixels(border)

    def normalized_from_pixels(self, pixels_px: npt.ArrayLike) -> FloatArray:
        """Undistorted normalised image coordinates (x/z, y/z) of pixels."""
        pts = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 1, 2)
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        eye = np.eye(3)  # no rectification, and the identity as the new camera: x/z, y/z
        out = cv2.undistortPointsIter(pts, self.camera_matrix, self.dist_coeffs, eye, eye,
                                      criteria)
        return np.asarray(out, dtype=np.float64).reshape(-1, 2)

    def render_geometry(self) -> tuple[int, int, float]:
        """(width, height, vertical fov in degrees) of the ideal render behind the lens.

        The render is centred on the optical axis with square pixels of focal length
        ``oversample * max(fx, fy)``, just large enough to hold every border ray.
        """
        rays = self._border_rays()
        f = self.oversample * max(self.fx_px, self.fy_px)
        half_w = float(np.max(np.abs(rays[:, 0]))) * f + 2.0
        half_h = float(np.max(np.abs(rays[:, 1]))) * f + 2.0
        width, height = 2 * math.ceil(half_w), 2 * math.ceil(half_h)
        fovy = math.degrees(2 * math.atan(height / 2 / f))
        return width, height, fovy

    def remap_tables(
        self, render: tuple[int, int, float] | None = None,
    ) -> tuple[npt.NDArray[np.int16], npt.NDArray[np.uint16]]:
        """cv2.remap tables: for each output pixel, where its ray lands in the render: the
        one of ``render_geometry()``, or ``render`` = (width, height, vertical fov in
        degrees), the same view drawn at another size."""
        key = (self, render)  # an equal lens's tables are these (a twin a scene, one lens)
        maps = _REMAP_TABLES.get(key)
        if maps is not None:
            return maps
        width, height, fovy = render if render is not None else self.render_geometry()
        f = height / 2 / math.tan(math.radians(fovy) / 2)
        u, v = np.meshgrid(np.arange(self.width_px, dtype=np.float64),
                           np.arange(self.height_px, dtype=np.float64))
        rays = self.normalized_from_pixels(np.stack([u.ravel(), v.ravel()], 1))
        # OpenGL renders the optical axis through the middle of the image: in OpenCV's
        # pixel-centre convention that is ((W - 1) / 2, (H - 1) / 2).
        map_x = (rays[:, 0] * f + (width - 1) / 2).reshape(self.height_px, self.width_px)
        map_y = (rays[:, 1] * f + (height - 1) / 2).reshape(self.height_px, self.width_px)
        fixed = cv2.convertMaps(map_x.astype(np.float32), map_y.astype(np.float32),
                                cv2.CV_16SC2)
        maps = (np.asarray(fixed[0], np.int16), np.asarray(fixed[1], np.uint16))
        for table in maps:
            table.flags.writeable = False  # shared by every twin with this lens
        with _REMAP_LOCK:  # cameras of several twins may draw at once
            if len(_REMAP_TABLES) >= REMAP_TABLES_KEPT:
                _REMAP_TABLES.pop(next(iter(_REMAP_TABLES)))
            _REMAP_TABLES[key] = maps
        return maps

    def apply(self, render: npt.NDArray[np.uint8],
              fovy_deg: float | None = None) -> npt.NDArray[np.uint8]:
        """The image this lens makes of an ideal render (from ``render_geometry``; or,
        given its ``fovy_deg``, of the same view drawn at the render's own size). Each
        channel on its own: RGB in, RGB out."""
        height, width = render.shape[:2]
        map1, map2 = self.remap_tables(None if fovy_deg is None else (width, height, fovy_deg))
        out = cv2.remap(render, map1, map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=np.uint8)


LENSES = {
    "wide": LensSpec(),
    "vendor": LensSpec(distortion=VENDOR_DISTORTION),
    "none": LensSpec(distortion=(0.0, 0.0, 0.0, 0.0)),
}
"""Named lenses for the twin's camera (``twin://?lens=NAME``, ``twin snapshot --lens``)."""


def lens_by_name(name: str) -> LensSpec:
    try:
        return LENSES[name]
    except KeyError:
        raise ConfigError(f"lens {name!r}; allowed: {', '.join(LENSES)}") from None
