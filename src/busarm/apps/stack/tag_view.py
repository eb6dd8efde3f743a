"""Tagged blocks as the wrist camera sees them: each AprilTag on a block's top gives the
block's id, its top face's centre and yaw, and its size.

A tag's pose from its corners is known up to scale: the same picture shows a tag twice
as large twice as far away. Here the scale comes from the table. The tag's black square
is ``TAG_SIDE_FRACTION`` of the block's side and lies on its top, so the block's side
``s`` is also its top's height over the table: with the pose solved for a guessed side
``s0``, the true tag centre is the camera's centre plus ``s / s0`` times the solved
offset, and its height must be the table's plus ``s`` (and the label's thickness). That
is one linear equation for ``s``. Once a block's side is known (it was measured on the
table), a tag seen on a tower is solved at that size directly and its height measured.

``TagView`` looks from joints that aim the camera at a point from a given height over a
surface (``busarm.apps.pick_sort.look_poses.look_pose``): close enough that a tag's
cells are several pixels wide (from the arm's ``look`` pose they are about 3 px, and
one tag in five was missed through a real lens).
"""

from __future__ import annotations

import contextlib
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.look_poses import look_pose
from busarm.arm import Arm
from busarm.errors import ConfigError, UnreachableError, VisionError
from busarm.perception.locate import BlockLocator
from busarm.vision.camera import CameraSource
from busarm.vision.tags import TagDetection, detect_tags, tag_pose

__all__ = [
    "LABEL_MM",
    "MAX_UPRIGHT_TILT_DEG",
    "TAG_SIDE_FRACTION",
    "Keepout",
    "TagSighting",
    "TagView",
    "measure_tag",
]


TAG_SIDE_FRACTION = 0.75
"""The tag's black square over its block's side (as the twin prints it,
``busarm.twin.block_tags``; the vendor's blocks alike)."""
LABEL_MM = 0.3
"""The printed label's thickness over the block's top face."""
MAX_UPRIGHT_TILT_DEG = 15.0
"""A tag facing further than this from straight up is on a block that is not upright."""
GUESS_MM = 30.0
"""The side a pose is first solved for (any will do: the scale is solved after)."""
MAX_TILT_DEG = 35.0
"""A look may tilt the camera this far from straight down where straight does not reach."""
RELOOKS = ((0.8, 4.0), (0.9, -4.0))
"""A tag not seen is looked for again from these: the camera height's share, and the
base turned so many degrees (the view's centre moves about 10 mm)."""
DROPS_MM = (0.0, 20.0, 40.0, 60.0)
"""How far below a surface a look may aim where it cannot aim at the surface itself: the
tool then passes 80 - drop mm over it at least (``look_poses.TOOL_CLEAR_MM``)."""


@dataclass(frozen=True)
class TagSighting:
    """One tagged block as seen: its id, its top face's centre (mm, base frame), yaw
    (deg, folded into -45..45), side (mm), how far its top faces from straight up (deg)
    and the pose's reprojection error (px)."""

    tag_id: int
    x_mm: float
    y_mm: float
    top_z_mm: float
    yaw_deg: float
    size_mm: float
    tilt_deg: float
    error_px: float

    @property
    def upright(self) -> bool:
        return self.tilt_deg <= MAX_UPRIGHT_TILT_DEG

    def off_mm(self, x_mm: float, y_mm: float) -> float:
        return math.hypot(self.x_mm - x_mm, self.y_mm - y_mm)


@dataclass(frozen=True)
class Keepout:
    """A column a look keeps the tool over (a tower): its axis (mm, base frame), how near
    its axis the tool and the fingers round it may come (mm), and the least height of the
    tool over it (mm, base frame z)."""

    x_mm: float
    y_mm: float
    radius_mm: float
    clear_z_mm: float

    def deck(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """``look_poses.look_pose``'s deck for a look at (x, y): the tool kept as high as
        ``clear_z_mm`` out to beyond the column if the column stands by the arm's way
        there (nearer than the point, within ``radius_mm`` of the arm's vertical plane);
        else no deck."""
        reach = math.hypot(x_mm, y_mm)
        if reach == 0.0:
            return 0.0, 0.0
        ux, uy = x_mm / reach, y_mm / reach
        along = self.x_mm * ux + self.y_mm * uy
        if along > reach or abs(self.y_mm * ux - self.x_mm * uy) >= self.radius_mm:
            return 0.0, 0.0
        return along + self.radius_mm, self.clear_z_mm


def measure_tag(detection: TagDetection, locator: BlockLocator, cam2base: npt.ArrayLike,
                size_mm: float | None = None) -> TagSighting:
    """The block under a tag: at ``size_mm`` if its side is known, else its side measured
    from its height over the table (see the module docstring). VisionError if no pose
    fits the tag, or the side it gives is not a block's."""
    intr = locator.intrinsics
    c2b = np.asarray(cam2base, dtype=np.float64)
    guess = GUESS_MM if size_mm is None else size_mm
    tag2cam, err = tag_pose(detection, guess * TAG_SIDE_FRACTION, intr.camera_matrix,
                            intr.distortion, fisheye=intr.model == "fisheye")
    offset = c2b[:3, :3] @ tag2cam[:3, 3]
    side = guess
    if size_mm is None:
        # cam_z + (offset_z / s0) s = table_z + s + label: one equation for s.
        denominator = 1.0 - offset[2] / guess
        side = (c2b[2, 3] - locator.table_z_mm - LABEL_MM) / denominator
        if not 5.0 <= side <= 200.0:
            raise VisionError(f"tag {detection.tag_id}: its pose gives a block {side:.0f} mm "
                              "tall, not one standing on the table")
    centre = c2b[:3, 3] + offset * (side / guess)
    rot = c2b[:3, :3] @ tag2cam[:3, :3]
    yaw = math.degrees(math.atan2(rot[1, 0], rot[0, 0]))
    tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(rot[2, 2])))))
    return TagSighting(detection.tag_id, float(centre[0]), float(centre[1]),
                       float(centre[2]) - LABEL_MM, (yaw + 45.0) % 90.0 - 45.0, float(side),
                       tilt, float(err))


class TagView:
    """Looks at tagged blocks with ``arm``'s wrist ``camera`` (see the module docstring);
    ``sizes``: the sides measured so far, by tag id (a tag seen again is solved at its
    block's size)."""

    def __init__(self, arm: Arm, camera: CameraSource, locator: BlockLocator,
                 settle_s: float, joint_speed_deg_s: float) -> None:
        self.arm, self.camera, self.locator = arm, camera, locator
        self.settle_s, self.joint_speed_deg_s = settle_s, joint_speed_deg_s
        self.sizes: dict[int, float] = {}
        self.last_image: npt.NDArray[np.uint8] | None = None

    def pose_for(self, x_mm: float, y_mm: float, surface_z_mm: float, camera_mm: float,
                 keepout: Keepout | None = None) -> tuple[float, ...]:
        """Joints aiming the camera at (x, y) on the plane ``surface_z_mm`` from about
        ``camera_mm`` over it (tilted if need be), the tool over ``keepout`` if it stands
        in the way; UnreachableError if none does."""
        kin = self.arm.kin
        bearing = math.degrees(math.atan2(y_mm, x_mm))
        deck = (0.0, 0.0) if keepout is None else keepout.deck(x_mm, y_mm)
        # Over a tall tower the camera cannot look down from as high as over the table
        # (a look keeps the tool ``TOOL_CLEAR_MM`` over the surface aimed at): it aims at
        # a plane below the top instead, its axis through nearly the same point (near
        # straight down), the tool kept that much less high over the top.
        for drop, tilt in itertools.product(DROPS_MM, (10.0, MAX_TILT_DEG)):
            with contextlib.suppress(UnreachableError):
                joints = look_pose(kin, self.locator.cam2link, surface_z_mm - drop,
                                   math.hypot(x_mm, y_mm), camera_mm + drop, tilt, deck)
                try:
                    return self.arm.config.check_joints((bearing, *joints[1:]))
                except ConfigError as exc:
                    raise UnreachableError(str(exc)) from exc
        raise UnreachableError(f"no look pose aims the camera at ({x_mm:.0f}, {y_mm:.0f}) mm "
                               f"from {camera_mm:.0f} mm over z {surface_z_mm:.0f} mm")

    def look(self, joints: Sequence[float]) -> list[TagSighting]:
        """Every tag seen with the arm at ``joints`` (moved there first)."""
        self.arm.move_joints(joints, speed_deg_s=self.joint_speed_deg_s)
        if self.settle_s:
            self.arm.clock.sleep(self.settle_s)
        frame = self.camera.read()
        measured = self.arm.read_joints_deg()
        self.last_image = frame.image
        cam2base = self.locator.cam2base(measured)
        out = []
        for detection in detect_tags(frame.image):
            with contextlib.suppress(VisionError):
                out.append(measure_tag(detection, self.locator, cam2base,
                                       self.sizes.get(detection.tag_id)))
        return out

    def survey(self, bearings_deg: Sequence[float], radius_mm: float, surface_z_mm: float,
               camera_mm: float, keepout: Keepout | None = None) -> dict[int, TagSighting]:
        """Every upright tag seen looking at the points ``radius_mm`` out on these
        bearings, on the plane ``surface_z_mm``, from ``camera_mm`` over it (the tool
        over ``keepout``), by id, lowest first: of several sightings of one tag, the one
        nearest the middle of its view."""
        found: dict[int, tuple[float, TagSighting]] = {}
        for bearing in bearings_deg:
            a = math.radians(bearing)
            x, y = radius_mm * math.cos(a), radius_mm * math.sin(a)
            try:
                pose = self.pose_for(x, y, surface_z_mm, camera_mm, keepout)
            except UnreachableError:
                continue
            for t in self.look(pose):
                off = t.off_mm(x, y)
                if t.upright and (t.tag_id not in found or off < found[t.tag_id][0]):
                    found[t.tag_id] = (off, t)
        return {tag: t for tag, (_, t) in sorted(found.items())}

    def find(self, tag_id: int, x_mm: float, y_mm: float, surface_z_mm: float,
             camera_mm: float, keepout: Keepout | None = None) -> TagSighting | None:
        """Tag ``tag_id`` looked at closer about (x, y) (the tool over ``keepout``); its
        side measured if not known yet. Not seen, it is looked at again from a little
        nearer and turned (a tag whose edges lie along the pixel rows can be missed).
        None if it is not seen."""
        base = self.pose_for(x_mm, y_mm, surface_z_mm, camera_mm, keepout)
        views: list[Sequence[float]] = [base]
        for nearer, turn in RELOOKS:
            with contextlib.suppress(UnreachableError, ConfigError):
                pose = self.pose_for(x_mm, y_mm, surface_z_mm, camera_mm * nearer, keepout)
                views.append(self.arm.config.check_joints((pose[0] + turn, *pose[1:])))
        for joints in views:
            seen = [t for t in self.look(joints) if t.tag_id == tag_id]
            if seen:
                best = min(seen, key=lambda t: t.off_mm(x_mm, y_mm))
                if tag_id not in self.sizes and best.upright:
                    self.sizes[tag_id] = best.size_mm
                return best
        return None
