"""Where the blocks are, in millimetres in the arm's base frame, from the wrist camera.

``BlockLocator`` ties the pieces together for one picture: colour blobs
(busarm.vision.color) -> each blob's yaw on the table (its oriented rectangle's edge,
cast onto the table) -> the block's position from its silhouette centroid
(busarm.vision.localize) with the camera pose = forward kinematics of the joints
*measured* when the picture was taken x the hand-eye calibration -> whether a grasp
reaches it. ``locate_averaged`` merges several pictures taken from the same pose.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TypeVar

import cv2
import numpy as np
import numpy.typing as npt

from busarm.arm.config import CAMERA_JOINT_INDEX
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, UnreachableError, VisionError
from busarm.perception.obstacles import Obstacle, find_obstacles
from busarm.perception.split import top_faces_mm
from busarm.units import check_range
from busarm.vision.calibration import CameraIntrinsics, HandEyeResult
from busarm.vision.color import ColorDetector, Detection
from busarm.vision.localize import (
    BlockLocation,
    average_locations,
    camera_to_base,
    locate_blocks,
    table_points_from_pixels,
)

__all__ = [
    "AREA_RANGE",
    "BIN_MARGIN_MM",
    "BIN_WALL_MM",
    "CAMERA_LINK",
    "CAMERA_LINK_NAME",
    "CUT_AREA_FRACTION",
    "MATCH_RADIUS_MM",
    "MAX_CAMERA_OFFSET_MM",
    "MAX_SPLIT",
    "NOT_BLOCK_COLORS",
    "SIDES_SHOWN",
    "SPLIT_MIN_AREA",
    "BlockLocator",
    "FloatArray",
    "Sighting",
    "link2base",
]


T = TypeVar("T")
R = TypeVar("R")
FloatArray = npt.NDArray[np.float64]

CAMERA_LINK = CAMERA_JOINT_INDEX
"""Index of the wrist-pitch link's frame in ``ArmKinematics.frames`` (DH frame 4)."""
CAMERA_LINK_NAME = "wrist_pitch"
MAX_CAMERA_OFFSET_MM = 300.0
NOT_BLOCK_COLORS = ("black", "white")
"""Colours the vendor's threshold file has for other jobs (lines, the table): never blocks."""
AREA_RANGE = (0.35, 3.5)
"""A blob counts as a block when its area is this many times the block's top face seen
from where it is: less is a glimpse or a speck, more is not a block (a table, an arm)."""
CUT_AREA_FRACTION = 0.25
"""A blob cut by the picture's edge needs only this fraction of the lower bound (part of a
block is out of the picture), so that a speck at the edge is still no block."""
SPLIT_MIN_AREA = 1.5
"""A blob is looked at for several touching blocks only if it is this many times one
block's top face (one block, top and sides, stays under it seen from the survey poses;
two side by side are twice the top at least)."""
MAX_SPLIT = 4
"""At most this many touching blocks along one side of a blob are split out of it."""
SIDES_SHOWN = 0.7
"""A single block's blob with less than this much of its visible side faces in it is
located by its top face's outline rather than by its whole silhouette."""
BIN_WALL_MM = 15.0
"""A tray's walls are this high at most (the twin's are 12 mm)."""
BIN_MARGIN_MM = 5.0
"""A tray is taken this much wider a side, not to see its rim's shadow as a thing."""
MATCH_RADIUS_MM = 20.0
"""Sightings of one block in several pictures are closer than this."""


@dataclass(frozen=True)
class Sighting:
    """A block seen in a picture: colour, where it is, and whether the arm reaches it.

    ``reachable``: a grasp at the block's centre height is within the arm's reach and
    limits (any pitch); ``top_down``: straight down works too; ``reason`` says why not.
    ``whole``: False if the blob is cut by the picture's edge, so that its location is
    only rough (look again, facing it).
    """

    color: str
    location: BlockLocation
    detection: Detection | None
    reachable: bool
    top_down: bool
    reason: str = ""
    detections: tuple[Detection, ...] = field(default=(), repr=False)
    whole: bool = True

    def to_dict(self) -> dict[str, object]:
        loc = self.location
        return {
            "color": self.color, "x_mm": round(loc.x_mm, 2), "y_mm": round(loc.y_mm, 2),
            "z_mm": round(loc.z_mm, 2), "yaw_deg": round(loc.yaw_deg, 2),
            "frames": loc.frames, "spread_max_mm": round(loc.spread_max_mm, 2),
            "reachable": self.reachable, "top_down": self.top_down, "reason": self.reason,
            "centroid_px": [round(v, 2) for v in loc.centroid_px], "whole": self.whole,
        }


def link2base(kin: ArmKinematics, joints_deg: Sequence[float]) -> FloatArray:
    """The camera link's frame (DH frame 4) in the base frame for measured joints (mm)."""
    return kin.frames(joints_deg)[CAMERA_LINK]


class BlockLocator:
    """Finds and locates blocks in wrist-camera pictures (see the module docstring)."""

    def __init__(
        self, kin: ArmKinematics, intrinsics: CameraIntrinsics, hand_eye: HandEyeResult,
        detector: ColorDetector, *, table_z_mm: float = 0.0, block_size_mm: float = 30.0,
    ) -> None:
        check_range("block_size_mm", block_size_mm, 5.0, 200.0, "mm")
        if not math.isfinite(table_z_mm):
            raise ConfigError(f"table_z_mm = {table_z_mm!r} must be finite")
        if hand_eye.link != CAMERA_LINK_NAME:
            raise ConfigError(f"the hand-eye calibration places the camera on the {hand_eye.link!r}"
                              f" link; the wrist camera rides the {CAMERA_LINK_NAME!r} link")
        reach = float(np.linalg.norm(hand_eye.cam2link[:3, 3]))
        if reach > MAX_CAMERA_OFFSET_MM:
            raise ConfigError(f"the hand-eye calibration puts the camera {reach:.0f} mm from the "
                              f"wrist; a wrist camera sits within {MAX_CAMERA_OFFSET_MM:g} mm")
        self.kin = kin
        self.intrinsics = intrinsics
        self.cam2link = hand_eye.cam2link
        self.detector = detector
        self.table_z_mm = float(table_z_mm)
        self.block_size_mm = float(block_size_mm)

    def cam2base(self, joints_deg: Sequence[float]) -> FloatArray:
        return camera_to_base(link2base(self.kin, joints_deg), self.cam2link)

    def _table_yaws(self, detections: Sequence[Detection], cam2base: FloatArray
                    ) -> list[float]:
        """Each blob's yaw on the table: its rectangle's edge direction cast onto the
        top-face plane (a square's yaw is known modulo 90 deg)."""
        pts = []
        for d in detections:
            a = math.radians(d.yaw_deg)
            half = max(d.rect_size_px) / 2
            cu, cv = d.rect_center_px
            pts += [(cu - half * math.cos(a), cv - half * math.sin(a)),
                    (cu + half * math.cos(a), cv + half * math.sin(a))]
        table = table_points_from_pixels(np.asarray(pts), self.intrinsics, cam2base,
                                         self.table_z_mm + self.block_size_mm)
        yaws = []
        for i in range(len(detections)):
            dx, dy = table[2 * i + 1, :2] - table[2 * i, :2]
            yaws.append((math.degrees(math.atan2(dy, dx)) + 45.0) % 90.0 - 45.0)
        return yaws

    def locate(self, image: npt.NDArray[np.uint8], joints_deg: Sequence[float]
               ) -> list[Sighting]:
        """Every block in ``image``, taken with the arm at the measured ``joints_deg``."""
        h, w = image.shape[:2]
        detections = [d for d in self.detector.detect(image) if d.color not in NOT_BLOCK_COLORS]
        cam2base = self.cam2base(joints_deg)
        if not detections:
            return []
        # Blocks of one colour that touch make one blob: such a blob is split into its
        # blocks by its size on the table, and each is located on its own.
        out: list[Sighting] = []
        single = []
        # Only a blob larger than one block's top face can be (is split, costly) is tried.
        centres = _all_or_each(lambda ds: list(table_points_from_pixels(
            np.array([d.centroid_px for d in ds]), self.intrinsics, cam2base,
            self.table_z_mm + self.block_size_mm)), detections)
        for d, centre in zip(detections, centres, strict=True):
            big = centre is not None and d.area_px > SPLIT_MIN_AREA * self._top_face_px(
                centre, cam2base)
            parts = self._split(d, cam2base) if big and not _touches_edge(d, w, h) else None
            if parts is None:
                single.append(d)
            else:
                out += [self._sighting(d.color, loc, d) for loc in parts]
        return out + self._locate_single(single, cam2base, w, h)

    def obstacles(self, image: npt.NDArray[np.uint8], joints_deg: Sequence[float],
                  bins: Sequence[tuple[float, float, float]] = (),
                  blocks: Sequence[Sighting] = ()) -> list[Obstacle]:
        """Things in ``image`` that are not blocks (``busarm.perception.obstacles``), cast onto
        the table; ``bins``: (x, y, side mm) of each tray, and ``blocks``: the blocks
        located in it, are not things (a block's side face in shade looks like no colour).
        """
        cam2base = self.cam2base(joints_deg)
        outlines = [d.contour_px for d in self.detector.detect(image)]
        boxes = [(b.location.x_mm, b.location.y_mm, self.block_size_mm, b.location.yaw_deg,
                  self.block_size_mm) for b in blocks]
        boxes += [(x, y, side + 2 * BIN_MARGIN_MM, 0.0, BIN_WALL_MM) for x, y, side in bins]
        for box in boxes:
            outline = self._box_outline_px(*box, cam2base)
            if outline is not None:
                outlines.append(outline)
        return find_obstacles(image, outlines, self.intrinsics, cam2base, self.table_z_mm)

    def _box_outline_px(self, x_mm: float, y_mm: float, side_mm: float, yaw_deg: float,
                        height_mm: float, cam2base: FloatArray) -> npt.NDArray[np.int32] | None:
        """The picture's outline of a square box standing on the table (its corners'
        hull); None if part of it is behind the camera."""
        a, half = math.radians(yaw_deg), side_mm / 2
        corners = [(x_mm + half * (su * math.cos(a) - sv * math.sin(a)),
                    y_mm + half * (su * math.sin(a) + sv * math.cos(a)), z)
                   for su in (-1, 1) for sv in (-1, 1)
                   for z in (self.table_z_mm, self.table_z_mm + height_mm)]
        base2cam = np.linalg.inv(cam2base)
        p_cam = np.array(corners) @ base2cam[:3, :3].T + base2cam[:3, 3]
        try:
            px = self.intrinsics.pixels_from_camera_points(p_cam)
        except VisionError:
            return None
        return np.asarray(cv2.convexHull(px.astype(np.float32)).reshape(-1, 2), np.int32)

    def _locate_single(self, detections: list[Detection], cam2base: FloatArray, w: int,
                       h: int) -> list[Sighting]:
        """Sightings of blobs that are one block each (or none: not block-sized)."""
        if not detections:
            return []
        # Yaw, then position, for all blobs at once (vectorised); a blob whose rays miss
        # the table is no block on it, and is left out.
        yaws = _all_or_each(lambda ds: self._table_yaws(ds, cam2base), detections)
        kept = [(d, y) for d, y in zip(detections, yaws, strict=True) if y is not None]
        locations = _all_or_each(
            lambda pairs: locate_blocks(
                np.array([d.centroid_px for d, _ in pairs]), self.intrinsics, cam2base,
                table_z_mm=self.table_z_mm, block_size_mm=self.block_size_mm,
                yaw_deg=[y for _, y in pairs]), kept)
        pairs = [(d, loc) for (d, _), loc in zip(kept, locations, strict=True)
                 if loc is not None]
        # A blob cut by the picture's edge is not a whole silhouette: its location is
        # rough (and it may look small); the sorter looks again before trusting it.
        out = []
        for d, loc in pairs:
            whole = not _touches_edge(d, w, h)
            if self._block_sized(d, loc, cam2base, whole):
                if whole:
                    loc = self._sides_missing(d, loc, cam2base)
                out.append(replace(self._sighting(d.color, loc, d), whole=whole))
        return out

    def _outline_grid(self, d: Detection, cam2base: FloatArray) -> _Grid | None:
        """The blob's outline cast onto the blocks' top plane, read as a grid of touching
        blocks (see ``_Grid``); None if the outline cannot be cast.

        Cast onto that plane, one block covers its top face plus the side faces the
        camera sees; n in a row cover n - 1 sides more. Lit from the side, a block's dark
        side faces may be too dark for its colour, and the blob is then its top faces
        only. So half the sides is assumed to count the blocks along each of the blocks'
        axes (the outline's main edge direction: right either way while the sides add
        less than a block), and how much of the sides the blob has is read from what its
        length leaves over.
        """
        size, top = self.block_size_mm, self.table_z_mm + self.block_size_mm
        # Straight edges (a pixel outline is a staircase, whose steps run along the
        # picture's axes, not the blocks').
        contour = cv2.approxPolyDP(d.contour_px.reshape(-1, 1, 2), 1.5, True).reshape(-1, 2)
        try:
            pts = table_points_from_pixels(contour.astype(np.float64), self.intrinsics,
                                           cam2base, top)[:, :2]
        except VisionError:
            return None
        yaw = _edge_yaw_deg(pts)
        a = math.radians(yaw)
        axes = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
        rel = pts @ axes.T
        lo_blob, hi_blob = rel.min(axis=0), rel.max(axis=0)
        centre = ((lo_blob + hi_blob) / 2) @ axes
        lo, hi = _cast_cube_extent(centre, axes, yaw, size, self.table_z_mm, cam2base[:3, 3])
        sides = (hi - lo) - size
        counts = tuple(max(1, round((ext - side / 2) / size))
                       for ext, side in zip(hi_blob - lo_blob, sides, strict=True))
        shown = np.clip((hi_blob - lo_blob - np.array(counts) * size) / np.maximum(sides, 1e-6),
                        0.0, 1.0)
        first = lo_blob + size / 2 + shown * (-lo - size / 2)  # the first top face's centre
        # The sides reach out from a top face on the camera's side only: lo or hi is
        # the top's half side, and their sum is how far the sides reach, signed.
        return _Grid(yaw, axes, (counts[0], counts[1]), first, shown, (lo_blob, hi_blob),
                     lo + hi)

    def _split(self, d: Detection, cam2base: FloatArray) -> list[BlockLocation] | None:
        """The blocks in a blob that holds several touching ones (a row, a 2 x 2, a
        staggered cluster): their top faces found on the top plane
        (``busarm.perception.split``); None for one block."""
        grid = self._outline_grid(d, cam2base)
        if grid is None or grid.counts[0] * grid.counts[1] <= 1 or max(grid.counts) > MAX_SPLIT:
            return None
        size, top = self.block_size_mm, self.table_z_mm + self.block_size_mm
        try:
            centres = top_faces_mm(d.contour_px, self.intrinsics, cam2base, top, size,
                                   grid.axes, grid.extent_uv_mm, grid.cast_uv_mm)
        except VisionError:
            return None
        if len(centres) <= 1:
            return None
        base2cam = np.linalg.inv(cam2base)
        p_cam = np.array([[x, y, top] for x, y in centres]) @ base2cam[:3, :3].T \
            + base2cam[:3, 3]
        pixels = self.intrinsics.pixels_from_camera_points(p_cam)
        return [BlockLocation(x, y, top, grid.yaw_deg, size, (float(u), float(v)),
                              silhouette=False)
                for (x, y), (u, v) in zip(centres, pixels.tolist(), strict=True)]

    def _sides_missing(self, d: Detection, loc: BlockLocation, cam2base: FloatArray
                       ) -> BlockLocation:
        """``loc`` (from the whole silhouette), or, if the blob lacks much of the side
        faces the camera sees (dark, lit from elsewhere), the block's top face as its
        outline gives it: the silhouette's centroid would be off by millimetres then."""
        grid = self._outline_grid(d, cam2base)
        if grid is None or grid.counts != (1, 1) or float(grid.shown.min()) >= SIDES_SHOWN:
            return loc
        x, y = grid.centre_mm(0, 0, self.block_size_mm)
        return replace(loc, x_mm=x, y_mm=y, silhouette=False)

    def _top_face_px(self, point_mm: npt.ArrayLike, cam2base: FloatArray) -> float:
        """The area (px) a block's top face at ``point_mm`` takes in the picture, about."""
        depth = float(np.linalg.norm(np.asarray(point_mm, dtype=float) - cam2base[:3, 3]))
        return float((self.intrinsics.fx * self.block_size_mm / max(depth, 1.0)) ** 2)

    def _block_sized(self, d: Detection, loc: BlockLocation, cam2base: FloatArray,
                     whole: bool = True) -> bool:
        top_px = self._top_face_px((loc.x_mm, loc.y_mm, loc.z_mm), cam2base)
        low = AREA_RANGE[0] * (1.0 if whole else CUT_AREA_FRACTION)
        # A cut blob may be a group of touching blocks (not split: its outline is cut).
        high = AREA_RANGE[1] * (1.0 if whole else MAX_SPLIT)
        return low * top_px <= d.area_px <= high * top_px

    def _sighting(self, color: str, loc: BlockLocation, detection: Detection | None,
                  detections: tuple[Detection, ...] = ()) -> Sighting:
        z_grasp = self.table_z_mm + self.block_size_mm / 2
        top_down, reachable, reason = True, True, ""
        try:
            self.kin.ik_best(loc.x_mm, loc.y_mm, z_grasp, -90.0)
        except UnreachableError:
            top_down = False
            try:
                self.kin.ik_free_pitch(loc.x_mm, loc.y_mm, z_grasp)
            except UnreachableError as exc:
                reachable, reason = False, str(exc)
        return Sighting(color, loc, detection, reachable, top_down, reason, detections)

    def locate_averaged(self, pictures: Sequence[tuple[npt.NDArray[np.uint8], Sequence[float]]]
                        ) -> list[Sighting]:
        """Blocks seen in several pictures, each located once per picture and averaged
        (a block seen in fewer than half of them is dropped as a glimpse)."""
        if not pictures:
            raise ConfigError("locate_averaged needs at least one picture")
        groups: list[list[Sighting]] = []
        for image, joints in pictures:
            for s in self.locate(image, joints):
                for group in groups:
                    ref = group[0].location
                    if group[0].color == s.color and math.hypot(
                            ref.x_mm - s.location.x_mm, ref.y_mm - s.location.y_mm
                    ) < MATCH_RADIUS_MM:
                        group.append(s)
                        break
                else:
                    groups.append([s])
        out = []
        for group in groups:
            if 2 * len(group) < len(pictures):
                continue
            loc = average_locations([s.location for s in group])
            dets = tuple(s.detection for s in group if s.detection is not None)
            out.append(replace(self._sighting(group[0].color, loc, dets[-1] if dets else None,
                                              dets), whole=all(s.whole for s in group)))
        return out


@dataclass(frozen=True)
class _Grid:
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


def _edge_yaw_deg(points: FloatArray) -> float:
    """The direction (deg, -45..45) most of an outline's length runs along, modulo 90:
    a row of cubes' sides, whatever the row's own shape."""
    edges = np.roll(points, -1, axis=0) - points
    length = np.hypot(edges[:, 0], edges[:, 1])
    angle4 = 4.0 * np.arctan2(edges[:, 1], edges[:, 0])
    mean = math.atan2(float(np.sum(length * np.sin(angle4))),
                      float(np.sum(length * np.cos(angle4))))
    return (math.degrees(mean / 4.0) + 45.0) % 90.0 - 45.0


def _cast_cube_extent(centre: FloatArray, axes: FloatArray, yaw_deg: float, size: float,
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


def _touches_edge(d: Detection, width_px: int, height_px: int) -> bool:
    c = d.contour_px.reshape(-1, 2)
    return bool(c[:, 0].min() <= 0 or c[:, 1].min() <= 0 or c[:, 0].max() >= width_px - 1
                or c[:, 1].max() >= height_px - 1)


def _all_or_each(solve: Callable[[list[T]], list[R]], items: Sequence[T]) -> list[R | None]:
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
