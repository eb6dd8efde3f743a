"""The wrist camera on the floor, for a robot: pose the arm to look ahead and down
(``look_ahead``) and make its floor camera (``floor_camera``) from the robot's
calibration, its joints and where its chassis carries the arm (busarm.perception.floor_view
has the model)."""

from __future__ import annotations

from collections.abc import Sequence

from busarm.base.config import ChassisConfig
from busarm.errors import ConfigError
from busarm.perception.floor_view import (
    LOOK_AHEAD_DEG,
    LOOK_AHEAD_SPEED_DEG_S,
    MAX_LOOK_SPEED_DEG_S,
    FloorCamera,
    floor_camera_at,
)
from busarm.perception.locate import CAMERA_LINK_NAME
from busarm.robot.robot import Robot
from busarm.units import check_range

__all__ = [
    "floor_camera",
    "look_ahead",
]


def _chassis(robot: Robot, chassis: ChassisConfig | None) -> ChassisConfig:
    if chassis is not None:
        return chassis
    if robot.base is not None:
        return robot.base.config
    if robot.twin is not None and robot.twin.chassis is not None:
        return robot.twin.chassis
    raise ConfigError("the floor camera needs to know where the arm sits above the floor: "
                      "open the robot with its chassis (Robot.open(..., chassis=\"jetauto\")) "
                      "or give chassis=")


def look_ahead(robot: Robot, *, speed_deg_s: float = LOOK_AHEAD_SPEED_DEG_S) -> tuple[float, ...]:
    """Move the arm to ``LOOK_AHEAD_DEG`` (its fastest joint at ``speed_deg_s``) and
    return the joints measured once it stands still."""
    speed = check_range("speed_deg_s", speed_deg_s, 1.0, MAX_LOOK_SPEED_DEG_S, "deg/s")
    robot.arm.move_joints(LOOK_AHEAD_DEG, speed_deg_s=speed)
    return robot.arm.settled_joints_deg()


def floor_camera(robot: Robot, *, chassis: ChassisConfig | None = None,
                 joints_deg: Sequence[float] | None = None) -> FloorCamera:
    """The wrist camera on the floor now: its calibration, the joints measured (or
    ``joints_deg``) and the chassis's arm mount (``chassis``, else the robot's base's or
    its twin's); ConfigError without a camera calibration or a chassis."""
    cal = robot.require_camera_calibration()
    if cal.hand_eye.link != CAMERA_LINK_NAME:
        raise ConfigError(f"the hand-eye calibration places the camera on the "
                          f"{cal.hand_eye.link!r} link; the wrist camera rides the "
                          f"{CAMERA_LINK_NAME!r} link")
    mount = _chassis(robot, chassis).arm
    joints = robot.arm.read_joints_deg() if joints_deg is None else joints_deg
    return floor_camera_at(robot.config, robot.arm.kin, cal.intrinsics,
                           cal.hand_eye.cam2link, mount, joints)
