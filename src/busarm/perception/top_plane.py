"""Colour blobs cast onto the blocks' top plane, all of a picture's at once.

``BlockLocator`` needs, per blob, its centroid's ray met with the plane of the blocks'
top faces (how large one block looks there), its rectangle's edge cast onto it (the
blob's yaw on the table) and its outline cast onto it (how many blocks it holds, and
how much of their side faces). ``cast_blobs`` casts all of that for every blob of a
picture in one undistortion call (its fixed cost was most of the time per blob), and
``outline_grids`` reads every outline as a grid of touching blocks in array operations
rather than a loop over the blobs.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeVar

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import VisionError
from busarm.perception.split import Grid
from busarm.vision.calibration import CameraIntrinsics
from busarm.vision.color import Detection
from busarm.vision.localize import table_points_from_pixels

__all__ = [
    "BlobCast",
    "all_or_each",
    "cast_blobs",
    "edge_points_px",
    "outline_grids",
    "straight_outline",
    "yaws_from_edges",
]

T = TypeVar("T")
R = TypeVar("R")
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class BlobCast:
    """One blob cast onto the top plane; None where its rays miss the plane."""

    centre: FloatArray | None
    """The centroid's ray met with the plane (x, y, z mm)."""
    yaw_deg: float | None
    """The rectangle's edge direction cast onto the plane, modulo 90 (-45..45 deg)."""
    outline: FloatArray | None
    """The straight outline (``straight_outline``) on the plane (K x 2: x, y mm)."""


def straight_outline(d: Detection) -> npt.NDArray[np.int32]:
    """Blob ``d``'s outline with straight edges (a pixel outline is a staircase, whose
    steps run along the picture's axes, not the blocks')."""
    return np.asarray(cv2.approxPolyDP(d.contour_px.reshape(-1, 1, 2), 1.5, True)
                      .reshape(-1, 2), np.int32)


def edge_points_px(d: Detection) -> FloatArray:
    """The two ends (2 x 2 px) of the blob's rectangle's longer side through its centre,
    along its yaw: cast onto the table, they give the blob's yaw there."""
    a = math.radians(d.yaw_deg)
    half = max(d.rect_size_px) / 2
    cu, cv = d.rect_center_px
    return np.array([(cu - half * math.cos(a), cv - half * math.sin(a)),
                     (cu + half * math.cos(a), cv + half * math.sin(a))])


def yaws_from_edges(table: FloatArray) -> list[float]:
    """Per pair of rows of ``table`` (cast edge ends, 2N x 2+), its direction modulo 90
    (a square's yaw is known modulo 90 deg)."""
    # Plain floats (the same differences as numpy's): a handful of numbers per blob.
    rows = table[:, :2].tolist()
    return [(math.degrees(math.atan2(y1 - y0, x1 - x0)) + 45.0) % 90.0 - 45.0
            for (x0, y0), (x1, y1) in zip(rows[::2], rows[1::2], strict=False)]


def cast_blobs(detections: Sequence[Detection], intrinsics: CameraIntrinsics,
               cam2base: FloatArray, top_z_mm: float) -> list[BlobCast]:
    """Every blob's centroid, edge and outline cast onto the plane z = ``top_z_mm``:
    all in one call, or, if a ray misses the plane, blob by blob and part by part (a
    part that still misses is None; the other parts and blobs are cast all the same)."""
    parts = [(np.array([d.centroid_px], np.float64), edge_points_px(d),
              straight_outline(d).astype(np.float64)) for d in detections]

    def cast(points: list[FloatArray]) -> list[FloatArray]:
        flat = table_points_from_pixels(np.concatenate(points), intrinsics, cam2base, top_z_mm)
        ends = list(itertools.accumulate(len(p) for p in points))
        return [flat[a:b] for a, b in zip([0, *ends[:-1]], ends, strict=True)]

    def blob(three: list[tuple[FloatArray, FloatArray, FloatArray]]) -> list[BlobCast]:
        pieces = iter(cast([p for one in three for p in one]))
        return [_blob_cast(next(pieces), next(pieces), next(pieces)) for _ in three]

    def alone(three: tuple[FloatArray, FloatArray, FloatArray]) -> BlobCast:
        centre, edge, outline = (all_or_each(cast, [p])[0] for p in three)
        return _blob_cast(centre, edge, outline)

    wholes = all_or_each(blob, parts)
    # A blob one of whose parts misses the plane: its parts one by one.
    return [alone(d) if whole is None else whole
            for d, whole in zip(parts, wholes, strict=True)]


def _blob_cast(centre: FloatArray | None, edge: FloatArray | None,
               outline: FloatArray | None) -> BlobCast:
    return BlobCast(None if centre is None else centre[0],
                    None if edge is None else yaws_from_edges(edge)[0],
                    None if outline is None else outline[:, :2])


def outline_grids(outlines: Sequence[FloatArray], size_mm: float, table_z_mm: float,
                  camera_mm: FloatArray) -> list[Grid]:
    """Each outline cast onto the top plane read as a grid of touching blocks (``Grid``),
    all at once.

    Cast onto that plane, one block covers its top face plus the side faces the camera
    sees; n in a row cover n - 1 sides more. Lit from the side, a block's dark side
    faces may be too dark for its colour, and the blob is then its top faces only. So
    half the sides is assumed to count the blocks along each of the blocks' axes (the
    outline's main edge direction, ``split.edge_yaw_deg``: right either way while the
    sides add less than a block), and how much of the sides the blob has is read from
    what its length leaves over.
    """
    if not outlines:
        return []
    size = size_mm
    pts = np.concatenate(outlines)
    sizes = [len(o) for o in outlines]
    lengths = np.array(sizes)
    starts = np.array([0, *itertools.accumulate(sizes[:-1])])
    # Each point's next one around its own outline.
    following = np.arange(1, len(pts) + 1)
    following[starts + lengths - 1] = starts
    edges = pts[following] - pts
    length = np.hypot(edges[:, 0], edges[:, 1])
    angle4 = 4.0 * np.arctan2(edges[:, 1], edges[:, 0])
    mean = np.arctan2(np.add.reduceat(length * np.sin(angle4), starts),
                      np.add.reduceat(length * np.cos(angle4), starts))
    yaw = (np.degrees(mean / 4.0) + 45.0) % 90.0 - 45.0
    a = np.radians(yaw)
    cos, sin = np.cos(a), np.sin(a)
    # Along the axes: u = (cos, sin), v = (-sin, cos).
    c, s = np.repeat(cos, lengths), np.repeat(sin, lengths)
    u = pts[:, 0] * c + pts[:, 1] * s
    v = pts[:, 1] * c - pts[:, 0] * s
    lo_blob = _pairs(np.minimum.reduceat(u, starts), np.minimum.reduceat(v, starts))
    hi_blob = _pairs(np.maximum.reduceat(u, starts), np.maximum.reduceat(v, starts))
    mid = (lo_blob + hi_blob) / 2
    centre = _pairs(mid[:, 0] * cos - mid[:, 1] * sin, mid[:, 0] * sin + mid[:, 1] * cos)
    # How far a cube there reaches along the axes, cast from the camera onto its top
    # plane (``split.cast_cube_extent``): its top's half side, and a bottom corner (+-
    # half a side) seen from the camera, which lands further out on the top plane.
    half = size / 2
    scale = (camera_mm[2] - (table_z_mm + size)) / (camera_mm[2] - table_z_mm)
    towards = camera_mm[:2] - centre
    seen = _pairs(towards[:, 0] * cos + towards[:, 1] * sin,
                  towards[:, 1] * cos - towards[:, 0] * sin) * (1.0 - scale)
    lo = np.minimum(-half, seen - half * scale)
    hi = np.maximum(half, seen + half * scale)
    sides = (hi - lo) - size
    extent = hi_blob - lo_blob
    counts = np.maximum(1, np.rint((extent - sides / 2) / size)).astype(int)
    shown = ((extent - counts * size) / np.maximum(sides, 1e-6)).clip(0.0, 1.0)
    first = lo_blob + size / 2 + shown * (-lo - size / 2)  # the first top face's centre
    axes = np.empty((len(outlines), 2, 2))
    axes[:, 0, 0], axes[:, 0, 1], axes[:, 1, 0], axes[:, 1, 1] = cos, sin, -sin, cos
    # The sides reach out from a top face on the camera's side only: lo or hi is the
    # top's half side, and their sum is how far the sides reach, signed.
    reach = lo + hi
    return [Grid(y, axes[i], (n_u, n_v), first[i], shown[i], (lo_blob[i], hi_blob[i]),
                 reach[i])
            for i, (y, (n_u, n_v)) in enumerate(zip(yaw.tolist(), counts.tolist(), strict=True))]


def _pairs(a: FloatArray, b: FloatArray) -> FloatArray:
    """(N, 2): ``a`` and ``b`` side by side (``np.stack(..., axis=1)`` without its
    checks: these arrays are a handful of numbers)."""
    out = np.empty((len(a), 2))
    out[:, 0], out[:, 1] = a, b
    return out


def all_or_each(solve: Callable[[list[T]], list[R]], items: Sequence[T]) -> list[R | None]:
    """``solve`` for all items at once, or, if that raises VisionError, for each alone
    (None for an item that still fails), so that one bad blob does not spoil the rest."""
    if not items:
        return []
    try:
        return list(solve(list(items)))
    except VisionError:
        pass
    out: list[R | None] = []
    for item in items:
        try:
            out.append(solve([item])[0])
        except VisionError:
            out.append(None)
    return out
