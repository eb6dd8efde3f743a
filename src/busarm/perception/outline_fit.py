"""The outline misfit behind busarm.perception.measure's fits, for many shapes at once.

A fit (scipy's ``least_squares``) asks for the residuals of one shape per step and, for its
Jacobian, of one shape per parameter, each a step off (finite differences). Each shape's
misfit is a few dozen small numpy operations: their cost is the calls, not the arithmetic.
Here a batch of shapes (their corners, ``(B, P, 3)``) is measured in one pass of the same
operations on ``(B, ...)`` arrays, and ``FiniteDifferences`` gives ``least_squares`` the
Jacobian it would have taken (the same steps, the same differences) from one batch.

Each residual is computed as one shape alone would have it, with the same arithmetic; a
hull of fewer corners than the batch's largest is padded by repeating its last corner
(a segment of no length: no point's nearest, nothing outside it, nothing to its area).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

__all__ = [
    "FiniteDifferences",
    "PreparedView",
    "box_corners",
    "cylinder_points",
    "misfit",
    "prepared_view",
    "residuals",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

HULL_POINTS = 32
"""Points taken along the shape's outline, each held to the measured outline."""
_CORNERS = np.array([[sx, sy, sz] for sz in (0.0, 1.0) for sx in (-0.5, 0.5)
                     for sy in (-0.5, 0.5)])
"""The unit box's corners: footprint centred on the origin, z from 0 (table) to 1."""
_CIRCLE = np.array([[np.cos(a), np.sin(a)]
                    for a in np.linspace(0.0, 2 * np.pi, 24, endpoint=False)])
_STEP = float(np.finfo(np.float64).eps ** 0.5)
"""scipy's relative finite-difference step for '2-point' differences."""


@dataclass(frozen=True)
class PreparedView:
    """One view's outline made ready for fitting (undistorted normalised coordinates)."""

    outline: FloatArray
    """(N, 2) outline points, evenly along it (a closed polyline)."""
    weight: FloatArray
    """(N,) 1 where the outline point (and the segment from it) is the thing's, else 0."""
    base2cam: FloatArray
    scale_px: float
    """Pixels per normalised unit (fx)."""
    rotation_t: FloatArray
    """base2cam's rotation, transposed (points @ it)."""
    trusted: npt.NDArray[np.bool_]
    """weight > 0."""
    all_trusted: bool
    outline_x: FloatArray
    outline_y: FloatArray
    seg_dx: FloatArray
    seg_dy: FloatArray
    """Each outline segment's (point to the next) extent."""
    seg_length2: FloatArray
    """Each outline segment's squared length (at least 1e-18)."""


def prepared_view(outline: FloatArray, weight: FloatArray, base2cam: FloatArray,
                  scale_px: float) -> PreparedView:
    """A view with what every misfit of it needs computed once."""
    ends = np.roll(outline, -1, axis=0)
    d = ends - outline
    trusted = weight > 0
    return PreparedView(outline, weight, base2cam, scale_px,
                        np.ascontiguousarray(base2cam[:3, :3].T), trusted, bool(trusted.all()),
                        np.ascontiguousarray(outline[:, 0]), np.ascontiguousarray(outline[:, 1]),
                        np.ascontiguousarray(d[:, 0]), np.ascontiguousarray(d[:, 1]),
                        np.maximum((d * d).sum(axis=1), 1e-18))


def box_corners(p: FloatArray, table_z_mm: float) -> FloatArray:
    """(B, 8, 3) corners of boxes ``p`` (B, 6: x, y, yaw, length, width, height)."""
    c, s = np.cos(p[:, 2:3]), np.sin(p[:, 2:3])
    local = _CORNERS[None] * p[:, None, 3:6]
    lx, ly = local[..., 0], local[..., 1]
    out: FloatArray = np.stack([p[:, 0:1] + c * lx - s * ly, p[:, 1:2] + s * lx + c * ly,
                                table_z_mm + local[..., 2]], axis=-1)
    return out


def cylinder_points(q: FloatArray, table_z_mm: float) -> FloatArray:
    """(B, 48, 3) points round the bottom and top of upright cylinders ``q`` (B, 4: x, y,
    radius, height)."""
    ring = _CIRCLE[None] * q[:, None, 2:3] + q[:, None, 0:2]
    bottom = np.broadcast_to(table_z_mm, ring.shape[:2])
    top = np.broadcast_to(table_z_mm + q[:, 3:4], ring.shape[:2])
    out: FloatArray = np.concatenate([np.concatenate([ring, bottom[..., None]], axis=2),
                                      np.concatenate([ring, top[..., None]], axis=2)], axis=1)
    return out


def _hulls(u: FloatArray, v: FloatArray) -> IntArray:
    """(B, H) indices of each row's convex hull's corners (OpenCV's, from float32), a
    shorter hull padded with its last corner."""
    img: npt.NDArray[np.float32] = np.empty((*u.shape, 2), dtype=np.float32)
    img[..., 0] = u
    img[..., 1] = v
    first = _hull(img[0])
    if len(img) == 1:
        return first[None]
    # A Jacobian's steps mostly move no point as float32 sees it: the same points, the
    # same hull.
    same = (img == img[0]).all(axis=(1, 2))
    each = [first if alike else _hull(img[k]) for k, alike in enumerate(same)]
    out = np.empty((len(each), max(len(h) for h in each)), dtype=np.intp)
    for row, hull in zip(out, each, strict=True):
        row[:len(hull)] = hull
        row[len(hull):] = hull[-1]
    return out


def _hull(points: npt.NDArray[np.float32]) -> IntArray:
    """Indices of the convex hull's corners of (P, 2) points, in OpenCV's order."""
    return np.asarray(cv2.convexHull(points, returnPoints=False), dtype=np.intp).ravel()


def _following(size: int) -> IntArray:
    """0..size-1, each index's next round a closed polygon."""
    out = _NEXT.get(size)
    if out is None:
        out = _NEXT[size] = np.roll(np.arange(size), -1)
    return out


_NEXT: dict[int, IntArray] = {}


def _to_segments(rx: FloatArray, ry: FloatArray, dx: FloatArray, dy: FloatArray,
                 length2: FloatArray) -> FloatArray:
    """Squared distances from points to segments, given each point's offset from each
    segment's start (rx, ry: ..., points, segments) and the segments' extents (d) and
    squared lengths (..., 1, segments)."""
    t = rx * dx
    t += ry * dy
    t /= length2
    np.maximum(t, 0.0, out=t)
    np.minimum(t, 1.0, out=t)
    gx = t * dx
    np.subtract(rx, gx, out=gx)
    t *= dy
    np.subtract(ry, t, out=t)
    gx *= gx
    t *= t
    gx += t
    return gx


def _resampled(hx: FloatArray, hy: FloatArray, ex: FloatArray, ey: FloatArray, count: int
               ) -> tuple[FloatArray, FloatArray]:
    """``count`` points evenly along each row's closed polygon (B, H; e: each side's
    extent), as ``np.interp`` places them (the same arithmetic: the slope times the way
    along the side, plus its start)."""
    batch, size = hx.shape
    arc = np.zeros((batch, size + 1))
    np.cumsum(np.hypot(ex, ey), axis=1, out=arc[:, 1:])
    at = _STEPS[count] * (arc[:, -1:] / count)
    # The side each sample is on: the last one starting at or before it (sides of no
    # length are passed over, as np.interp's search does).
    j = (arc[:, None, 1:size] <= at[:, :, None]).sum(axis=2)
    j += np.arange(0, batch * size, size)[:, None]
    span = arc[:, 1:] - arc[:, :-1]
    span += span == 0  # never taken (only a polygon of no length has one): kept finite
    a0 = arc[:, :-1].ravel()[j]
    off = at - a0
    x0, y0 = hx.ravel()[j], hy.ravel()[j]
    px = (ex / span).ravel()[j]
    px *= off
    px += x0
    py = (ey / span).ravel()[j]
    py *= off
    py += y0
    exact = a0 == at
    if exact.any():
        px[exact] = x0[exact]
        py[exact] = y0[exact]
    return px, py


_STEPS = {HULL_POINTS: np.arange(HULL_POINTS, dtype=np.float64)[None, :]}


def misfit(corners: FloatArray, views: Sequence[PreparedView]
           ) -> tuple[FloatArray, FloatArray]:
    """How far each view's outline is from the outline (convex hull) of each convex
    thing with these ``corners`` (B, P, 3; mm, base frame): residuals (B, M; px) and
    their weights (B, M; 0: untrusted), per view its outline points' then the hull's."""
    return _misfit(corners, views, True)


def residuals(corners: FloatArray, views: Sequence[PreparedView]) -> FloatArray:
    """``misfit``'s residuals alone."""
    return _misfit(corners, views, False)[0]


def _misfit(corners: FloatArray, views: Sequence[PreparedView], weighted: bool
            ) -> tuple[FloatArray, FloatArray]:
    """``misfit``; its weights only if ``weighted`` (else the residuals twice)."""
    out, weights = [], []
    batch = corners.shape[0]
    rows = np.arange(batch)[:, None]
    for v in views:
        cam = corners @ v.rotation_t + v.base2cam[:3, 3]
        z = np.maximum(cam[..., 2], 1.0)  # a corner behind the camera: no fit (kept finite)
        u, w = cam[..., 0] / z, cam[..., 1] / z
        # Which corners make the outline, from float32 (OpenCV's); the outline itself in
        # float64, so that the fit's small steps are not lost to rounding.
        index = _hulls(u, w)
        hx, hy = u[rows, index], w[rows, index]
        following = _following(index.shape[1])
        ex, ey = hx[:, following] - hx, hy[:, following] - hy
        ex3, ey3 = ex[:, None, :], ey[:, None, :]
        rx = v.outline_x[:, None] - hx[:, None, :]
        ry = v.outline_y[:, None] - hy[:, None, :]
        length2 = ex * ex
        length2 += ey * ey
        np.maximum(length2, 1e-18, out=length2)
        to_hull = np.sqrt(_to_segments(rx, ry, ex3, ey3, length2[:, None, :]).min(axis=2))
        if v.all_trusted:
            out.append(to_hull * v.scale_px)
        else:
            # Where the outline is a neighbour's, the thing may go on behind the
            # neighbour: the box must reach the outline there (no point of it outside
            # the box), but may reach beyond it; the box's outline there says nothing.
            cross = ex3 * ry - ey3 * rx
            turn = (hx * hy[:, following] - hx[:, following] * hy).sum(axis=1)
            outside = ((cross * turn[:, None, None]) < 0).any(axis=2)
            out.append(to_hull * np.where(v.trusted, 1.0, outside) * v.scale_px)
        px, py = _resampled(hx, hy, ex, ey, HULL_POINTS)
        squared = _to_segments(px[:, :, None] - v.outline_x, py[:, :, None] - v.outline_y,
                               v.seg_dx, v.seg_dy, v.seg_length2)
        to_outline = np.sqrt(squared.min(axis=2))
        # A weight of 1 everywhere multiplies nothing: it is left out (the same bits).
        near_weight = (np.ones_like(to_outline) if v.all_trusted
                       else v.weight[squared.argmin(axis=2)])
        out.append(to_outline * v.scale_px if v.all_trusted
                   else to_outline * near_weight * v.scale_px)
        if weighted:
            weights += [np.broadcast_to(v.weight, (batch, v.weight.size)), near_weight]
    res = np.concatenate(out, axis=1)
    if not weighted:
        return res, res
    return res, np.concatenate(weights, axis=1)


class FiniteDifferences:
    """``least_squares``' residuals and Jacobian of ``batch`` (B, n parameter vectors ->
    B, m residuals): the Jacobian by the forward differences scipy's '2-point' scheme
    takes (its steps, turned back at a bound), all evaluated in one batch.

    Most of a fit's steps are taken, and scipy then asks for the Jacobian there: the
    residuals at a point are measured together with its Jacobian's steps (one batch),
    and the Jacobian is the kept differences (each row of a batch is measured as it
    would be alone, to the bit)."""

    def __init__(self, batch: Callable[[FloatArray], FloatArray],
                 lower: Sequence[float], upper: Sequence[float]) -> None:
        self.batch = batch
        self.lower = np.asarray(lower, dtype=np.float64)
        self.upper = np.asarray(upper, dtype=np.float64)
        self._x: FloatArray | None = None
        self._jacobian: FloatArray | None = None

    def residuals(self, x: FloatArray) -> FloatArray:
        """The residuals at ``x`` (its Jacobian, which scipy asks next, kept)."""
        steps, dx = self._steps(x)
        both = self.batch(np.vstack([x[None], steps]))
        self._x, self._jacobian = x.copy(), self._differences(both, dx)
        out: FloatArray = both[0]
        return out

    def jacobian(self, x: FloatArray) -> FloatArray:
        """(m, n) forward differences at ``x``."""
        if self._jacobian is not None and self._x is not None and np.array_equal(self._x, x):
            return self._jacobian
        steps, dx = self._steps(x)
        return self._differences(self.batch(np.vstack([x[None], steps])), dx)

    def _steps(self, x: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The points a step off ``x`` in each parameter (n, n), and each step as it is
        represented (n,)."""
        n = x.size
        sign = (x >= 0).astype(float) * 2 - 1
        h = _STEP * sign * np.maximum(1.0, np.abs(x))
        h = self._within_bounds(x, h)
        steps = np.repeat(x[None], n, axis=0)
        diagonal = np.arange(n)
        steps[diagonal, diagonal] += h
        return steps, steps[diagonal, diagonal] - x

    @staticmethod
    def _differences(both: FloatArray, dx: FloatArray) -> FloatArray:
        """(m, n) differences from the residuals at a point and at its steps (1 + n, m)."""
        transposed: FloatArray = (both[1:] - both[0]) / dx[:, None]
        out: FloatArray = transposed.T
        return out

    def _within_bounds(self, x: FloatArray, h: FloatArray) -> FloatArray:
        """``h`` turned back (or shortened) where a step would cross a bound, as scipy
        does for a one-sided scheme."""
        lower_dist, upper_dist = x - self.lower, self.upper - x
        stepped = x + h
        violated = (stepped < self.lower) | (stepped > self.upper)
        fitting = np.abs(h) <= np.maximum(lower_dist, upper_dist)
        if not violated.any() and fitting.all():
            return h
        h = h.copy()
        h[violated & fitting] *= -1
        forward = (upper_dist >= lower_dist) & ~fitting
        h[forward] = upper_dist[forward]
        backward = (upper_dist < lower_dist) & ~fitting
        h[backward] = -lower_dist[backward]
        return h
