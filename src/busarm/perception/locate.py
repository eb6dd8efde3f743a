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
from collections.abc import Sequence
from dataclasses import replace

import cv2
import numpy as np
import numpy.typing as npt

from busarm.arm.config import CAMERA_JOINT_INDEX
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, UnreachableError, VisionError
from busarm.perception.obstacles import Obstacle, cast_obstacle, find_obstacles
from busarm.perception.shape import (
    MIN_TRUSTED,
    ROUND_FROM_PX,
    WHOLE_SHARE,
    OutlineCover,
    Shape,
    cube_silhouettes,
    judge_blobs,
    nearest_other_mm,
)
from busarm.perception.sightings import Found, NotBlock, Sighting
from busarm.perception.split import Grid, top_faces_mm
from busarm.perception.top_plane import (
    BlobCast,
    all_or_each,
    cast_blobs,
    edge_points_px,
    outline_grids,
    yaws_from_edges,
)
from busarm.units import check_range
from busarm.vision.calibration import CameraIntrinsics, HandEyeResult
from busarm.vision.calibration.core import as_transform, inverse_of
from busarm.vision.color import ColorDetector, Detection
from busarm.vision.localize import (
    BlockLocation,
    average_locations,
    locate_checked_blocks,
    table_points_from_pixels,
)

__all__ = [
    "AREA_RANGE",
    "BIN_MARGIN_MM",
    "BIN_WALL_MM",
    "CAMERA_LINK",
    "CAMERA_LINK_NAME",
    "CUT_AREA_FRACTION",
    "HIDDEN_SIZE_MM",
    "JUDGED_SHARE",
    "MATCH_PX",
    "MATCH_RADIUS_MM",
    "MAX_CAMERA_OFFSET_MM",
    "MAX_SPLIT",
    "NOT_BLOCK_COLORS",
    "SIDES_SHOWN",
    "SPLIT_EXPLAINS",
    "SPLIT_MIN_AREA",
    "BlockLocator",
    "FloatArray",
    "Found",
    "NotBlock",
    "Sighting",
    "link2base",
]


FloatArray = npt.NDArray[np.float64]

CAMERA_LINK = CAMERA_JOINT_INDEX
"""Index of the wrist-pitch link's frame in ``ArmKinematics.frames`` (DH frame 4)."""
CAMERA_LINK_NAME = "wrist_pitch"
MAX_CAMERA_OFFSET_MM = 300.0
NOT_BLOCK_COLORS = ("black", "white")
"""Colours the vendor's threshold file has for other jobs (lines, the table): never blocks."""
AREA_RANGE = (0.35, 4.5)
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
MATCH_PX = 6.0
"""... or, in pictures from one pose, their blobs' centroids are."""
HIDDEN_SIZE_MM = 4.0
"""A partly hidden block whose cube is this near the locator's size is taken at that size
and located as before; one further off, as the cube that fits what shows of it."""
JUDGED_SHARE = 0.8
"""Things are judged by their shape in this share of the picture about its middle only
(near its edge, the lens's calibration and the steep view measure worst)."""
SPLIT_EXPLAINS = 0.8
"""Touching blocks split out of one blob are kept if their silhouettes cover the blob's
outline this well (intersection over union): a thing of another shape is not them."""


def link2base(kin: ArmKinematics, joints_deg: Sequence[float]) -> FloatArray:
    """The camera link's frame (DH frame 4) in the base frame for measured joints (mm)."""
    return kin.frame(joints_deg, CAMERA_LINK)


class BlockLocator:
    """Finds and locates blocks in wrist-camera pictures (see the module docstring)."""

    def __init__(
        self, kin: ArmKinematics, intrinsics: CameraIntrinsics, hand_eye: HandEyeResult,
        detector: ColorDetector, *, table_z_mm: float = 0.0, block_size_mm: float = 30.0,
    ) -> None:
        check_range("block_size_mm", block_size_mm, 5.0, 200.0, "mm")
        # (Checked here once: each picture's locating trusts it.)
        check_range("table_z_mm", table_z_mm, -1e6, 1e6, "mm")
        if hand_eye.link != CAMERA_LINK_NAME:
            raise ConfigError(f"the hand-eye calibration places the camera on the {hand_eye.link!r}"
                              f" link; the wrist camera rides the {CAMERA_LINK_NAME!r} link")
        reach = float(np.linalg.norm(hand_eye.cam2link[:3, 3]))
        if reach > MAX_CAMERA_OFFSET_MM:
            raise ConfigError(f"the hand-eye calibration puts the camera {reach:.0f} mm from the "
                              f"wrist; a wrist camera sits within {MAX_CAMERA_OFFSET_MM:g} mm")
        self.kin = kin
        self.intrinsics = intrinsics
        # Checked once here: each picture's camera pose trusts it.
        self.cam2link = as_transform("cam2link", hand_eye.cam2link)
        self.detector = detector
        self.table_z_mm = float(table_z_mm)
        self.block_size_mm = float(block_size_mm)

    def cam2base(self, joints_deg: Sequence[float]) -> FloatArray:
        # ``camera_to_base`` without its checks: the forward kinematics' frame is rigid
        # as made, and the calibration's transform was checked when this was made.
        out: FloatArray = link2base(self.kin, joints_deg) @ self.cam2link
        return out

    def _table_yaws(self, detections: Sequence[Detection], cam2base: FloatArray
                    ) -> list[float]:
        """Each blob's yaw on the table: its rectangle's edge direction cast onto the
        top-face plane (a square's yaw is known modulo 90 deg)."""
        if not detections:
            return []
        table = table_points_from_pixels(np.concatenate([edge_points_px(d) for d in detections]),
                                         self.intrinsics, cam2base,
                                         self.table_z_mm + self.block_size_mm)
        return yaws_from_edges(table)

    def locate(self, image: npt.NDArray[np.uint8], joints_deg: Sequence[float], *,
               judge: bool = True) -> list[Sighting]:
        """Every block in ``image``, taken with the arm at the measured ``joints_deg``;
        ``judge``: each block seen whole and alone judged by its outline's shape and
        measured (``busarm.perception.shape``): things that are not blocks left out."""
        return self.find_in(image, joints_deg, judge=judge).blocks

    def find_in(self, image: npt.NDArray[np.uint8], joints_deg: Sequence[float], *,
                judge: bool = True, trays: Sequence[tuple[float, float, float]] = ()
                ) -> Found:
        """The blocks in ``image`` and (``judge``) the things in a block's colour that
        are not blocks; what lies in ``trays`` (x, y, radius mm: sorted already, the
        walls hiding it) is not judged."""
        h, w = image.shape[:2]
        detections = [d for d in self.detector.detect(image) if d.color not in NOT_BLOCK_COLORS]
        cam2base = self.cam2base(joints_deg)
        if not detections:
            return Found([], [])
        # Every blob's centroid, edge and outline cast onto the top plane at once, and
        # each outline read as a grid of blocks (the undistortion's fixed cost is paid
        # once a picture, the grids are array operations over all blobs).
        cast_list = cast_blobs(detections, self.intrinsics, cam2base,
                               self.table_z_mm + self.block_size_mm)
        casts = {id(d): c for d, c in zip(detections, cast_list, strict=True)}
        grids = self._grids(detections, cast_list, cam2base)
        cut = {id(d): _touches_edge(d, w, h) for d in detections}
        # Blocks of one colour that touch make one blob: such a blob is split into its
        # blocks by its size on the table, and each is located on its own.
        out: list[Sighting] = []
        single, big = [], []
        # Only a blob larger than one block's top face can be (is split, costly) is tried.
        for d, cast in zip(detections, cast_list, strict=True):
            if cast.centre is not None and not cut[id(d)] and d.area_px > \
                    SPLIT_MIN_AREA * self._top_face_px(cast.centre, cam2base):
                big.append(d)
            else:
                single.append(d)
        if judge:
            return self._judged_all(image, detections, single, big, cam2base, trays,
                                    casts, grids, cut)
        for d in big:
            parts = self._split(d, cam2base, grids[id(d)])
            if parts is None:
                single.append(d)
            else:  # cubes that explain the blob; else the split's guess, its places not sure
                explained = self._explained_parts(d, d.contour_px, cam2base, parts)
                out += explained if explained is not None else [
                    self._sighting(d.color, loc, d, whole=False) for loc in parts]
        return Found(out + self._locate_single(single, cam2base, cut, casts, grids), [])

    def _grids(self, detections: Sequence[Detection], casts: Sequence[BlobCast],
               cam2base: FloatArray) -> dict[int, Grid | None]:
        """Each blob's outline read as a grid of touching blocks (``outline_grids``), by
        the blob's id; None for one whose outline cannot be cast."""
        cast = [(d, c.outline) for d, c in zip(detections, casts, strict=True)
                if c.outline is not None]
        grids = outline_grids([pts for _, pts in cast], self.block_size_mm, self.table_z_mm,
                              cam2base[:3, 3])
        out: dict[int, Grid | None] = {id(d): None for d in detections}
        out.update((id(d), g) for (d, _), g in zip(cast, grids, strict=True))
        return out

    def _judged_all(self, image: npt.NDArray[np.uint8], detections: Sequence[Detection],
                    single: list[Detection], big: list[Detection], cam2base: FloatArray,
                    trays: Sequence[tuple[float, float, float]], casts: dict[int, BlobCast],
                    grids: dict[int, Grid | None], cut: dict[int, bool]) -> Found:
        """Every blob judged as one thing first (a block may be larger than the size
        this locator was given); a large blob that is not one measured block may be
        several touching ones: split, and the parts kept if cubes there explain its
        outline (else it stays as judged: no block, or one not measured). ``casts``,
        ``grids``, ``cut``: each blob's (by its id), as ``find_in`` made them."""
        first = self._judged(image, detections, self._locate_single(
            single + big, cam2base, cut, casts, grids), cam2base, trays)
        large = {id(d) for d in big}
        blocks: list[Sighting] = []
        not_blocks: list[NotBlock] = []
        done: set[int] = set()
        for s in first.blocks:
            measured = s.shape is not None and s.shape.verdict != "hidden"
            if id(s.detection) in large and not measured and s.detection is not None:
                done.add(id(s.detection))
                # (A crowd mostly hidden: its own blob, as before there was measuring.)
                outline = s.detection.contour_px if s.shape is None \
                    or s.shape.views[-1].trusted_share < MIN_TRUSTED \
                    else s.shape.views[-1].outline_px
                parts = self._explained_parts(s.detection, outline, cam2base,
                                              grid=grids[id(s.detection)])
                blocks += [s] if parts is None else parts
            else:
                blocks.append(s)
        for n in first.not_blocks:
            parts = None
            if n.detection is not None and id(n.detection) in large and n.shape.crowd:
                done.add(id(n.detection))
                parts = self._explained_parts(n.detection, n.shape.views[-1].outline_px,
                                              cam2base, grid=grids[id(n.detection)])
            if parts is not None:
                blocks += parts
            elif id(n.detection) not in large or _a_thing(n.shape):
                not_blocks.append(n)
            # (else a crowd of touching blocks no split makes out: looked at again later)
        for d in big:  # too large to be taken for one block at all
            if id(d) not in done and all(s.detection is not d for s in first.blocks):
                blocks += self._explained_parts(d, d.contour_px, cam2base,
                                                grid=grids[id(d)]) or []
        return Found(blocks, not_blocks)

    def _explained_parts(self, d: Detection, outline: npt.NDArray[np.int32],
                         cam2base: FloatArray, split: list[BlockLocation] | None = None, *,
                         grid: Grid | None = None) -> list[Sighting] | None:
        """The touching blocks split out of blob ``d`` (``split``: already; else split
        by its outline's ``grid``) if cubes of this locator's size there explain the
        thing's ``outline``; else None."""
        parts = split if split is not None else self._split(d, cam2base, grid)
        if parts is None:
            return None
        # Each part's silhouette is drawn once and the sets of them scored against the
        # outline from those drawings (``cubes_explain``, without drawing them again).
        size = self.block_size_mm
        cover = OutlineCover(outline, cube_silhouettes(
            [(p.x_mm, p.y_mm, p.yaw_deg, size) for p in parts], self.intrinsics, cam2base,
            self.table_z_mm))
        # No more blocks than explain it: a part the others explain as well without (two
        # blocks apart, seen as one blob through the gap, split in three; two in a row
        # whose sides in view make the blob big enough for four) is none.
        kept = list(range(len(parts)))
        best, k = cover.share(kept), 0
        while len(kept) > 1 and k < len(kept):
            fewer = [*kept[:k], *kept[k + 1:]]
            if (without := cover.share(fewer)) >= best:
                kept, best = fewer, without
            else:
                k += 1
        if best < SPLIT_EXPLAINS:
            return None
        return [self._sighting(d.color, parts[i], d) for i in kept]

    def _judged(self, image: npt.NDArray[np.uint8], detections: Sequence[Detection],
                found: list[Sighting], cam2base: FloatArray,
                trays: Sequence[tuple[float, float, float]]) -> Found:
        """``found`` with each whole blob of one block judged by its shape and measured
        (located as the cube that fits its outline); things that are not blocks apart."""
        blobs = [id(s.detection) for s in found]
        h, w = image.shape[:2]
        targets = [s for s in found if s.whole and s.detection is not None
                   and blobs.count(id(s.detection)) == 1
                   and not any(math.hypot(s.location.x_mm - x, s.location.y_mm - y) < r
                               for x, y, r in trays)]
        # Near the picture's edge a thing is measured (a block's size and place), never
        # judged: what looks like no block there is taken as before, and a cube is only
        # a cube the sorter looks at again.
        edge = {id(s) for s in targets if s.detection is not None
                and not _inner(s.detection, w, h)}
        shapes = judge_blobs(image, detections, [
            (s.detection, (s.location.x_mm, s.location.y_mm, s.location.yaw_deg,
                           s.location.size_mm)) for s in targets if s.detection is not None],
            self.intrinsics, cam2base, self.table_z_mm)
        judged = {id(s): shape for s, shape in zip(targets, shapes, strict=True)}
        blocks, not_blocks = [], []
        for s in found:
            shape = judged.get(id(s))
            if shape is not None and id(s) in edge:
                shape = None if shape.verdict in ("not a block", "hidden") else replace(
                    shape, verdict="unsure", why=f"seen near the picture's edge: {shape.why}")
            if shape is None:
                blocks.append(s)
            elif shape.verdict == "hidden":
                # What shows of it fits a cube: that cube, if its size is not the usual
                # one (a block partly hidden among others is most likely the usual size).
                usual = (abs(shape.cube.length_mm - self.block_size_mm) <= HIDDEN_SIZE_MM
                         or shape.views[-1].trusted_share < MIN_TRUSTED)
                blocks.append(replace(s, shape=shape) if usual else self.measured(s, shape))
            elif shape.verdict == "not a block":
                not_blocks.append(NotBlock(s.color, shape, s.detection))
            else:
                blocks.append(self.measured(s, shape))
        return Found(blocks, not_blocks)

    def measured(self, seen: Sighting, shape: Shape) -> Sighting:
        """``seen`` located and sized as the cube that fits ``shape``'s outlines best."""
        cube = shape.cube
        loc = replace(seen.location, x_mm=cube.x_mm, y_mm=cube.y_mm,
                      z_mm=self.table_z_mm + cube.length_mm, size_mm=cube.length_mm,
                      yaw_deg=(cube.yaw_deg + 45.0) % 90.0 - 45.0)
        return replace(self._sighting(seen.color, loc, seen.detection, seen.detections),
                       whole=seen.whole, shape=shape)

    def obstacles(self, image: npt.NDArray[np.uint8], joints_deg: Sequence[float],
                  bins: Sequence[tuple[float, float, float]] = (),
                  blocks: Sequence[Sighting] = (), not_blocks: Sequence[NotBlock] = ()
                  ) -> list[Obstacle]:
        """Things in ``image`` that are not blocks (``busarm.perception.obstacles``), cast onto
        the table; ``bins``: (x, y, side mm) of each tray, and ``blocks``: the blocks
        located in it, are not things (a block's side face in shade looks like no colour);
        ``not_blocks``: things in a block's colour found in it that are not blocks.
        """
        cam2base = self.cam2base(joints_deg)
        outlines = [d.contour_px for d in self.detector.detect(image)]
        boxes = [(b.location.x_mm, b.location.y_mm, b.location.size_mm, b.location.yaw_deg,
                  b.location.size_mm) for b in blocks]
        boxes += [(x, y, side + 2 * BIN_MARGIN_MM, 0.0, BIN_WALL_MM) for x, y, side in bins]
        for box in boxes:
            outline = self._box_outline_px(*box, cam2base)
            if outline is not None:
                outlines.append(outline)
        found = find_obstacles(image, outlines, self.intrinsics, cam2base, self.table_z_mm)
        for thing in not_blocks:
            cast = cast_obstacle(thing.shape.views[-1].outline_px, self.intrinsics, cam2base,
                                 self.table_z_mm)
            if cast is not None:
                found.append(cast)
        return found

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

    def _locate_single(self, detections: list[Detection], cam2base: FloatArray,
                       cut: dict[int, bool], casts: dict[int, BlobCast],
                       grids: dict[int, Grid | None]) -> list[Sighting]:
        """Sightings of blobs that are one block each (or none: not block-sized).
        ``cut`` (whether the blob touches the picture's edge), ``casts``, ``grids``: each
        blob's (by its id), as ``find_in`` made them."""
        if not detections:
            return []
        # Position for all blobs at once (vectorised), from their yaw on the table; a
        # blob whose rays miss the table is no block on it, and is left out.
        kept = [(d, yaw) for d in detections if (yaw := casts[id(d)].yaw_deg) is not None]
        # (The checked entry: finite centroids, a forward-kinematics pose, cast yaws.)
        locations = all_or_each(
            lambda pairs: locate_checked_blocks(
                np.array([d.centroid_px for d, _ in pairs]), self.intrinsics, cam2base,
                self.table_z_mm, self.block_size_mm, [y for _, y in pairs]), kept)
        out = []
        for (d, _), loc in zip(kept, locations, strict=True):
            # A blob cut by the picture's edge is not a whole silhouette: its location is
            # rough (and it may look small); the sorter looks again before trusting it.
            whole = not cut[id(d)]
            if loc is None or not self._block_sized(d, loc, cam2base, whole):
                continue
            if whole:
                loc = self._sides_missing(loc, grids[id(d)])
            out.append(self._sighting(d.color, loc, d, whole=whole))
        return out

    def _cast_outlines(self, detections: Sequence[Detection], cam2base: FloatArray
                       ) -> list[FloatArray | None]:
        """Each blob's outline (straight edges) cast onto the blocks' top plane (x, y mm);
        None for one that cannot be cast."""
        top = self.table_z_mm + self.block_size_mm
        return [c.outline for c in cast_blobs(detections, self.intrinsics, cam2base, top)]

    def _split(self, d: Detection, cam2base: FloatArray, grid: Grid | None
               ) -> list[BlockLocation] | None:
        """The blocks in a blob that holds several touching ones (a row, a 2 x 2, a
        staggered cluster): their top faces found on the top plane
        (``busarm.perception.split``), from the blob's outline read as a ``grid``
        (``outline_grids``); None for one block."""
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
        base2cam = inverse_of(cam2base)
        p_cam = np.array([[x, y, top] for x, y in centres]) @ base2cam[:3, :3].T \
            + base2cam[:3, 3]
        pixels = self.intrinsics.pixels_from_camera_points(p_cam)
        return [BlockLocation(x, y, top, grid.yaw_deg, size, (float(u), float(v)),
                              silhouette=False)
                for (x, y), (u, v) in zip(centres, pixels.tolist(), strict=True)]

    def _sides_missing(self, loc: BlockLocation, grid: Grid | None) -> BlockLocation:
        """``loc`` (from the whole silhouette), or, if the blob lacks much of the side
        faces the camera sees (dark, lit from elsewhere), the block's top face as its
        outline's ``grid`` gives it (None: the outline cannot be cast): the silhouette's
        centroid would be off by millimetres then."""
        if grid is None or grid.counts != (1, 1):
            return loc
        # (Both shares as floats: numpy's min of two numbers costs more than the test.)
        shown_u, shown_v = grid.shown.tolist()
        if shown_u >= SIDES_SHOWN and shown_v >= SIDES_SHOWN:
            return loc
        x, y = grid.centre_mm(0, 0, self.block_size_mm)
        return replace(loc, x_mm=x, y_mm=y, silhouette=False)

    def _top_face_px(self, point_mm: Sequence[float] | FloatArray, cam2base: FloatArray) -> float:
        """The area (px) a block's top face at ``point_mm`` takes in the picture, about."""
        # (An array's numbers as floats at once: float() of each costs more.)
        point = point_mm.tolist() if isinstance(point_mm, np.ndarray) else [
            float(v) for v in point_mm]
        depth = math.dist(point, cam2base[:3, 3].tolist())
        return float((self.intrinsics.fx * self.block_size_mm / max(depth, 1.0)) ** 2)

    def _block_sized(self, d: Detection, loc: BlockLocation, cam2base: FloatArray,
                     whole: bool = True) -> bool:
        top_px = self._top_face_px((loc.x_mm, loc.y_mm, loc.z_mm), cam2base)
        low = AREA_RANGE[0] * (1.0 if whole else CUT_AREA_FRACTION)
        # A cut blob may be a group of touching blocks (not split: its outline is cut).
        high = AREA_RANGE[1] * (1.0 if whole else MAX_SPLIT)
        return low * top_px <= d.area_px <= high * top_px

    def _sighting(self, color: str, loc: BlockLocation, detection: Detection | None,
                  detections: tuple[Detection, ...] = (), whole: bool = True) -> Sighting:
        z_grasp = self.table_z_mm + loc.size_mm / 2
        top_down, reachable, reason = True, True, ""
        if not self.kin.reaches(loc.x_mm, loc.y_mm, z_grasp, -90.0):
            top_down = False
            try:
                self.kin.ik_free_pitch(loc.x_mm, loc.y_mm, z_grasp)
            except UnreachableError as exc:
                reachable, reason = False, str(exc)
        return Sighting(color, loc, detection, reachable, top_down, reason, detections,
                        whole)

    def locate_averaged(self, pictures: Sequence[tuple[npt.NDArray[np.uint8], Sequence[float]]]
                        ) -> list[Sighting]:
        """Blocks seen in several pictures, each located once per picture and averaged
        (a block seen in fewer than half of them is dropped as a glimpse)."""
        return self.find(pictures).blocks

    def find(self, pictures: Sequence[tuple[npt.NDArray[np.uint8], Sequence[float]]], *,
             trays: Sequence[tuple[float, float, float]] = ()) -> Found:
        """``locate_averaged``'s blocks, judged by their shapes in the last picture (a
        block's location and size then the measured cube's), and the things in a block's
        colour that are not blocks (``trays`` as ``find_in``)."""
        if not pictures:
            raise ConfigError("locate_averaged needs at least one picture")
        groups: list[list[Sighting]] = []
        last = Found([], [])
        for k, (image, joints) in enumerate(pictures):
            last = self.find_in(image, joints, judge=k == len(pictures) - 1, trays=trays)
            for s in last.blocks:
                for group in groups:
                    # The same block in another picture from the same pose: about the
                    # same place, or (one measured, one taken at the usual size) the same
                    # place in the picture.
                    ref = group[0].location
                    if group[0].color == s.color and (math.hypot(
                            ref.x_mm - s.location.x_mm, ref.y_mm - s.location.y_mm
                    ) < MATCH_RADIUS_MM or math.dist(ref.centroid_px, s.location.centroid_px)
                            < MATCH_PX):
                        group.append(s)
                        break
                else:
                    groups.append([s])
        out = []
        for group in groups:
            if 2 * len(group) < len(pictures) or any(
                    n.color == group[0].color and math.hypot(
                        n.xy_mm[0] - group[0].location.x_mm, n.xy_mm[1] - group[0].location.y_mm)
                    < MATCH_RADIUS_MM for n in last.not_blocks):
                continue
            dets = tuple(s.detection for s in group if s.detection is not None)
            judged = [s for s in group if s.shape is not None]
            if judged:  # measured: its own size and place (the others assumed a size)
                out.append(replace(judged[-1], detections=dets,
                                   location=replace(judged[-1].location, frames=len(group))))
                continue
            loc = average_locations([s.location for s in group])
            out.append(replace(self._sighting(group[0].color, loc, dets[-1] if dets else None,
                                              dets), whole=all(s.whole for s in group)))
        return Found([s for s in out if s.shape is not None or not _part_of_measured(s, out)],
                     last.not_blocks)


def _part_of_measured(seen: Sighting, found: Sequence[Sighting]) -> bool:
    """Whether ``seen`` (not measured: split from a blob at the usual size in a picture
    not judged) stands nearer a measured block of its colour than another block can:
    that block, taken for several in that picture."""
    return any(m.shape is not None and m.shape.verdict in ("cube", "unsure")
               and m.color == seen.color and math.hypot(
                   m.location.x_mm - seen.location.x_mm, m.location.y_mm - seen.location.y_mm)
               < nearest_other_mm(m.location.size_mm) for m in found)


def _a_thing(shape: Shape) -> bool:
    """Whether a large blob judged no block is one thing (seen whole, box-shaped or
    round), not a crowd of touching blocks of one colour."""
    return all(v.trusted_share >= WHOLE_SHARE for v in shape.views) and (
        shape.box.fit_px <= ROUND_FROM_PX or shape.why.startswith("round"))


def _inner(d: Detection, width_px: int, height_px: int) -> bool:
    """Whether blob ``d`` lies in the picture's inner part (``JUDGED_SHARE`` of it), where
    a lens calibrated to a fraction of a pixel measures a thing's sides well."""
    u, v = d.centroid_px
    return (abs(u - width_px / 2) <= JUDGED_SHARE * width_px / 2
            and abs(v - height_px / 2) <= JUDGED_SHARE * height_px / 2)


def _touches_edge(d: Detection, width_px: int, height_px: int) -> bool:
    # The outline's bounding box: its lowest and highest column and row, in one C call.
    x, y, w, h = cv2.boundingRect(d.contour_px.reshape(-1, 1, 2))
    return x <= 0 or y <= 0 or x + w - 1 >= width_px - 1 or y + h - 1 >= height_px - 1
