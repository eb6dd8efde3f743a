"""How big a thing on the table is, and whether it is a box, from its outline in pictures.

A thing standing on the table is taken to be a box (a cuboid): footprint centre (x, y),
yaw, length, width and height, in mm in the arm's base frame. Its outline in a picture is
the outline of the projection of its eight corners (their convex hull: a box is convex).
``fit_box`` finds the box whose projected outlines match the measured ones in every view
(least squares on each outline point's distance to the box's outline, and each of the
box's outline corners' distance to the measured outline), in undistorted normalised
image coordinates, where the box's edges are straight, so lens distortion costs nothing
in the loop.

What the fit says beyond the sizes:

- ``fit_px``: how far (RMS, px) the outline is from the best box's. A box's outline is
  straight-edged; a cylinder's or a disc's is curved, and no box matches it closely.
- Seen from above, one outline does not pin a box down: a flat box a little larger, or a
  tall one a little smaller, casts nearly the same outline as a cube. Two views from
  poses apart (the base turned 25 deg) do: fit them together.

The outline must be the whole thing's (its sides included, however dark they are lit):
``thing_outline`` grows a colour blob by the pixels next to it that are not the table.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from busarm.errors import VisionError
from busarm.vision.calibration import CameraIntrinsics

__all__ = [
    "GOOD_FIT_PX",
    "HULL_POINTS",
    "OUTLINE_POINTS",
    "BoxFit",
    "FloatArray",
    "fit_box",
    "side_pixels",
    "table_mask",
    "thing_outline",
]

FloatArray = npt.NDArray[np.float64]

OUTLINE_POINTS = 64
"""Points taken along each view's outline (evenly by arc length)."""
GOOD_FIT_PX = 0.6
"""A fit this close (RMS px) is taken as found; a worse one is tried from another start."""
HULL_POINTS = 32
"""Points taken along the box's outline, each held to the measured outline."""
_CORNERS = np.array([[sx, sy, sz] for sz in (0.0, 1.0) for sx in (-0.5, 0.5)
                     for sy in (-0.5, 0.5)])
"""The unit box's corners: footprint centred on the origin, z from 0 (table) to 1."""
_LOWER = [-np.inf, -np.inf, -np.inf, 1.0, 1.0, 0.5]
_UPPER = [np.inf, np.inf, np.inf, 400.0, 400.0, 400.0]
_SCALE = [5.0, 5.0, 0.1, 5.0, 5.0, 5.0]
"""x, y, yaw, length, width, height: bounds and typical steps (mm, rad)."""


@dataclass(frozen=True)
class BoxFit:
    """The box that best explains a thing's outlines (mm, deg, base frame)."""

    x_mm: float
    y_mm: float
    yaw_deg: float
    length_mm: float
    """The longer side of the footprint."""
    width_mm: float
    height_mm: float
    fit_px: float
    """RMS distance (px) between the measured outlines and the box's."""
    views: int

    @property
    def sides_mm(self) -> tuple[float, float, float]:
        return (self.length_mm, self.width_mm, self.height_mm)

    def __repr__(self) -> str:
        return (f"BoxFit({self.length_mm:.1f} x {self.width_mm:.1f} x {self.height_mm:.1f} mm"
                f" at ({self.x_mm:.1f}, {self.y_mm:.1f}), fit {self.fit_px:.2f} px, "
                f"{self.views} view(s))")


@dataclass(frozen=True)
class _View:
    outline: FloatArray
    """(N, 2) outline points, undistorted normalised."""
    segments: tuple[FloatArray, FloatArray]
    """The outline as a closed polyline: starts and ends (M, 2)."""
    base2cam: FloatArray
    scale_px: float
    """Pixels per normalised unit (fx)."""


def _resample(contour: FloatArray, count: int) -> FloatArray:
    """``count`` points evenly spaced along a closed contour."""
    closed = np.vstack([contour, contour[:1]])
    step = np.hypot(*np.diff(closed, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(step)])
    at = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.column_stack([np.interp(at, arc, closed[:, 0]), np.interp(at, arc, closed[:, 1])])


def _view(contour_px: npt.ArrayLike, cam2base: FloatArray, intr: CameraIntrinsics) -> _View:
    c = np.asarray(contour_px, dtype=np.float64).reshape(-1, 2)
    if c.shape[0] < 4:
        raise VisionError(f"an outline of {c.shape[0]} points is too short to fit a box to")
    poly = cv2.approxPolyDP(c.astype(np.float32).reshape(-1, 1, 2), 1.0, True).reshape(-1, 2)
    poly_n = intr.normalized_from_pixels(poly.astype(np.float64))
    pts = intr.normalized_from_pixels(_resample(c, OUTLINE_POINTS))
    base2cam: FloatArray = np.linalg.inv(cam2base)
    return _View(pts, (poly_n, np.roll(poly_n, -1, axis=0)), base2cam, float(intr.fx))


def _segment_distances(points: FloatArray, starts: FloatArray, ends: FloatArray) -> FloatArray:
    """Each point's distance to the nearest of the segments (starts -> ends)."""
    d = ends - starts
    rel = points[:, None, :] - starts[None]
    t = np.clip((rel * d).sum(axis=2) / np.maximum((d * d).sum(axis=1), 1e-18), 0.0, 1.0)
    gap = rel - t[..., None] * d
    out: FloatArray = np.sqrt((gap * gap).sum(axis=2).min(axis=1))
    return out


def _box_corners(p: FloatArray, table_z_mm: float) -> FloatArray:
    x, y, yaw, length, width, height = p
    c, s = math.cos(yaw), math.sin(yaw)
    local = _CORNERS * (length, width, height)
    out: FloatArray = np.column_stack([x + c * local[:, 0] - s * local[:, 1],
                                       y + s * local[:, 0] + c * local[:, 1],
                                       table_z_mm + local[:, 2]])
    return out


def _residuals(p: FloatArray, views: Sequence[_View], table_z_mm: float) -> FloatArray:
    corners = _box_corners(p, table_z_mm)
    out = []
    for v in views:
        cam = corners @ v.base2cam[:3, :3].T + v.base2cam[:3, 3]
        z = np.maximum(cam[:, 2], 1.0)  # a corner behind the camera: no fit (kept finite)
        img = cam[:, :2] / z[:, None]
        # Which corners make the outline, from float32 (OpenCV's); the outline itself in
        # float64, so that the fit's small steps are not lost to rounding.
        index = cv2.convexHull(img.astype(np.float32), returnPoints=False).ravel()
        hull = img[index]
        out.append(_segment_distances(v.outline, hull, np.roll(hull, -1, axis=0)) * v.scale_px)
        out.append(_segment_distances(_resample(hull, HULL_POINTS), *v.segments) * v.scale_px)
    return np.concatenate(out)


def fit_box(views: Sequence[tuple[npt.ArrayLike, npt.ArrayLike]], intrinsics: CameraIntrinsics,
            table_z_mm: float, guess: tuple[float, float, float, float]) -> BoxFit:
    """The box (standing on the table at ``table_z_mm``) whose outline matches each
    ``(outline_px, cam2base)`` view; ``guess``: (x mm, y mm, yaw deg, side mm) to start
    from. VisionError if an outline cannot be used."""
    if not views:
        raise VisionError("fit_box needs at least one view")
    prepared = [_view(c, np.asarray(t, dtype=np.float64), intrinsics) for c, t in views]
    x0, y0, yaw0, side0 = guess
    fit = None
    # A square's yaw is known modulo 90 deg only: a start 45 deg off can settle on a
    # box turned the wrong way, so a poor fit is tried again from the other diagonal.
    for turn_deg in (0.0, 45.0):
        start = np.array([x0, y0, math.radians(yaw0 + turn_deg), side0, side0, side0])
        start[3:] = np.clip(start[3:], 2.0, 399.0)
        tried = least_squares(_residuals, start, args=(prepared, table_z_mm),
                              bounds=(_LOWER, _UPPER), x_scale=_SCALE, max_nfev=200)
        if fit is None or tried.cost < fit.cost:
            fit = tried
        if math.sqrt(2.0 * fit.cost / fit.fun.size) < GOOD_FIT_PX:
            break
    assert fit is not None
    x, y, yaw, a, b, h = fit.x
    rms = float(np.sqrt(np.mean(fit.fun ** 2)))
    if a < b:
        a, b, yaw = b, a, yaw + math.pi / 2
    yaw_deg = (math.degrees(yaw) + 90.0) % 180.0 - 90.0
    return BoxFit(float(x), float(y), yaw_deg, float(a), float(b), float(h), rms, len(prepared))


def table_mask(image: npt.NDArray[np.uint8], saturation: int = 40, dark: float = 0.55,
               bright: float = 1.12) -> npt.NDArray[np.uint8]:
    """255 where a pixel is not the table: saturated, or much darker or brighter than the
    table's median brightness (busarm.perception.obstacles uses the same rule)."""
    hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
    s, v = hsv[..., 1], hsv[..., 2]
    grey = v[s < saturation].astype(np.float64)
    med = float(np.median(grey)) if grey.size else 128.0
    mask = (s >= saturation) | (v < dark * med) | ((v > bright * med) & (s < saturation))
    return mask.astype(np.uint8) * 255


def thing_outline(blob_contour_px: npt.ArrayLike, sides: npt.NDArray[np.uint8],
                  grow_px: int) -> npt.NDArray[np.int32] | None:
    """The whole thing's outline: the colour blob with the ``sides`` pixels (255: not the
    table and in no colour blob: a side in shade) within ``grow_px`` of it that connect to
    it; None if the picture's edge cuts it."""
    h, w = sides.shape[:2]
    blob = np.zeros((h, w), np.uint8)
    cv2.drawContours(blob, [np.asarray(blob_contour_px, np.int32).reshape(-1, 1, 2)], -1, 255,
                     cv2.FILLED)
    size = 2 * max(1, grow_px) + 1
    near = cv2.dilate(blob, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)))
    thing = cv2.bitwise_or(blob, cv2.bitwise_and(near, sides))
    _, labels = cv2.connectedComponents(thing)
    inside = labels[blob > 0]
    keep = np.bincount(inside[inside > 0]).argmax() if inside.size else 0
    part = (labels == keep).astype(np.uint8) * 255
    contours, _ = cv2.findContours(part, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    c = max(contours, key=cv2.contourArea).reshape(-1, 2)
    if c[:, 0].min() <= 0 or c[:, 1].min() <= 0 or c[:, 0].max() >= w - 1 \
            or c[:, 1].max() >= h - 1:
        return None
    return np.asarray(c, np.int32)


def side_pixels(image: npt.NDArray[np.uint8], blob_contours: Sequence[npt.ArrayLike]
                ) -> npt.NDArray[np.uint8]:
    """255 where a pixel may be a thing's side in shade: not the table, and in none of the
    colour blobs (a neighbour's blob is the neighbour, not this thing's side)."""
    mask = table_mask(image)
    cv2.drawContours(mask, [np.asarray(c, np.int32).reshape(-1, 1, 2) for c in blob_contours],
                     -1, 0, cv2.FILLED)
    return mask
