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

import itertools
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import VisionError
from busarm.vision.calibration import CameraIntrinsics

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
    best: tuple[float, FloatArray] | None = None
    for share in itertools.product(*(SIDE_SHARES if abs(c) > FIT_SLACK_MM else (0.0,)
                                     for c in cast_uv_mm)):
        tops = _without_sides(blob, np.asarray(share) * cast_uv_mm)
        centres, fit = _place_squares(tops, size_mm)
        if best is None or fit > best[0]:
            best = (fit, centres)
    assert best is not None
    return [(float(x), float(y)) for x, y in plane.to_base(best[1])]


def _redraw(contour_px: npt.NDArray[np.int32], intrinsics: CameraIntrinsics,
            cam2base: FloatArray, top_z_mm: float, plane: TopPlane) -> npt.NDArray[np.uint8]:
    """The blob as a mask on the top plane (1 inside)."""
    x0, y0, w, h = cv2.boundingRect(contour_px.reshape(-1, 1, 2))
    mask = np.zeros((h + 2, w + 2), np.uint8)
    cv2.drawContours(mask, [contour_px.reshape(-1, 1, 2) - (x0 - 1, y0 - 1)], -1, 1, -1)
    rows, cols = plane.shape
    base2cam = np.linalg.inv(cam2base)
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
    kernel = np.zeros((abs(dv) + 1, abs(du) + 1), np.uint8)
    anchor = (0 if du >= 0 else -du, 0 if dv >= 0 else -dv)
    cv2.line(kernel, anchor, (anchor[0] + du, anchor[1] + dv), 1, 1)
    return np.asarray(cv2.erode(blob, kernel, anchor=anchor, borderType=cv2.BORDER_CONSTANT,
                                borderValue=0), np.uint8)


def _place_squares(tops: npt.NDArray[np.uint8], size_mm: float) -> tuple[FloatArray, float]:
    """Greedy squares on the top faces (a 0/1 mask; see the module docstring): their
    centres (N x 2, pixels: column, row) and how well they explain the tops, in blocks:
    what they cover, less twice what is left over and twice what they cover of nothing
    (a square put on a side face's strip, or a top cut short by too much taken off)."""
    side = max(3, round(size_mm / RESOLUTION_MM))
    inner = max(1, side - 2 * round(FIT_SLACK_MM / RESOLUTION_MM))
    left = np.array(tops, np.uint8)
    # Where a top fits (an inner square wholly on the tops: its box sum is full), as a
    # 0/1 factor; box sums of a 0/1 mask are whole numbers, exact in float32.
    fits = (_box_sums(left, inner) > inner * inner - 0.5).astype(np.float32)
    # What is left's pixel count and row and column sums, kept up to date as squares
    # take windows off it (whole numbers: its middle is the same as from its moments).
    m = cv2.moments(left, binaryImage=True)
    count, sum_r, sum_c = m["m00"], m["m01"], m["m10"]
    width = left.shape[1]
    centres: list[tuple[float, float]] = []
    covered = empty = 0.0
    for _ in range(MAX_BLOCKS):
        cover = _box_sums(left, side)
        np.multiply(cover, fits, out=cover)
        best = float(cover.max())
        if best < MIN_COVER * side * side:
            break
        rows, cols = np.divmod(np.flatnonzero(cover >= best - 0.01 * side * side), width)
        # Of the (nearly) best places, the one furthest from what is left's middle: a
        # row's end block rather than a square straddling two.
        mass_r, mass_c = sum_r / count, sum_c / count
        k = int(np.argmax((rows - mass_r) ** 2 + (cols - mass_c) ** 2))
        centre = _centred(left, int(rows[k]), int(cols[k]), side)
        centres.append(centre)
        r0, c0 = round(centre[0]) - side // 2, round(centre[1]) - side // 2
        r0, c0, window = _window(left, r0, c0, side)
        w = cv2.moments(window, binaryImage=True) if window.size else {"m00": 0.0}
        held = w["m00"]
        if held:
            count -= held
            sum_r -= w["m01"] + r0 * held
            sum_c -= w["m10"] + c0 * held
        covered += held
        empty += side * side - held
        window[:] = 0
    fit = (covered - 2.0 * count - 2.0 * empty) / (side * side)
    rc = np.array(centres, dtype=np.float64).reshape(-1, 2)
    return rc[:, ::-1].copy(), fit


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


def _centred(left: npt.NDArray[np.uint8], row: int, col: int, side: int
             ) -> tuple[float, float]:
    """The square at (row, col) moved to the middle of what it covers, twice (a place
    found on a tie sits a little off its block)."""
    cr, cc = float(row), float(col)
    for _ in range(2):
        r0, c0, window = _window(left, round(cr) - side // 2, round(cc) - side // 2, side)
        if window.size == 0 or not window.any():
            break
        mid_r, mid_c = _middle(window)
        # Half a square's shift at most: it stays on the block it was placed on.
        shift_r, shift_c = mid_r + r0 - cr, mid_c + c0 - cc
        if max(abs(shift_r), abs(shift_c)) < 0.25:
            break
        cr += min(max(shift_r, -side / 4), side / 4)
        cc += min(max(shift_c, -side / 4), side / 4)
    return cr, cc


def _middle(mask: npt.NDArray[np.float32] | npt.NDArray[np.uint8]) -> tuple[float, float]:
    """The mean (row, column) of a mask's nonzero pixels (some must be). From OpenCV's
    moments: their sums are whole numbers, so this is the same mean as numpy's, without
    listing the pixels."""
    m = cv2.moments(mask, binaryImage=True)
    return m["m01"] / m["m00"], m["m10"] / m["m00"]


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
