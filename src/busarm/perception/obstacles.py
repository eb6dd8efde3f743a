"""Things on the table that are not blocks (a cup, a pen, a coaster): where the wrist
camera sees them, cast onto the table, for the fingers and the pushes to keep off.

The table is what most of the picture's unsaturated pixels show; its brightness is their
median. A pixel much darker than that (darker than a shadow: a lamp's share of the light
is a third at most) or much brighter and unsaturated (a white thing under the same light)
is something else. Blobs of such pixels, less the blocks and trays (their outlines, from
where they are known to be), the arm's own black parts, what lies on its base and white
floor tape (a strip of the tape's width all along, flat: busarm.vision.tape_colour; a
thing standing on it stays), are cast onto the table plane. A thing standing up casts
further than its foot (its top is higher), so the cast covers at least what it stands
on: its convex hull is kept off.

How tall a thing is, no picture says; but it lies inside the cone from each camera that
saw it whole through its cast (its visual hull), and, standing upright, in the column on
what all its casts share. A point in space that one of them does not hold is not in the
thing: a finger may pass over a pen (cast beyond the pen's cast by the camera, it is
higher than the pen) that would block it were the pen as tall as a cup.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError, VisionError
from busarm.vision.calibration import CameraIntrinsics
from busarm.vision.floor_line import each_floor_line
from busarm.vision.localize import table_points_from_pixels
from busarm.vision.tape_colour import flat_tape_mask

__all__ = [
    "ARM_DARK",
    "ARM_DARK_V",
    "BASE_KEEP_OUT_MM",
    "BLOCK_MARGIN_PX",
    "BRIGHT",
    "DARK",
    "MIN_AREA_PX",
    "PIECE_GAP_MM",
    "TABLE_SATURATION",
    "TAPE_MIN_M",
    "WHITE_SATURATION",
    "FloatArray",
    "Obstacle",
    "View",
    "cast_obstacle",
    "find_obstacles",
    "near_convex",
    "refine",
]


FloatArray = npt.NDArray[np.float64]

TABLE_SATURATION = 40
"""Pixels under this saturation (0-255) are the table's candidates."""
DARK = 0.55
"""A pixel under this share of the table's brightness is something dark (a shadow keeps
two thirds of the light or more)."""
BRIGHT = 1.12
"""An unsaturated pixel over this share of the table's brightness is something white."""
WHITE_SATURATION = 60
MIN_AREA_PX = 120.0
"""Smaller blobs are specks (or a block's edge)."""
ARM_DARK = 0.18
"""A blob whose median brightness is under this share of the table's is black: the arm's
own fingers and links in the picture (0.08-0.13 of the table); a brown or grey cup, its
shaded side dark, is 0.24 or lighter."""
ARM_DARK_V = 34.0
"""Nor darker than this (0..255) on a dark floor: the arm's black parts are as black
there (``ARM_DARK`` of a light table); a brown or grey cup's shaded side is 45 or more."""
BLOCK_MARGIN_PX = 5
"""The blocks' own blobs, grown this much, are not obstacles (their dark edges)."""
BASE_KEEP_OUT_MM = 80.0
"""What lies this close to the arm's axis is the arm's own base."""
PIECE_GAP_MM = 10.0
TAPE_MIN_M = 0.1
"""White tape is a strip of its width this long at least (a lit edge of the gripper is
shorter)."""
"""Casts this close are pieces of one thing (its lit top and a shaded side, say)."""


@dataclass(frozen=True)
class View:
    """A thing seen whole from one place: its cast on the table at ``table_z_mm`` (N x 2,
    mm, base frame, convex) and the camera's centre then (x, y, z mm, base frame)."""

    cast: FloatArray
    camera_mm: FloatArray
    table_z_mm: float

    def holds(self, points_mm: FloatArray, margin_mm: float) -> npt.NDArray[np.bool_]:
        """Which points (N x 3, mm) lie within ``margin_mm`` of the cone from the camera
        through the cast (the points cast onto the table from the camera fall in it)."""
        cam = self.camera_mm
        height = cam[2] - points_mm[:, 2]
        ahead = height > 1e-6  # points level with the camera or above it are not in it
        t = (cam[2] - self.table_z_mm) / np.where(ahead, height, 1.0)
        cast = cam[:2] + (points_mm[:, :2] - cam[:2]) * t[:, None]
        return np.asarray(ahead & near_convex(self.cast, cast, margin_mm))


@dataclass(frozen=True)
class Obstacle:
    """Something that is not a block: its outline cast onto the table (N x 2, mm, base
    frame, convex, in order); ``whole``: not cut by the picture's edge; ``views``: each
    whole sighting, whose cones hold the thing."""

    corners: FloatArray
    whole: bool = True
    views: tuple[View, ...] = ()

    @property
    def centre_mm(self) -> tuple[float, float]:
        c = self.corners.mean(axis=0)
        return float(c[0]), float(c[1])

    def reaches(self, points_mm: FloatArray, margin_mm: float) -> bool:
        """Whether the thing may be within ``margin_mm`` of any of ``points_mm`` (N x 3,
        mm, base frame): whether ``holds`` any of them."""
        return bool(self.holds(points_mm, margin_mm).any())

    def holds(self, points_mm: FloatArray, margin_mm: float) -> npt.NDArray[np.bool_]:
        """Which of ``points_mm`` (N x 3, mm, base frame) the thing may be within
        ``margin_mm`` of: those held by the column standing on ``corners`` (a thing
        stands upright: no wider up than at its foot) and by every view's cone."""
        points = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
        held = near_convex(self.corners, points[:, :2], margin_mm)
        for view in self.views:
            held &= view.holds(points, margin_mm)
        return held


def near_convex(corners: FloatArray, points: FloatArray, margin_mm: float
                ) -> npt.NDArray[np.bool_]:
    """Which ``points`` (N x 2) lie inside the convex polygon ``corners`` (M x 2, in
    order, either way round) or within ``margin_mm`` of each of its edges' lines."""
    poly = np.asarray(corners, dtype=np.float64)
    ahead: FloatArray = np.roll(poly, -1, axis=0)
    edges = ahead - poly
    area = float(np.sum(poly[:, 0] * ahead[:, 1] - ahead[:, 0] * poly[:, 1]))
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) * (1.0 if area > 0 else -1.0)
    lengths = np.maximum(np.linalg.norm(normals, axis=1), 1e-12)
    outward = np.einsum("nmk,mk->nm", points[:, None, :] - poly[None, :, :], normals) / lengths
    return np.asarray(np.all(outward <= margin_mm, axis=1))


def find_obstacles(image: npt.NDArray[np.uint8], known: Sequence[npt.NDArray[np.int32]],
                   intrinsics: CameraIntrinsics, cam2base: FloatArray, table_z_mm: float
                   ) -> list[Obstacle]:
    """Things in ``image`` (RGB) that are neither the table nor ``known`` (the outlines
    of blocks and trays in the picture, N x 2 pixels), cast onto the table. Pieces of one
    thing (a lit top, a shaded side) cast close together are one obstacle."""
    found = _thing_blobs(image, known)
    if found is None:
        return []
    mask, val, table = found
    if np.any((mask > 0) & (val > BRIGHT * table)):
        floor = ~_arm_at_bottom(val < DARK * table)
        tape = _white_tape(image, floor, intrinsics, cam2base, table_z_mm)
        mask = mask & ~(tape & (val > BRIGHT * table)).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    h, w = image.shape[:2]
    out = []
    for c in contours:
        pts = c.reshape(-1, 2)
        if cv2.contourArea(c) < MIN_AREA_PX or pts[:, 1].max() >= h - 2:
            continue  # a speck, or the arm's own fingers at the picture's bottom
        inside = np.zeros(mask.shape, np.uint8)
        cv2.drawContours(inside, [c], -1, 1, -1)
        if float(np.median(val[(inside > 0) & (mask > 0)])) < max(ARM_DARK * table,
                                                                  ARM_DARK_V):
            continue  # black: the arm itself
        whole = not (pts[:, 0].min() <= 0 or pts[:, 1].min() <= 0 or pts[:, 0].max() >= w - 1)
        thing = cast_obstacle(np.asarray(pts, np.int32), intrinsics, cam2base, table_z_mm,
                              whole=whole)
        if thing is not None:
            out.append(thing)
    camera = np.asarray(cam2base[:3, 3], dtype=np.float64)
    return [replace(o, views=(View(o.corners, camera, table_z_mm),)) if o.whole else o
            for o in _merged(out)]


def cast_obstacle(outline_px: npt.NDArray[np.int32], intrinsics: CameraIntrinsics,
                  cam2base: FloatArray, table_z_mm: float, *, whole: bool = True
                  ) -> Obstacle | None:
    """A thing whose outline in the picture is ``outline_px``, cast onto the table (seen
    from this camera, if ``whole``); None if it reaches above the horizon or is the arm's
    own base."""
    hull = cv2.convexHull(outline_px.reshape(-1, 1, 2)).reshape(-1, 2).astype(np.float64)
    try:
        cast = table_points_from_pixels(hull, intrinsics, cam2base, table_z_mm)[:, :2]
    except VisionError:
        return None  # part of it above the horizon: no thing on the table
    if math.hypot(*cast.mean(axis=0)) < BASE_KEEP_OUT_MM:
        return None  # the arm's own base
    corners = _hull_mm(cast)
    camera = np.asarray(cam2base[:3, 3], dtype=np.float64)
    return Obstacle(corners, whole, (View(corners, camera, table_z_mm),) if whole else ())


def refine(seen: Sequence[Obstacle], new: Sequence[Obstacle]) -> list[Obstacle]:
    """What is known of the things after another picture: a thing standing up, seen
    whole from two places, stands inside both its casts (each stretches away from its
    camera): where they overlap is kept; the rest as seen."""
    out: list[Obstacle] = []
    used: set[int] = set()
    for old in seen:
        same = [i for i, n in enumerate(new) if old.whole and n.whole
                and _overlap(old.corners, n.corners) > 0.0]
        if not same:
            out.append(old)
            continue
        used.update(same)
        other = _hull_mm(np.vstack([new[i].corners for i in same]))
        area, both = cv2.intersectConvexConvex(old.corners.astype(np.float32),
                                               other.astype(np.float32))
        kept = np.asarray(both, np.float64).reshape(-1, 2) if area > 1.0 else old.corners
        views = old.views + tuple(v for i in same for v in new[i].views)
        out.append(Obstacle(_hull_mm(kept), views=views))
    return out + [n for i, n in enumerate(new) if i not in used]


def _thing_blobs(image: npt.NDArray[np.uint8], known: Sequence[npt.NDArray[np.int32]]
                 ) -> tuple[npt.NDArray[np.uint8], FloatArray, float] | None:
    """The mask of pixels that are neither table nor block, the brightness, and the
    table's brightness; None if the picture shows little table."""
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    sat, val = hsv[..., 1], hsv[..., 2].astype(np.float64)
    plain = sat < TABLE_SATURATION
    if int(plain.sum()) < image.shape[0] * image.shape[1] // 4:
        return None  # no table to speak of in this picture
    table = float(np.median(val[plain]))
    mask = ((val < DARK * table) | ((val > BRIGHT * table) & (sat < WHITE_SATURATION)))
    mask_u8 = mask.astype(np.uint8)
    for outline in known:
        cv2.drawContours(mask_u8, [outline.reshape(-1, 1, 2)], -1, 0, -1)
        cv2.drawContours(mask_u8, [outline.reshape(-1, 1, 2)], -1, 0, 2 * BLOCK_MARGIN_PX)
    opened = cv2.morphologyEx(mask_u8, cv2.MORPH_OPEN, np.ones((3, 3), np.uint8))
    return np.asarray(opened, np.uint8), val, table


def _arm_at_bottom(dark: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """The dark blobs that reach the picture's bottom (the arm's own gripper), grown a
    little: H x W, True."""
    count, labels = cv2.connectedComponents(dark.astype(np.uint8), connectivity=8)
    bottom = np.unique(labels[-2:][labels[-2:] > 0])
    arm = np.isin(labels, bottom).astype(np.uint8)
    return np.asarray(cv2.dilate(arm, np.ones((9, 9), np.uint8)) > 0)


def _white_tape(image: npt.NDArray[np.uint8], floor: npt.NDArray[np.bool_],
                intrinsics: CameraIntrinsics, cam2base: FloatArray, table_z_mm: float
                ) -> npt.NDArray[np.bool_]:
    """The flat white tape on the table's plane in ``image`` (RGB; ``floor``: the pixels
    that may show it): H x W, True."""
    bgr = np.ascontiguousarray(image[..., ::-1])
    to_plane = np.array(cam2base, dtype=np.float64)
    to_plane[2, 3] -= table_z_mm
    to_plane[:3, 3] /= 1000.0
    out = np.zeros(image.shape[:2], bool)
    try:
        for line in each_floor_line(bgr, intrinsics, to_plane, "white", mask=floor,
                                    from_middle=True):
            if line.length_m >= TAPE_MIN_M:
                out |= flat_tape_mask(bgr, line, intrinsics, to_plane, floor)[0]
    except ConfigError:  # a camera below the plane or a picture of another size: no tape
        return out
    return out


def _merged(things: list[Obstacle]) -> list[Obstacle]:
    """Casts that overlap or nearly (``PIECE_GAP_MM``) merged into their hull."""
    out = list(things)
    merged = True
    while merged:
        merged = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                a, b = out[i], out[j]
                if _gap_mm(a.corners, b.corners) <= PIECE_GAP_MM:
                    out[i] = Obstacle(_hull_mm(np.vstack([a.corners, b.corners])),
                                      a.whole and b.whole)
                    del out[j]
                    merged = True
                    break
            if merged:
                break
    return out


def _overlap(a: FloatArray, b: FloatArray) -> float:
    area, _ = cv2.intersectConvexConvex(a.astype(np.float32), b.astype(np.float32))
    return float(area)


def _gap_mm(a: FloatArray, b: FloatArray) -> float:
    """How far apart two convex outlines are (0 if they overlap), about: the least
    distance from a corner of one to the other's outline."""
    if _overlap(a, b) > 0.0:
        return 0.0
    d = [abs(cv2.pointPolygonTest(poly.astype(np.float32).reshape(-1, 1, 2),
                                  (float(p[0]), float(p[1])), True))
         for poly, pts in ((a, b), (b, a)) for p in pts]
    return float(min(d))


def _hull_mm(points: FloatArray) -> FloatArray:
    hull = cv2.convexHull(points.astype(np.float32)).reshape(-1, 2)
    return np.asarray(hull, dtype=np.float64)
