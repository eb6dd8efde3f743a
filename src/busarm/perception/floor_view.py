"""The wrist camera looking at the floor ahead of the mobile base: for line following.

``LOOK_AHEAD_DEG`` poses the arm upright and leaning over the front of the chassis,
the tool pitched down ahead, so that the wrist camera (about 0.57 m above the floor and
0.16 m ahead of the base's centre, looking down and forward) sees the floor from about
0.18 m ahead of the base's centre (just beyond the chassis's front edge, 0.15 m) to
about 0.72 m straight ahead (farther toward the picture's upper corners), centred on
the base's x axis; the chassis stays out of view. The gripper hangs in front of the lens
in any pose (the camera looks along the tool), so the picture's rows from the
gripper's top edge down are not the floor: ``FloorCamera.floor_rows`` says where they
begin, computed from the gripper's envelope (the arm config's finger pads opened
widest, and a palm) projected through the camera's calibration.

``floor_camera_at(...)`` is the camera's model and pose on the floor: the intrinsics and
the camera-to-base transform (the base frame on the floor, z = 0 the floor, metres),
from the joints measured now through the arm's kinematics and the hand-eye calibration
(``cam2base``), and where the chassis carries the arm (its config's arm ``Mount``).
The arm stays put while the base drives: make it once after looking ahead and use it
for every frame (``FloorCamera.find_line``); for a robot, ``busarm.apps.line_follow.floor_look``
poses the arm (``look_ahead``) and makes it (``floor_camera``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.arm.config import ArmConfig
from busarm.arm.kinematics import ArmKinematics
from busarm.base.config import Mount
from busarm.errors import ConfigError
from busarm.perception.locate import link2base
from busarm.vision.calibration import CameraIntrinsics
from busarm.vision.calibration.core import invert_transform
from busarm.vision.color_thresholds import ColorRange
from busarm.vision.floor_line import FloorLineSighting, find_floor_line
from busarm.vision.localize import camera_to_base

__all__ = [
    "GRIPPER_MARGIN_PX",
    "LENS_TRUSTED_SHARE",
    "LOOK_AHEAD_DEG",
    "LOOK_AHEAD_SPEED_DEG_S",
    "LOWER_ARM_LINK",
    "MAX_LOOK_SPEED_DEG_S",
    "PALM_HALF_MM",
    "FloatArray",
    "FloorCamera",
    "floor_camera_at",
    "floor_rows",
]


FloatArray = npt.NDArray[np.float64]

LOOK_AHEAD_DEG = (0.0, -95.0, 80.0, 0.0, 0.0)
"""base yaw, shoulder, elbow, wrist pitch, wrist roll: see the module docstring."""
LOOK_AHEAD_SPEED_DEG_S = 45.0
"""The move there (the fastest joint): slow enough for an arm riding a moving base."""
MAX_LOOK_SPEED_DEG_S = 90.0
PALM_HALF_MM = (15.0, 30.0)
"""The gripper's palm, half its depth (toward the camera) and half its width (across the
fingers): the vendor's gripper, and the twin's."""
GRIPPER_MARGIN_PX = 8
"""Rows kept clear above the gripper's projected top edge (its edge's blur, and a
hand-eye calibration a little off)."""
LENS_TRUSTED_SHARE = 0.8
"""The picture's corners beyond this share of its half-diagonal from the principal point
are not looked at: a lens calibration is least sure there (its boards seldom reach them;
the twin's calibration is off by 3-6 px in them, a centimetre on the far floor)."""
LOWER_ARM_LINK = 4
"""Index in ``ArmKinematics.frames`` of the wrist roll's frame (DH frame 5), which the
gripper hangs from: its z axis is the tool's."""


@dataclass(frozen=True)
class FloorCamera:
    """The wrist camera's lens and its pose above the floor (see the module docstring)."""

    intrinsics: CameraIntrinsics
    cam_to_floor: FloatArray
    """4x4, metres: the camera (OpenCV axes) in the base frame on the floor (z up)."""
    floor_rows: int
    """Rows 0..floor_rows-1 of the picture may show the floor; below them the gripper
    (``mask`` also leaves out the picture's corners: ``LENS_TRUSTED_SHARE``)."""
    joints_deg: tuple[float, ...]
    """The joints it was computed for."""

    @property
    def mask(self) -> npt.NDArray[np.bool_]:
        """The pixels that may show the floor (H x W, True), for ``find_floor_line``."""
        i = self.intrinsics
        rows, cols = np.ogrid[: i.height_px, : i.width_px]
        reach_px = LENS_TRUSTED_SHARE * math.hypot(i.width_px, i.height_px) / 2
        out = (cols - i.cx) ** 2 + (rows - i.cy) ** 2 <= reach_px ** 2
        out[self.floor_rows:] = False
        return np.asarray(out, dtype=bool)

    def view_m(self) -> tuple[float, float]:
        """How far ahead of the base's centre (m) the picture's centre column meets the
        floor, at its lowest floor row and at its top (inf above the horizon)."""
        rows = (max(self.floor_rows - 1, 0), 0)
        xy = self.intrinsics.normalized_from_pixels([[self.intrinsics.cx, r] for r in rows])
        rot, origin = self.cam_to_floor[:3, :3], self.cam_to_floor[:3, 3]
        out = []
        for ray in np.c_[xy, np.ones(2)] @ rot.T:
            out.append(origin[0] - origin[2] / ray[2] * ray[0] if ray[2] < 0 else math.inf)
        return out[0], out[1]

    def find_line(self, image: npt.NDArray[np.uint8], colour: str | ColorRange = "black",
                  **options: float) -> FloorLineSighting | None:
        """``find_floor_line`` on a picture taken from here (the gripper masked out)."""
        return find_floor_line(image, self.intrinsics, self.cam_to_floor, colour,
                               mask=self.mask, **options)


def _mount_to_floor(mount: Mount) -> FloatArray:
    """The arm's base frame in the base frame on the floor (mm, as the kinematics)."""
    c, s = math.cos(mount.yaw_rad), math.sin(mount.yaw_rad)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:3, 3] = (mount.x_m * 1000, mount.y_m * 1000, mount.z_m * 1000)
    return out


def _gripper_corners_mm(config: ArmConfig) -> FloatArray:
    """(4, 16) homogeneous corners of the gripper's envelope in the wrist roll's frame:
    the palm, then the finger pads opened widest."""
    g, tool = config.gripper, config.geometry.tool_mm
    thick, width, length = g.pad_mm
    palm_end = tool - length
    reach = g.widest_gap_mm / 2 + thick
    boxes = (((-PALM_HALF_MM[0], PALM_HALF_MM[0]), (-PALM_HALF_MM[1], PALM_HALF_MM[1]),
              (0.0, palm_end)),
             ((-width / 2, width / 2), (-reach, reach), (palm_end, tool)))
    return np.array([[x, y, z, 1.0] for xs, ys, zs in boxes for x in xs for y in ys
                     for z in zs]).T


def floor_rows(config: ArmConfig, kin: ArmKinematics, intrinsics: CameraIntrinsics,
               cam2arm_mm: FloatArray, joints_deg: Sequence[float]) -> int:
    """How many rows from the top of the picture are clear of the gripper."""
    wrist = kin.frames(joints_deg)[LOWER_ARM_LINK]
    in_cam = (invert_transform(cam2arm_mm) @ wrist @ _gripper_corners_mm(config))[:3].T
    ahead = in_cam[in_cam[:, 2] > 1.0]
    if not len(ahead):
        return intrinsics.height_px
    top = float(np.min(intrinsics.pixels_from_camera_points(ahead)[:, 1]))
    return int(min(max(math.floor(top - GRIPPER_MARGIN_PX), 0), intrinsics.height_px))


def floor_camera_at(config: ArmConfig, kin: ArmKinematics, intrinsics: CameraIntrinsics,
                    cam2link_mm: npt.ArrayLike, mount: Mount,
                    joints_deg: Sequence[float]) -> FloorCamera:
    """The floor camera for ``joints_deg``, a hand-eye ``cam2link_mm`` (the wrist pitch
    link's, mm) and the arm's ``mount`` on the chassis."""
    joints = config.check_joints(joints_deg)
    cam2arm = camera_to_base(link2base(kin, joints), cam2link_mm)
    to_floor = _mount_to_floor(mount) @ cam2arm
    to_floor[:3, 3] /= 1000.0
    if not to_floor[2, 3] > 0.0:
        raise ConfigError(f"the camera is {to_floor[2, 3]:.3f} m from the floor, not above "
                          f"it: joints {[round(j, 1) for j in joints]} deg")
    return FloorCamera(intrinsics, to_floor,
                       floor_rows(config, kin, intrinsics, cam2arm, joints), joints)
