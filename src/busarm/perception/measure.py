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
from busarm.perception.obstacles import (
    ARM_DARK,
    BRIGHT,
    DARK,
    TABLE_SATURATION,
    WHITE_SATURATION,
)
from busarm.perception.outline_fit import (
    HULL_POINTS,
    FiniteDifferences,
    PreparedView,
    box_corners,
    cylinder_points,
    misfit,
    prepared_view,
    residuals,
)
from busarm.units import check_range
from busarm.vision.calibration import CameraIntrinsics

__all__ = [
    "COLOURED",
    "GOOD_FIT_PX",
    "HULL_POINTS",
    "KEPT_SHARE",
    "OUTLINE_POINTS",
    "ROBUST_PX",
    "BoxFit",
    "CylinderFit",
    "FloatArray",
    "OutlineView",
    "PreparedViews",
    "TablePixels",
    "fit_box",
    "fit_cylinder",
    "prepare_views",
    "table_pixels",
    "thing_outline",
]

FloatArray = npt.NDArray[np.float64]

OUTLINE_POINTS = 64
"""Points taken along each view's outline (evenly by arc length)."""
ROBUST_PX = 0.7
"""Outline distances beyond this count less and less in the fit (a robust loss)."""
KEPT_SHARE = 0.9
"""The share of outline distances a fit is judged by (the rest may be a neighbour's)."""
COLOURED = 60
"""A pixel this much more saturated (0-255) than the table is something on it."""
GOOD_FIT_PX = 0.6
"""A fit this close (RMS px) is taken as found; a worse one is tried from another start."""
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
    view_fit_px: tuple[float, ...] = ()
    """``fit_px`` of each view alone (a view from the side tells heights apart that one
    from above cannot: together they would blur it)."""

    @property
    def sides_mm(self) -> tuple[float, float, float]:
        return (self.length_mm, self.width_mm, self.height_mm)

    def __repr__(self) -> str:
        return (f"BoxFit({self.length_mm:.1f} x {self.width_mm:.1f} x {self.height_mm:.1f} mm"
                f" at ({self.x_mm:.1f}, {self.y_mm:.1f}), fit {self.fit_px:.2f} px, "
                f"{self.views} view(s))")


@dataclass(frozen=True)
class OutlineView:
    """One picture's outline of a thing (px, in order) and where the camera was
    (``cam2base``); ``trusted``: per outline point, False where the outline borders
    another thing (a neighbour hides the thing there: the outline is the neighbour's)."""

    outline_px: npt.NDArray[np.int32]
    cam2base: FloatArray
    trusted: npt.NDArray[np.bool_] | None = None

    def __repr__(self) -> str:
        kept = "" if self.trusted is None else f", {int(self.trusted.sum())} trusted"
        return f"OutlineView({len(self.outline_px)} outline points{kept})"

    @property
    def trusted_share(self) -> float:
        return 1.0 if self.trusted is None else float(np.mean(self.trusted))


def _resample(contour: FloatArray, count: int) -> FloatArray:
    """``count`` points evenly spaced along a closed contour."""
    closed = np.vstack([contour, contour[:1]])
    step = np.hypot(*np.diff(closed, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(step)])
    at = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.column_stack([np.interp(at, arc, closed[:, 0]), np.interp(at, arc, closed[:, 1])])


@dataclass(frozen=True)
class PreparedViews:
    """Views made ready for fitting (``prepare_views``): several fits of the same views
    (``fit_box``, ``fit_cylinder``) then undistort their outlines once."""

    views: tuple[OutlineView, ...]
    prepared: tuple[PreparedView, ...]


def prepare_views(views: Sequence[OutlineView], intrinsics: CameraIntrinsics
                  ) -> PreparedViews:
    """``views`` ready for fitting with ``intrinsics``. VisionError if an outline cannot
    be used."""
    return PreparedViews(tuple(views), tuple(_view(v, intrinsics) for v in views))


def _prepared(views: Sequence[OutlineView] | PreparedViews, intrinsics: CameraIntrinsics
              ) -> tuple[PreparedView, ...]:
    if isinstance(views, PreparedViews):
        return views.prepared
    return prepare_views(views, intrinsics).prepared


def _view(view: OutlineView, intr: CameraIntrinsics) -> PreparedView:
    c = np.asarray(view.outline_px, dtype=np.float64).reshape(-1, 2)
    if c.shape[0] < 4:
        raise VisionError(f"an outline of {c.shape[0]} points is too short to fit a box to")
    samples = _outward(_resample(c, OUTLINE_POINTS), 0.5)
    weight: FloatArray = np.ones(OUTLINE_POINTS)
    if view.trusted is not None:
        # Each sample takes its nearest outline point's trust.
        nearest = np.argmin(((samples[:, None, :] - c[None]) ** 2).sum(axis=2), axis=1)
        own: FloatArray = np.asarray(view.trusted, dtype=np.float64)[nearest]
        weight = np.asarray(np.minimum(own, np.roll(own, -1)), dtype=np.float64)  # both ends
    base2cam = np.asarray(np.linalg.inv(np.asarray(view.cam2base, dtype=np.float64)), np.float64)
    return prepared_view(intr.normalized_from_pixels(samples), weight, base2cam,
                         float(intr.fx))


def _outward(points: FloatArray, by_px: float) -> FloatArray:
    """A closed outline moved ``by_px`` outward: a traced outline runs through its edge
    pixels' centres, half a pixel inside the thing's edge."""
    tangent = np.roll(points, -1, axis=0) - np.roll(points, 1, axis=0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    normal /= np.maximum(np.hypot(normal[:, 0], normal[:, 1]), 1e-9)[:, None]
    x, y = points[:, 0], points[:, 1]
    area = 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    # (dy, -dx) points outward for a counter-clockwise outline in y-up terms; image rows
    # run down, so the sign of the area decides.
    out: FloatArray = points + (-by_px if area < 0 else by_px) * normal
    return out


def _weighted(p: FloatArray, views: Sequence[PreparedView], table_z_mm: float
              ) -> tuple[FloatArray, FloatArray]:
    """The fit's residuals (px) for box ``p``, and each one's weight (0: untrusted)."""
    res, weight = misfit(box_corners(p[None], table_z_mm), views)
    return res[0], weight[0]


def fit_box(views: Sequence[OutlineView] | PreparedViews, intrinsics: CameraIntrinsics,
            table_z_mm: float, guess: tuple[float, float, float, float], *,
            aspect: float | None = None, turned_retry: bool = True,
            tolerance: float = 1e-8) -> BoxFit:
    """The box (standing on the table at ``table_z_mm``) whose outline matches each
    view's (its trusted part); ``guess``: (x mm, y mm, yaw deg, side mm) to start
    from. ``aspect``: None for any box; else a square footprint and the height this
    times its side (1: a cube). ``views`` may be prepared (``prepare_views``) for several
    fits. ``turned_retry``: a poor fit is tried again with the yaw turned 45 deg (False:
    the guess's yaw is already a fit's). ``tolerance``: the fit ends when a step changes
    its cost or parameters less than this share (scipy's ``ftol`` and ``xtol``).
    VisionError if an outline cannot be used."""
    check_range("tolerance", tolerance, 1e-10, 0.1)
    prepared = _prepared(views, intrinsics)
    if not prepared:
        raise VisionError("fit_box needs at least one view")
    x0, y0, yaw0, side0 = guess
    side0 = min(max(side0, 2.0), 399.0)
    ratio = None if aspect is None else float(aspect)
    size = 6 if ratio is None else 4
    lower, upper, scale = _LOWER[:size], _UPPER[:size], _SCALE[:size]
    # The Jacobian's steps are measured in one batch (busarm.perception.outline_fit).
    steps = FiniteDifferences(lambda q: residuals(box_corners(_box_of(q, ratio), table_z_mm),
                                                  prepared), lower, upper)
    fit = None
    # A square's yaw is known modulo 90 deg only: a start 45 deg off can settle on a
    # box turned the wrong way, so a poor fit is tried again from the other diagonal.
    for turn_deg in (0.0, 45.0):
        start = np.array([x0, y0, math.radians(yaw0 + turn_deg), side0, side0, side0])
        tried = least_squares(steps.residuals, start[:size], jac=steps.jacobian,
                              bounds=(lower, upper), x_scale=scale, max_nfev=200,
                              loss="soft_l1", f_scale=ROBUST_PX, ftol=tolerance,
                              xtol=tolerance)
        if fit is None or tried.cost < fit.cost:
            fit = tried
        if not turned_retry or _fit_px(fit.fun) < GOOD_FIT_PX:
            break
    assert fit is not None
    return _box_fit(fit.x, ratio, prepared, table_z_mm)


def _box_fit(p: FloatArray, ratio: float | None, prepared: Sequence[PreparedView],
             table_z_mm: float) -> BoxFit:
    """The box of a fit's parameters ``p``, and how well it fits."""
    q = _box_of(p[None], ratio)[0]
    x, y, yaw, a, b, h = q
    res, weight = _weighted(q, prepared, table_z_mm)
    rms = _fit_px(res[weight > 0])
    each = OUTLINE_POINTS + HULL_POINTS  # residuals per view, in order
    per_view = tuple(_fit_px(r[w > 0]) for r, w in zip(
        np.split(res, len(prepared)), np.split(weight, len(prepared)), strict=True))
    assert res.size == each * len(prepared)
    if a < b:
        a, b, yaw = b, a, yaw + math.pi / 2
    yaw_deg = (math.degrees(yaw) + 90.0) % 180.0 - 90.0
    return BoxFit(float(x), float(y), yaw_deg, float(a), float(b), float(h), rms, len(prepared),
                  per_view)


def _box_of(q: FloatArray, ratio: float | None) -> FloatArray:
    """Boxes (B, 6) from a fit's parameters (B, 6; or B, 4 with a square footprint and
    the height ``ratio`` times its side)."""
    if ratio is None:
        return q
    return np.column_stack([q, q[:, 3], ratio * q[:, 3]])


@dataclass(frozen=True)
class CylinderFit:
    """The upright cylinder that best explains a thing's outlines (mm, base frame)."""

    x_mm: float
    y_mm: float
    diameter_mm: float
    height_mm: float
    fit_px: float

    def __repr__(self) -> str:
        return (f"CylinderFit({self.diameter_mm:.1f} mm across, {self.height_mm:.1f} mm tall"
                f" at ({self.x_mm:.1f}, {self.y_mm:.1f}), fit {self.fit_px:.2f} px)")


def fit_cylinder(views: Sequence[OutlineView] | PreparedViews,
                 intrinsics: CameraIntrinsics, table_z_mm: float,
                 guess: tuple[float, float, float]) -> CylinderFit:
    """The upright cylinder (a cup, a disc) whose outline matches each view's best;
    ``guess``: (x mm, y mm, diameter mm). A box's outline is straight-edged and a
    cylinder's curved: which of the two fits better says which it is."""
    prepared = _prepared(views, intrinsics)
    if not prepared:
        raise VisionError("fit_cylinder needs at least one view")
    x0, y0, d0 = guess
    lower, upper = [-np.inf, -np.inf, 0.5, 0.5], [np.inf, np.inf, 200.0, 400.0]
    steps = FiniteDifferences(
        lambda q: residuals(cylinder_points(q, table_z_mm), prepared), lower, upper)
    start = np.array([x0, y0, min(max(d0 / 2, 1.0), 199.0), min(max(d0, 1.0), 399.0)])
    fit = least_squares(steps.residuals, start, jac=steps.jacobian, bounds=(lower, upper),
                        x_scale=[5.0, 5.0, 5.0, 5.0], max_nfev=200, loss="soft_l1",
                        f_scale=ROBUST_PX)
    res, weight = misfit(cylinder_points(fit.x[None], table_z_mm), prepared)
    x, y, radius, height = (float(v) for v in fit.x)
    return CylinderFit(x, y, 2 * radius, height, _fit_px(res[0][weight[0] > 0]))


def _fit_px(residuals_px: FloatArray) -> float:
    """How far an outline is from a box's: the RMS of the closest ``KEPT_SHARE`` of the
    distances (where a thing's shadow joins it, the outline there is not the thing's; a
    round thing is off all round)."""
    if residuals_px.size == 0:
        return math.inf
    d = np.sort(np.abs(residuals_px))[:max(1, int(KEPT_SHARE * residuals_px.size))]
    return float(np.sqrt(np.mean(d * d)))


@dataclass(frozen=True)
class TablePixels:
    """A picture's pixels sorted against the table under them (255 masks)."""

    shaded: npt.NDArray[np.uint8]
    """Much darker than the table (a side in shade; a shadow is lighter) or much brighter
    and unsaturated (something white), but not black (the arm's own links)."""
    coloured: npt.NDArray[np.uint8]
    """Much more coloured than the table (a warm lamp tints it: not saturation alone)."""
    black: npt.NDArray[np.uint8]
    hue: npt.NDArray[np.uint8]
    """OpenCV's hue, 0..179."""

    @property
    def something(self) -> npt.NDArray[np.uint8]:
        """Everything that is not the table."""
        out: npt.NDArray[np.uint8] = self.shaded | self.coloured | self.black
        return out


def table_pixels(image: npt.NDArray[np.uint8]) -> TablePixels:
    """``image``'s pixels against the table's brightness and tint, by
    busarm.perception.obstacles' rules."""
    hsv: npt.NDArray[np.uint8] = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2HSV), np.uint8)
    s, v = hsv[..., 1], hsv[..., 2].astype(np.float64)
    table = _table_brightness(hsv)
    black = v < ARM_DARK * table
    shaded = ((v < DARK * table) | ((v > BRIGHT * table) & (s < WHITE_SATURATION))) & ~black
    near = np.abs(v - table) < 0.1 * table
    tint = float(np.median(s[near].astype(np.float64))) if near.any() else 0.0
    coloured = (s > tint + COLOURED) & ~shaded & ~black

    def u8(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.uint8]:
        return mask.astype(np.uint8) * 255

    return TablePixels(u8(shaded), u8(coloured), u8(black), np.asarray(hsv[..., 0]))


def _table_brightness(hsv: npt.NDArray[np.uint8]) -> float:
    """The table's brightness: the commonest brightness of the picture's pixels that are
    not strongly coloured (the table fills most of a picture of it; a warm lamp tints it,
    and the floor beyond its edge, dark, may fill a good part too)."""
    plain = hsv[..., 2][hsv[..., 1] < 3 * TABLE_SATURATION]
    if plain.size == 0:
        plain = hsv[..., 2].ravel()
    counts = np.bincount(plain.ravel(), minlength=256).astype(np.float64)
    smooth = np.convolve(counts, np.ones(9) / 9.0, mode="same")
    return float(max(int(np.argmax(smooth)), 1))


def thing_outline(blob_contour_px: npt.ArrayLike, sides: npt.NDArray[np.uint8],
                  toward_px: tuple[float, float], grow_px: int) -> npt.NDArray[np.int32] | None:
    """The whole thing's outline: the colour blob with the ``sides`` pixels (255: not the
    table and in no colour blob: a side in shade) that connect to it, swept up to
    ``grow_px`` from it toward ``toward_px`` (the picture's point below the camera: a
    thing's sides show on that side of its top); None if the picture's edge cuts it."""
    h, w = sides.shape[:2]
    c = np.asarray(blob_contour_px, np.int32).reshape(-1, 2)
    x0, y0, bw, bh = cv2.boundingRect(c)
    # Work in a window round the blob (the picture may be large, the blob is not).
    pad = grow_px + 2
    left, top = max(0, x0 - pad), max(0, y0 - pad)
    right, bottom = min(w, x0 + bw + pad), min(h, y0 + bh + pad)
    blob = np.zeros((bottom - top, right - left), np.uint8)
    cv2.drawContours(blob, [(c - (left, top)).reshape(-1, 1, 2)], -1, 255, cv2.FILLED)
    centre = np.array([x0 + bw / 2, y0 + bh / 2])
    way = np.asarray(toward_px, dtype=np.float64) - centre
    way = way / max(float(np.hypot(*way)), 1e-9)
    swept: npt.NDArray[np.uint8] = blob.copy()
    steps = max(1, grow_px // 2)
    for k in range(1, steps + 1):
        dx, dy = way * grow_px * k / steps
        shift = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]], dtype=np.float32)
        swept |= np.asarray(cv2.warpAffine(blob, shift, (blob.shape[1], blob.shape[0])),
                            np.uint8)
    swept = np.asarray(cv2.dilate(swept, np.ones((3, 3), np.uint8)), np.uint8)
    thing = blob | (swept & sides[top:bottom, left:right])
    _, labels = cv2.connectedComponents(thing)
    inside = labels[blob > 0]
    keep = np.bincount(inside[inside > 0]).argmax() if inside.size else 0
    part = (labels == keep).astype(np.uint8) * 255
    contours, _ = cv2.findContours(part, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return None
    out = max(contours, key=cv2.contourArea).reshape(-1, 2) + np.array([left, top])
    if out[:, 0].min() <= 0 or out[:, 1].min() <= 0 or out[:, 0].max() >= w - 1 \
            or out[:, 1].max() >= h - 1:
        return None
    return np.asarray(out, np.int32)
