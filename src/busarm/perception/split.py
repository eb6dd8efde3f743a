"""Touching blocks of one colour in one blob: where each block's top face is.

The blob is redrawn on the blocks' top plane, along their axes (``RESOLUTION_MM`` a
pixel), where each block is a square. The side faces the camera sees, cast onto that
plane, lie on the camera's side of each top face; the part of them the blob holds is
taken off (an erosion along the cast direction), leaving the top faces. Then squares are
placed greedily: each where a block's top fits inside and covers the most of what no
square covers yet (ties: the furthest out), then centred on what it covers; until what is
left is less than half a block. Rows, 2 x 2 groups and staggered clusters alike.
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import VisionError
from busarm.vision.calibration import CameraIntrinsics
from busarm.vision.calibration.core import inverse_of

__all__ = [
    "FIT_SLACK_MM",
    "MAX_BLOCKS",
    "MIN_COVER",
    "RESOLUTION_MM",
    "SIDE_SHARES",
    "FloatArray",
    "Grid",
    "TopPlane",
    "cast_cube_extent",
    "edge_yaw_deg",
    "top_faces_mm",
]


FloatArray = npt.NDArray[np.float64]

RESOLUTION_MM = 0.5
"""The top plane's pixel, redrawn."""
FIT_SLACK_MM = 2.0
"""A block's top fits where a square this much smaller a side lies inside the blob (the
outline's pixels and the cast are a little rough)."""
MIN_COVER = 0.5
"""A square is placed only where it covers this much of a block's top not yet covered."""
MAX_BLOCKS = 16
SIDE_SHARES = (0.0, 0.5, 1.0)
"""The shares of the side faces the blob may hold, tried along each axis."""
"""At most this many blocks in one blob."""


@dataclass(frozen=True)
class TopPlane:
    """The blocks' top plane around a blob, along the blocks' ``axes`` (rows: unit
    vectors in the base frame): ``origin`` (u, v mm) is the corner pixel's place."""

    axes: FloatArray
    origin: FloatArray
    shape: tuple[int, int]

    def to_base(self, uv_px: FloatArray) -> FloatArray:
        """(N, 2) pixels (column, row) of the redrawn plane -> (N, 2) base x, y mm."""
        uv = self.origin + uv_px * RESOLUTION_MM
        return uv @ self.axes


def top_faces_mm(contour_px: npt.NDArray[np.int32], intrinsics: CameraIntrinsics,
                 cam2base: FloatArray, top_z_mm: float, size_mm: float, axes: FloatArray,
                 extent_uv_mm: tuple[FloatArray, FloatArray], cast_uv_mm: FloatArray
                 ) -> list[tuple[float, float]]:
    """The centres (base x, y mm) of the blocks' top faces in the blob outlined by
    ``contour_px``. ``extent_uv_mm``: the outline's (lowest, highest) u, v on the top
    plane; ``cast_uv_mm``: how far the side faces the blob holds reach out from a top face
    towards the camera, along u and v. Empty if no block's top fits in the blob."""
    lo, hi = extent_uv_mm
    plane = TopPlane(axes, lo - 2.0, (math.ceil((hi[1] - lo[1] + 4.0) / RESOLUTION_MM),
                                      math.ceil((hi[0] - lo[0] + 4.0) / RESOLUTION_MM)))
    blob = _redraw(contour_px, intrinsics, cam2base, top_z_mm, plane)
    # How much of the sides the blob holds (lit or dark) is found by trying: the right
    # share leaves the blob a union of whole squares (none cut short, nothing over).
    tops = [_without_sides(blob, np.asarray(share) * cast_uv_mm)
            for share in itertools.product(*(SIDE_SHARES if abs(c) > FIT_SLACK_MM else (0.0,)
                                             for c in cast_uv_mm))]
    return [(float(x), float(y)) for x, y in plane.to_base(_best_squares(tops, size_mm))]


def _best_squares(tops: Sequence[npt.NDArray[np.uint8]], size_mm: float) -> FloatArray:
    """The greedy squares (``_place_squares``) of whichever of ``tops`` they fit best,
    the first of them on a tie. Those that could fit best are tried first, and one that
    cannot beat the best so far (or tie it from an earlier place) is given up as soon as
    that is sure (``_fit_bound``): the same choice as trying every one in order."""
    area = max(3, round(size_mm / RESOLUTION_MM)) ** 2
    bounds = [_fit_bound(0.0, cv2.countNonZero(t), 0.0, area) for t in tops]
    best: tuple[float, int, FloatArray] | None = None
    for i in sorted(range(len(tops)), key=lambda i: (-bounds[i], i)):
        ties = best is not None and i < best[1]
        if best is not None and _cannot_beat(bounds[i], best[0], ties):
            continue
        placed = _place_squares(tops[i], size_mm, None if best is None else (best[0], ties))
        if placed is not None and (best is None or placed[1] > best[0]
                                   or (placed[1] == best[0] and ties)):
            best = (placed[1], i, placed[0])
    if best is None:
        raise ValueError("no tops to place squares on")
    return best[2]


def _redraw(contour_px: npt.NDArray[np.int32], intrinsics: CameraIntrinsics,
            cam2base: FloatArray, top_z_mm: float, plane: TopPlane) -> npt.NDArray[np.uint8]:
    """The blob as a mask on the top plane (1 inside)."""
    x0, y0, w, h = cv2.boundingRect(contour_px.reshape(-1, 1, 2))
    mask = np.zeros((h + 2, w + 2), np.uint8)
    cv2.drawContours(mask, [contour_px.reshape(-1, 1, 2) - (x0 - 1, y0 - 1)], -1, 1, -1)
    rows, cols = plane.shape
    base2cam = inverse_of(cam2base)
    r, t = base2cam[:3, :3], base2cam[:3, 3]
    # Pixel (column, row) of the plane is at origin + (column, row) * RESOLUTION_MM along
    # the axes: its camera point is projective-affine in them (p0 + column * dc + row *
    # dr), so the camera model maps the whole plane in one pass.
    p0 = r @ np.array([*(plane.origin @ plane.axes), top_z_mm]) + t
    dc, dr = (r[:, :2] @ (axis * RESOLUTION_MM) for axis in plane.axes)
    try:
        map_u, map_v = intrinsics.plane_pixel_maps(np.column_stack([dc, dr, p0]), cols, rows,
                                                   (x0 - 1.0, y0 - 1.0))
    except VisionError:
        raise VisionError("the blob's top plane reaches behind the camera") from None
    return np.asarray(cv2.remap(mask, map_u, map_v, cv2.INTER_NEAREST,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=0), np.uint8)


def _without_sides(blob: npt.NDArray[np.uint8], cast_uv_mm: FloatArray
                   ) -> npt.NDArray[np.uint8]:
    """The blob less the side faces it holds: a place stays if the blob reaches from it
    along the whole cast (a top face's place does; a side's runs off the blob's edge)."""
    du, dv = (round(c / RESOLUTION_MM) for c in cast_uv_mm)
    if du == 0 and dv == 0:
        return blob
    kernel, anchor = _line_kernel(du, dv)
    return np.asarray(cv2.erode(blob, kernel, anchor=anchor, borderType=cv2.BORDER_CONSTANT,
                                borderValue=0), np.uint8)


@functools.lru_cache(maxsize=1024)
def _line_kernel(du: int, dv: int) -> tuple[npt.NDArray[np.uint8], tuple[int, int]]:
    """The erosion's kernel for a cast of (du, dv) pixels: a line from its anchor (made
    once: the same few casts come again and again). Read only."""
    kernel = np.zeros((abs(dv) + 1, abs(du) + 1), np.uint8)
    anchor = (0 if du >= 0 else -du, 0 if dv >= 0 else -dv)
    cv2.line(kernel, anchor, (anchor[0] + du, anchor[1] + dv), 1, 1)
    kernel.flags.writeable = False
    return kernel, anchor


def _fit_bound(covered: float, left: float, empty: float, area: int) -> float:
    """The best fit ``_place_squares`` can still reach (to the bit: whole numbers divided
    as there) with ``covered``, ``left`` and ``empty`` pixels so far (squares of ``area``
    pixels): each further square holds h <= min(area, what is left) and adds 5 h - 2 area
    to the fit's numerator, so m more add 3 m area at most while they fit in what is
    left, 5 left - 2 m area beyond."""
    rest = int(left)
    low, high = rest // area, -(-rest // area)
    gain = max(3 * low * area, 5 * rest - 2 * high * area)
    return (int(covered) - 2 * rest - 2 * int(empty) + gain) / area


def _cannot_beat(bound: float, fit: float, ties: bool) -> bool:
    """Whether a fit of at most ``bound`` loses to ``fit`` (``ties``: equalling it wins)."""
    return bound < fit or (bound == fit and not ties)


def _place_squares(tops: npt.NDArray[np.uint8], size_mm: float,
                   beat: tuple[float, bool] | None = None) -> tuple[FloatArray, float] | None:
    """Greedy squares on the top faces (a 0/1 mask; see the module docstring): their
    centres (N x 2, pixels: column, row) and how well they explain the tops, in blocks:
    what they cover, less twice what is left over and twice what they cover of nothing
    (a square put on a side face's strip, or a top cut short by too much taken off).
    ``beat``: (a fit, whether equalling it is enough): None, as soon as that is sure,
    if the fit cannot beat it."""
    side = max(3, round(size_mm / RESOLUTION_MM))
    area = side * side
    left = np.array(tops, np.uint8)
    # What is left's pixel count and row and column sums, kept up to date as squares
    # take windows off it (whole numbers: its middle is the same as from its moments).
    count, sum_r, sum_c = _sums(left)
    fits, crop = _fit_places(left, side)
    y, x = crop[0].start, crop[1].start
    width = fits.shape[1]
    centres: list[tuple[float, float]] = []
    covered = empty = 0.0
    for _ in range(MAX_BLOCKS if fits.size else 0):
        # No square covers more than is left: too little left is the end, unsummed.
        if count < MIN_COVER * area:
            break
        if beat is not None and _cannot_beat(_fit_bound(covered, count, empty, area), *beat):
            return None
        cover = _box_sums(left[crop], side)
        np.multiply(cover, fits, out=cover)
        best = float(cover.max())
        if best < MIN_COVER * side * side:
            break
        rows, cols = np.divmod(np.flatnonzero(cover >= best - 0.01 * side * side), width)
        rows += y
        cols += x
        # Of the (nearly) best places, the one furthest from what is left's middle: a
        # row's end block rather than a square straddling two.
        mass_r, mass_c = sum_r / count, sum_c / count
        k = int(np.argmax((rows - mass_r) ** 2 + (cols - mass_c) ** 2))
        centre, (r0, c0, window, w) = _centred(left, int(rows[k]), int(cols[k]), side)
        centres.append(centre)
        held = w[0]
        if held:
            count -= held
            sum_r -= w[1] + r0 * held
            sum_c -= w[2] + c0 * held
        covered += held
        empty += area - held
        window[:] = 0
    fit = (covered - 2.0 * count - 2.0 * empty) / (side * side)
    rc = np.array(centres, dtype=np.float64).reshape(-1, 2)
    return rc[:, ::-1].copy(), fit


def _fit_places(tops: npt.NDArray[np.uint8], side: int
                ) -> tuple[npt.NDArray[np.float32], tuple[slice, slice]]:
    """Where a block's top fits on ``tops`` (an inner square wholly on them: its box sum
    is full), as a 0/1 factor (box sums of a 0/1 mask are whole numbers, exact in
    float32), on the part of the plane a square's cover is looked at (the bounding box
    of those places grown by a square's reach: the box sums there are those of the
    whole plane); and that part."""
    inner = max(1, side - 2 * round(FIT_SLACK_MM / RESOLUTION_MM))
    full = _box_sums(tops, inner) > inner * inner - 0.5
    x, y, w, h = cv2.boundingRect(full.view(np.uint8))
    before, after = side // 2, side - 1 - side // 2  # the box about a pixel (its anchor)
    crop = (slice(max(y - before, 0), y + h + after), slice(max(x - before, 0), x + w + after))
    if not w:  # fits nowhere
        crop = (slice(0, 0), slice(0, 0))
    return full[crop].astype(np.float32), crop


def _box_sums(mask: npt.NDArray[np.uint8], side: int) -> npt.NDArray[np.float32]:
    """Per pixel, the sum of ``mask`` over the side x side square about it (outside the
    mask counts 0)."""
    return np.asarray(cv2.boxFilter(mask, cv2.CV_32F, (side, side), normalize=False,
                                    borderType=cv2.BORDER_CONSTANT), np.float32)


def _window(mask: npt.NDArray[np.uint8], r0: int, c0: int, side: int
            ) -> tuple[int, int, npt.NDArray[np.uint8]]:
    """The side x side window of ``mask`` from (r0, c0), cut to the mask: its first row
    and column, and the window (a view)."""
    ra, ca = max(r0, 0), max(c0, 0)
    return ra, ca, mask[ra:max(r0 + side, 0), ca:max(c0 + side, 0)]


_Window = tuple[int, int, npt.NDArray[np.uint8], tuple[float, float, float]]
"""A side x side window of a mask cut to it: its first row and column, the window (a
view) and its sums (``_sums``)."""


def _sums_at(mask: npt.NDArray[np.uint8], r0: int, c0: int, side: int) -> _Window:
    """The window of ``mask`` from (r0, c0) (``_window``) and its sums."""
    ra, ca, window = _window(mask, r0, c0, side)
    return ra, ca, window, (_sums(window) if window.size else (0.0, 0.0, 0.0))


def _centred(left: npt.NDArray[np.uint8], row: int, col: int, side: int
             ) -> tuple[tuple[float, float], _Window]:
    """The square at (row, col) moved to the middle of what it covers, twice (a place
    found on a tie sits a little off its block), and its window there (``_Window``)."""
    cr, cc = float(row), float(col)
    half = side // 2
    at = _sums_at(left, row - half, col - half, side)
    for _ in range(2):
        r0, c0, _, (m00, m01, m10) = at
        if m00 == 0:
            break
        # Half a square's shift at most: it stays on the block it was placed on.
        shift_r, shift_c = m01 / m00 + r0 - cr, m10 / m00 + c0 - cc
        if max(abs(shift_r), abs(shift_c)) < 0.25:
            break
        cr += min(max(shift_r, -side / 4), side / 4)
        cc += min(max(shift_c, -side / 4), side / 4)
        # The window where the square now is (the last turn's: the one it is placed in).
        at = _sums_at(left, round(cr) - half, round(cc) - half, side)
    return (cr, cc), at


_RAMP = np.stack([np.ones(1024), np.arange(1024.0)])
_RAMP.flags.writeable = False
"""Ones and 0, 1, 2, ...: a mask's sums as two matrix products."""


def _sums(mask: npt.NDArray[np.float32] | npt.NDArray[np.uint8]) -> tuple[float, float, float]:
    """A 0/1 mask's pixel count and the sums of its pixels' rows and of their columns
    (OpenCV's moments m00, m01, m10). Whole numbers, so exact in float64 however the
    products add them up: the same as from ``cv2.moments``, at a fraction of its cost."""
    rows, cols = mask.shape
    ramp = _RAMP if max(rows, cols) <= _RAMP.shape[1] else np.stack(
        [np.ones(max(rows, cols)), np.arange(float(max(rows, cols)))])
    s = ramp[:, :rows] @ mask.astype(np.float64) @ ramp[:, :cols].T
    return float(s[0, 0]), float(s[1, 0]), float(s[0, 1])


@dataclass(frozen=True)
class Grid:
    """A blob's outline on the blocks' top plane read as ``counts`` touching blocks
    along its ``axes`` (rows: unit vectors, base frame): the first top face's centre
    (``first``, in the axes' coordinates) and how much of the side faces the camera sees
    along each axis is in the blob (``shown``, 0..1)."""

    yaw_deg: float
    axes: FloatArray
    counts: tuple[int, int]
    first: FloatArray
    shown: FloatArray
    extent_uv_mm: tuple[FloatArray, FloatArray]
    """The outline's (lowest, highest) place along the axes."""
    cast_uv_mm: FloatArray
    """How far the side faces the camera sees reach out from a top face, along the axes."""

    def centre_mm(self, i: int, j: int, size_mm: float) -> tuple[float, float]:
        """The centre (base frame) of the top face at place (i, j) of the grid."""
        u, v = self.first + np.array([i * size_mm, j * size_mm])
        x, y = u * self.axes[0] + v * self.axes[1]
        return float(x), float(y)


def edge_yaw_deg(points: FloatArray) -> float:
    """The direction (deg, -45..45) most of an outline's length runs along, modulo 90:
    a row of cubes' sides, whatever the row's own shape."""
    edges = np.roll(points, -1, axis=0) - points
    length = np.hypot(edges[:, 0], edges[:, 1])
    angle4 = 4.0 * np.arctan2(edges[:, 1], edges[:, 0])
    mean = math.atan2(float(np.sum(length * np.sin(angle4))),
                      float(np.sum(length * np.cos(angle4))))
    return (math.degrees(mean / 4.0) + 45.0) % 90.0 - 45.0


def cast_cube_extent(centre: FloatArray, axes: FloatArray, yaw_deg: float, size: float,
                      table_z: float, camera: FloatArray) -> tuple[FloatArray, FloatArray]:
    """How far a cube at ``centre`` (turned ``yaw_deg``) reaches along each of ``axes``,
    cast from the ``camera`` onto its top plane: (lowest, highest) per axis, from the
    centre (mm)."""
    a = math.radians(yaw_deg)
    u, v = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    top = table_z + size
    corners = [centre + su * size / 2 * u + sv * size / 2 * v for su in (-1, 1)
               for sv in (-1, 1)]
    cast = list(corners)
    for c in corners:  # a bottom corner, seen from the camera, lands further out on top
        scale = (camera[2] - top) / (camera[2] - table_z)
        cast.append(camera[:2] + (c - camera[:2]) * scale)
    rel = (np.array(cast) - centre) @ axes.T
    return rel.min(axis=0), rel.max(axis=0)
