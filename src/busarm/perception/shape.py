"""Is it a block? A thing's shape and size judged from its outlines (busarm.perception.measure).

A block is a cube of ``CUBE_SIDES_MM``. Anything else in a block's colour (a cup, a coaster,
a pen, a box taller than a block) is not one: never picked, never reported. ``judge``
fits the outlines four ways (any box; a cube; a box taller and one flatter than a cube, on
the same square) and says:

- ``"not a block"`` when no box fits the outline closely (curved: a cup, a disc), the
  footprint is not square (a bar), the size is not a block's, or the height is clearly
  not the footprint's side (the cube fits clearly worse than the box that is found);
- ``"cube"`` when the cube fits and both the taller and the flatter box fit clearly worse
  (the views show the height);
- ``"unsure"`` otherwise: seen from above, a tall box's top and a cube's look alike. Look
  again from another pose and judge both views together before touching it;
- ``"hidden"`` when a neighbour hides part of its outline (touching blocks in a row, say)
  and what shows is straight-edged: how far it goes on behind the neighbour no picture
  says, so its size and height are not measured (it is taken as a block of the size the
  locator was given, as before there was this).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import VisionError
from busarm.perception.measure import (
    BoxFit,
    CylinderFit,
    FloatArray,
    OutlineView,
    TablePixels,
    fit_box,
    fit_cylinder,
    prepare_views,
    table_pixels,
    thing_outline,
)
from busarm.vision.calibration import CameraIntrinsics
from busarm.vision.calibration.core import inverse_of
from busarm.vision.color import Detection

__all__ = [
    "COMPARED_TOLERANCE",
    "CUBE_SIDES_MM",
    "DECISIVE_PX",
    "FIT_MAX_PX",
    "FLAT",
    "HEIGHT_TOLERANCE",
    "MIN_TRUSTED",
    "ROUNDER_PX",
    "ROUND_FROM_PX",
    "SIDE_GROW",
    "SIDE_HUE",
    "SQUARE_MIN",
    "TALL",
    "WHOLE_SHARE",
    "OutlineCover",
    "Shape",
    "Verdict",
    "cube_silhouettes",
    "cubes_explain",
    "judge",
    "judge_blobs",
    "nearest_other_mm",
]

CUBE_SIDES_MM = (17.0, 48.0)
"""A block's side (busarm's blocks are 20-45 mm; measuring costs a little either way)."""
FIT_MAX_PX = 1.5
"""A box's outline is this close (RMS px) to a box-shaped thing's at worst."""
ROUND_FROM_PX = 0.45
"""A box that fits worse than this (RMS px) is compared with an upright cylinder."""
ROUNDER_PX = 0.2
"""A cylinder that fits this much better than any box makes the thing round."""
SQUARE_MIN = 0.8
"""A block's footprint: its shorter side at least this share of its longer."""
HEIGHT_TOLERANCE = (0.55, 0.2)
"""A block's height is its side within this share: as one picture measures it (the
height is the least sure of its sizes: seen from above it hardly shows, and a camera's
pose known to a fraction of a degree moves it most: a disc or a box twice a block's
height is told at once, the rest is left unsure), and as two do. A box taller than a
block is 1.4 times its side or more."""
DECISIVE_PX = 0.3
"""One fit is clearly better than another when this much closer (RMS px)."""
TALL, FLAT = 1.45, 0.6
"""The heights (times the side) the views must rule out to call a thing a cube."""
COMPARED_TOLERANCE = 1e-4
"""The taller and flatter boxes' fits end when a step changes them less than this share
(the free and cube fits: scipy's 1e-8): a comparison at 0.3 px needs no finer."""
WHOLE_SHARE = 0.97
"""An outline this much its own (not bordering another thing) shows the whole thing."""
MIN_TRUSTED = 0.6
"""A thing is judged only if this share of its outline is its own (not bordering another
thing); one hidden more by its neighbours is "hidden" (in a crowd of blocks)."""
SIDE_HUE = 12
"""A side in shade keeps its colour's hue within this (OpenCV hue, 0..179)."""
SIDE_GROW = 0.5
"""A blob is grown by the shaded pixels next to it up to this share of its size (its
sides, lit from elsewhere, may be too dark for its colour) to make the thing's outline."""

Verdict = Literal["cube", "unsure", "not a block", "hidden"]


def nearest_other_mm(size_mm: float) -> float:
    """How near another block's centre can stand to a block ``size_mm`` wide (half its
    side and half the smallest block's, less 2 mm): a sighting nearer is that block
    seen in part (a large block's picture split in two)."""
    return (size_mm + CUBE_SIDES_MM[0]) / 2 - 2.0


@dataclass(frozen=True)
class Shape:
    """What a thing's outlines say: the verdict, why, and the fits behind it."""

    verdict: Verdict
    why: str
    side_mm: float
    """The cube's side that fits best (a block's size)."""
    box: BoxFit
    """The best box of any shape."""
    cube: BoxFit
    """The best cube."""
    views: tuple[OutlineView, ...]
    crowd: bool = False
    """Whether touching blocks could look so (irregular, not square, too big): a round
    thing, or one of the wrong height, is no crowd of blocks."""
    cylinder: CylinderFit | None = None
    """The upright cylinder that fits a round thing."""

    @property
    def xy_mm(self) -> tuple[float, float]:
        """Where the thing stands (its cylinder's centre if it is round)."""
        if self.cylinder is not None:
            return (self.cylinder.x_mm, self.cylinder.y_mm)
        return (self.box.x_mm, self.box.y_mm)

    @property
    def reach_mm(self) -> float:
        """How far the thing reaches from ``xy_mm`` on the table."""
        if self.cylinder is not None:
            return self.cylinder.diameter_mm / 2
        return float(np.hypot(self.box.length_mm, self.box.width_mm)) / 2

    def __repr__(self) -> str:
        return f"Shape({self.verdict}: {self.why})"


def judge(views: Sequence[OutlineView], intrinsics: CameraIntrinsics, table_z_mm: float,
          guess: tuple[float, float, float, float]) -> Shape:
    """The verdict on one thing seen in ``views`` (see the module docstring); ``guess``:
    (x mm, y mm, yaw deg, side mm). VisionError if an outline cannot be used."""
    pairs = prepare_views(views, intrinsics)  # undistorted once for every fit below
    box = fit_box(pairs, intrinsics, table_z_mm, guess)
    start = (box.x_mm, box.y_mm, box.yaw_deg, (box.length_mm + box.width_mm) / 2)
    cube = fit_box(pairs, intrinsics, table_z_mm, start, aspect=1.0)
    if cube.fit_px < box.fit_px:
        # A cube is a box: the free fit stopped in a worse minimum (a small cube seen
        # from the side fits a flat slab nearly as well). Started from the cube, it does
        # at least as well.
        again = fit_box(pairs, intrinsics, table_z_mm,
                        (cube.x_mm, cube.y_mm, cube.yaw_deg, cube.length_mm))
        box = again if again.fit_px < cube.fit_px else cube

    def shape(verdict: Verdict, why: str, crowd: bool = False) -> Shape:
        return Shape(verdict, why, cube.length_mm, box, cube, tuple(views), crowd)

    side0 = (box.length_mm + box.width_mm) / 2
    footprint = f"{box.length_mm:.0f} x {box.width_mm:.0f} mm"
    if box.fit_px > ROUND_FROM_PX:  # a round thing first: it is no crowd of blocks
        round_ = fit_cylinder(pairs, intrinsics, table_z_mm, (box.x_mm, box.y_mm, side0))
        if round_.fit_px < box.fit_px - ROUNDER_PX:
            return replace(shape("not a block", f"round: {round_!r} fits better than any "
                                                f"box ({box.fit_px:.2f} px)"), cylinder=round_)
    if box.fit_px > FIT_MAX_PX:
        return shape("not a block", f"irregular: no box's outline is within "
                                    f"{FIT_MAX_PX:g} px of it ({box.fit_px:.1f} px)", True)
    if any(v.trusted_share < WHOLE_SHARE for v in views):
        # What shows may go on behind the neighbour: only a cube that cannot explain
        # what shows (of a block's size) rules it out.
        lo, hi = CUBE_SIDES_MM
        if cube.fit_px > FIT_MAX_PX or not lo <= cube.length_mm <= hi:
            return shape("not a block", f"no block's cube explains what shows of it "
                                        f"(partly hidden: {cube!r})", True)
        return shape("hidden", "partly hidden by a neighbour: not measured")
    if box.width_mm < SQUARE_MIN * box.length_mm:
        return shape("not a block", f"not square: {footprint}", True)
    lo, hi = CUBE_SIDES_MM
    if not lo <= cube.length_mm <= hi:
        return shape("not a block", f"{cube.length_mm:.0f} mm: blocks are {lo:g}-{hi:g} mm",
                     cube.length_mm > hi)
    side = (box.length_mm + box.width_mm) / 2
    tolerance = HEIGHT_TOLERANCE[0 if len(views) == 1 else 1]
    if abs(box.height_mm / side - 1.0) > tolerance and cube.fit_px - box.fit_px > DECISIVE_PX:
        return shape("not a block", f"{box.height_mm:.0f} mm tall on {footprint}")
    # A cube when both the taller and the flatter box fit clearly worse: the flatter one
    # is fitted only when the taller one does. They start once, from the free fit's yaw
    # (a poor fit is what they are expected to be), and end at COMPARED_TOLERANCE: the
    # same verdicts at half the cost (docs/profiles/pick-bench.md; the property tests).
    if all(_worse_by(fit_box(pairs, intrinsics, table_z_mm, start, aspect=aspect,
                             turned_retry=False, tolerance=COMPARED_TOLERANCE), cube)
           > DECISIVE_PX for aspect in (TALL, FLAT)):
        return shape("cube", f"a {cube.length_mm:.1f} mm cube")
    return shape("unsure", f"a {cube.length_mm:.0f} mm cube or a box of another height: "
                           f"to be seen from another pose")


def _worse_by(other: BoxFit, cube: BoxFit) -> float:
    """How much worse (px) ``other`` fits than ``cube`` in the view that tells them
    apart best."""
    return max(o - c for o, c in zip(other.view_fit_px, cube.view_fit_px, strict=True))


def judge_blobs(image: npt.NDArray[np.uint8], blobs: Sequence[Detection],
                targets: Sequence[tuple[Detection, tuple[float, float, float, float]]],
                intrinsics: CameraIntrinsics, cam2base: FloatArray, table_z_mm: float
                ) -> list[Shape | None]:
    """Each target blob's verdict from this one picture (its outline grown by its shaded
    sides; ``blobs``: every colour blob in the picture, none of which is a side); None
    where the picture cuts the thing or its outline cannot be used. Each target comes
    with a guess (x mm, y mm, yaw deg, side mm)."""
    if not targets:
        return []
    pixels = table_pixels(image)
    contours = [d.contour_px.reshape(-1, 1, 2) for d in blobs]
    something = pixels.something
    cv2.drawContours(something, contours, -1, 255, cv2.FILLED)  # every thing, blocks too
    in_blobs = np.zeros_like(something)
    cv2.drawContours(in_blobs, contours, -1, 255, cv2.FILLED)
    below = _below_camera_px(intrinsics, cam2base, table_z_mm)
    out: list[Shape | None] = []
    for blob, guess in targets:
        grow = max(2, int(SIDE_GROW * float(np.sqrt(blob.area_px))))
        outline = thing_outline(blob.contour_px, _sides_of(blob, pixels, in_blobs), below, grow)
        if outline is None:
            out.append(None)
            continue
        view = OutlineView(outline, cam2base, _own_outline(outline, something))
        try:
            shape = judge([view], intrinsics, table_z_mm, guess)
        except VisionError:
            out.append(None)
            continue
        if view.trusted_share < MIN_TRUSTED and shape.verdict != "hidden":
            # Mostly hidden by its neighbours: in a crowd, whatever the fit says.
            shape = replace(shape, verdict="hidden",
                            why="mostly hidden by its neighbours: not measured")
        out.append(shape)
    return out


def _sides_of(blob: Detection, pixels: TablePixels, in_blobs: npt.NDArray[np.uint8]
              ) -> npt.NDArray[np.uint8]:
    """The pixels that may be ``blob``'s thing's sides: in shade, or of its own hue (a
    side too dark for the colour's range), and in no colour blob."""
    u, v = (round(c) for c in blob.centroid_px)
    h, w = pixels.hue.shape
    patch = pixels.hue[max(0, v - 2):min(h, v + 3), max(0, u - 2):min(w, u + 3)]
    hue = int(np.median(patch)) if patch.size else 0
    off = np.abs(pixels.hue.astype(np.int16) - hue)
    same_hue = np.minimum(off, 180 - off) <= SIDE_HUE
    sides = pixels.shaded | np.where(same_hue, pixels.coloured, 0).astype(np.uint8)
    out: npt.NDArray[np.uint8] = sides & ~in_blobs
    return out


def _own_outline(outline: npt.NDArray[np.int32], not_table: npt.NDArray[np.uint8]
                 ) -> npt.NDArray[np.bool_]:
    """Per outline point: True unless something else that is not the table (a
    neighbour) lies right next to it there."""
    h, w = not_table.shape[:2]
    x0, y0 = np.maximum(outline.min(axis=0) - 4, 0)
    x1, y1 = np.minimum(outline.max(axis=0) + 5, (w, h))
    window = not_table[y0:y1, x0:x1].copy()
    cv2.drawContours(window, [(outline - (x0, y0)).reshape(-1, 1, 2)], -1, 0, cv2.FILLED)
    near = cv2.dilate(window, np.ones((5, 5), np.uint8))
    local = outline - (x0, y0)
    return np.asarray(near[local[:, 1], local[:, 0]] == 0)


def _below_camera_px(intrinsics: CameraIntrinsics, cam2base: FloatArray, table_z_mm: float
                     ) -> tuple[float, float]:
    """Where the table point right below the camera is in the picture (undistorted
    pinhole: only its direction from a blob matters; it may lie outside the picture)."""
    origin = cam2base[:3, 3]
    base2cam = np.linalg.inv(cam2base)
    p = base2cam[:3, :3] @ np.array([origin[0], origin[1], table_z_mm]) + base2cam[:3, 3]
    z = max(float(p[2]), 1e-6)
    return (intrinsics.fx * p[0] / z + intrinsics.cx, intrinsics.fy * p[1] / z + intrinsics.cy)


def cubes_explain(outline_px: npt.ArrayLike, cubes: Sequence[tuple[float, float, float, float]],
                  intrinsics: CameraIntrinsics, cam2base: FloatArray, table_z_mm: float
                  ) -> float:
    """How well cubes (x mm, y mm, yaw deg, side mm) standing on the table explain a
    thing's outline: the intersection over union of the area inside the outline and the
    cubes' silhouettes (1: exactly; several touching blocks split from one blob are
    checked so, that a thing of another shape is not taken for them)."""
    hulls = cube_silhouettes(cubes, intrinsics, cam2base, table_z_mm)
    return OutlineCover(outline_px, hulls).share(range(len(hulls)))


def cube_silhouettes(cubes: Sequence[tuple[float, float, float, float]],
                     intrinsics: CameraIntrinsics, cam2base: FloatArray, table_z_mm: float
                     ) -> list[npt.NDArray[np.int32] | None]:
    """Each cube's (x mm, y mm, yaw deg, side mm, on the table) silhouette in the picture:
    its corners' convex hull (K x 2 px, rounded); None for one not wholly in front of the
    camera."""
    base2cam = inverse_of(cam2base)
    su = np.array([-1.0, -1.0, -1.0, -1.0, 1.0, 1.0, 1.0, 1.0])
    sv = np.array([-1.0, -1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0])
    p_cam = []
    for x, y, yaw_deg, side in cubes:
        a = np.radians(yaw_deg)
        cos, sin = np.cos(a), np.sin(a)
        # The corners (bottom and top of each), in the order and arithmetic of a loop
        # over them: each number is the same to the bit.
        corners = np.empty((8, 3))
        corners[:, 0] = x + side / 2 * (su * cos - sv * sin)
        corners[:, 1] = y + side / 2 * (su * sin + sv * cos)
        corners[:, 2] = (table_z_mm, table_z_mm + side) * 4
        p_cam.append(corners @ base2cam[:3, :3].T + base2cam[:3, 3])
    if not p_cam:
        return []
    # All corners projected at once (the model works point by point); if one is behind
    # the camera, cube by cube.
    px: list[FloatArray | None] = []
    try:
        flat = intrinsics.pixels_from_camera_points(np.concatenate(p_cam))
        px += [flat[8 * i:8 * i + 8] for i in range(len(p_cam))]
    except VisionError:
        for one in p_cam:
            try:
                px.append(intrinsics.pixels_from_camera_points(one))
            except VisionError:
                px.append(None)
    return [None if p is None else np.asarray(
        cv2.convexHull(np.round(p).astype(np.int32)).reshape(-1, 2), np.int32) for p in px]


class OutlineCover:
    """How well sets of silhouettes explain one outline (``cubes_explain``): the outline
    and each silhouette drawn once, on one canvas holding all, for any set of them."""

    def __init__(self, outline_px: npt.ArrayLike,
                 hulls: Sequence[npt.NDArray[np.int32] | None]) -> None:
        outline = np.asarray(outline_px, np.int32).reshape(-1, 2)
        every = np.vstack([outline, *(h for h in hulls if h is not None)])
        x0, y0 = every.min(axis=0) - 1
        x1, y1 = every.max(axis=0) + 2
        size = (int(y1 - y0), int(x1 - x0))
        # Filled polygons with whole-pixel corners move with the canvas pixel for pixel:
        # the counts are those of a canvas fitted to each set.
        self._thing = np.zeros(size, np.uint8)
        cv2.drawContours(self._thing, [(outline - (x0, y0)).reshape(-1, 1, 2)], -1, 1,
                         cv2.FILLED)
        self._models: list[npt.NDArray[np.uint8] | None] = []
        for hull in hulls:
            model = None
            if hull is not None:
                model = np.zeros(size, np.uint8)
                cv2.fillConvexPoly(model, (hull - (x0, y0)).astype(np.int32), 1)
            self._models.append(model)

    def share(self, which: Iterable[int]) -> float:
        """The intersection over union of the outline's area and the silhouettes
        ``which`` (indices); 0 if one of them is not wholly in front of the camera."""
        model = np.zeros_like(self._thing)
        for i in which:
            one = self._models[i]
            if one is None:
                return 0.0
            model |= one
        union = int(np.count_nonzero(self._thing | model))
        return float(np.count_nonzero(self._thing & model)) / union if union else 0.0
