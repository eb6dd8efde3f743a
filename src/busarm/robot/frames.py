"""The robot's coordinate frames, named as the URDF ``busarm arm urdf`` writes: what ROS's
/tf (busarm.ros) and Foxglove's transforms (busarm.view) show.

The arm: ``base_link`` -> one ``<joint>_link`` per joint -> ``tool`` (a chain, as in the
URDF, so robot_state_publisher's tree and ours agree), and the wrist camera's optical
frame (x right, y down, z along the view: OpenCV's, and ROS's ``_optical_frame``) on the
link it is mounted to, from the hand-eye calibration. The mobile base: ``odom`` ->
``base_footprint`` (the chassis on the floor) -> ``base_link`` (the arm's mount) and
``laser`` (the Lidar's). Lengths in metres, as ROS has them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from busarm.arm.config import ArmConfig
from busarm.arm.kinematics import ArmKinematics
from busarm.arm.urdf import link_names
from busarm.base.config import Mount
from busarm.base.odometry import Pose2D
from busarm.perception.locate import CAMERA_LINK

__all__ = [
    "CAMERA_FRAME",
    "FOOTPRINT_FRAME",
    "LASER_FRAME",
    "ODOM_FRAME",
    "FloatArray",
    "Frame",
    "arm_frames",
    "base_frames",
    "planar",
]


FloatArray = npt.NDArray[np.float64]
Frame = tuple[str, str, FloatArray]
"""(parent, child, 4 x 4 transform of child in parent, m)."""

CAMERA_FRAME = "wrist_camera_optical_frame"
ODOM_FRAME = "odom"
FOOTPRINT_FRAME = "base_footprint"
LASER_FRAME = "laser"


def _in_m(transform_mm: npt.ArrayLike) -> FloatArray:
    out = np.array(transform_mm, dtype=np.float64)
    out[:3, 3] /= 1000.0
    return out


def arm_frames(config: ArmConfig, kin: ArmKinematics, joints_deg: Sequence[float],
               cam2link_mm: npt.ArrayLike | None = None) -> list[Frame]:
    """Each arm link in its parent for these joint angles, and the camera when given."""
    names = link_names(config)
    poses = [np.eye(4), *kin.frames(joints_deg)]
    out: list[Frame] = []
    for k in range(1, len(poses)):
        relative = np.linalg.solve(poses[k - 1], poses[k])
        out.append((names[k - 1], names[k], _in_m(relative)))
    if cam2link_mm is not None:
        out.append((names[CAMERA_LINK + 1], CAMERA_FRAME, _in_m(cam2link_mm)))
    return out


def planar(x_m: float, y_m: float, z_m: float, yaw_rad: float) -> FloatArray:
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[:3, 3] = (x_m, y_m, z_m)
    return out


def base_frames(pose: Pose2D, arm: Mount, lidar: Mount) -> list[Frame]:
    """The base in ``odom`` at ``pose``, and the arm's and the Lidar's mounts on it."""
    return [
        (ODOM_FRAME, FOOTPRINT_FRAME, planar(pose.x_m, pose.y_m, 0.0, pose.yaw_rad)),
        (FOOTPRINT_FRAME, "base_link", planar(arm.x_m, arm.y_m, arm.z_m, arm.yaw_rad)),
        (FOOTPRINT_FRAME, LASER_FRAME, planar(lidar.x_m, lidar.y_m, lidar.z_m, lidar.yaw_rad)),
    ]
