"""ROS 2 messages of what the robot senses: servo diagnostics, blocks, scans, odometry."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from busarm.base.base import BaseOdometry
from busarm.lidar.beams import SCAN_BEAMS, even_beams
from busarm.lidar.scan import LaserScan
from busarm.nav.grid import OccupancyGrid
from busarm.nav.map_files import trinary_cells
from busarm.perception.locate import Sighting
from busarm.robot.state import StateReader
from busarm.ros.messages import (
    DIAGNOSTIC_ARRAY,
    LASER_SCAN,
    MARKER_ARRAY,
    OCCUPANCY_GRID,
    ODOMETRY,
    header,
    message_class,
    stamp,
    yaw_quaternion,
)

__all__ = [
    "BLOCK_COLORS_RGB",
    "SCAN_BEAMS",
    "block_markers",
    "diagnostics",
    "laser_scan",
    "occupancy_grid",
    "odometry",
]


OK, WARN, ERROR = 0, 1, 2
BLOCK_COLORS_RGB = {"red": (0.9, 0.1, 0.1), "green": (0.1, 0.8, 0.2),
                    "blue": (0.1, 0.3, 0.9), "yellow": (0.95, 0.85, 0.1)}


def diagnostics(t_s: float, state: StateReader, joint_names: Sequence[str],
                halted: str | None) -> Any:
    """One DiagnosticStatus per servo (its joint's name; temperature C, voltage V, torque,
    alarms) and one for the bus (halted or not)."""
    status = message_class("diagnostic_msgs/msg/DiagnosticStatus")
    pair = message_class("diagnostic_msgs/msg/KeyValue")
    names = {**dict(zip(state.arm.config.servo_ids[:len(joint_names)], joint_names,
                        strict=False)), state.arm.config.gripper.servo_id: "gripper"}
    out = []
    for s in state.servos.values():
        alarms = s.alarms()
        level = ERROR if s.error else WARN if alarms else OK
        values = [pair(key="temperature_c", value=_num(s.temp_c)),
                  pair(key="voltage_v", value=_num(s.vin_v)),
                  pair(key="torque", value="" if s.torque_on is None else
                       ("on" if s.torque_on else "off"))]
        out.append(status(level=level, name=f"busarm/servo {s.servo_id} "
                          f"({names.get(s.servo_id, '?')})",
                          message="; ".join(alarms) or "OK", hardware_id=str(s.servo_id),
                          values=values))
    out.append(status(level=ERROR if halted else OK, name="busarm/bus",
                      message=f"halted: {halted}" if halted else "armed",
                      hardware_id="bus", values=[]))
    return message_class(DIAGNOSTIC_ARRAY)(header=header(t_s, ""), status=out)


def _num(value: float | None) -> str:
    return "" if value is None else f"{value:g}"


def block_markers(t_s: float, sightings: Sequence[Sighting],
                  frame_id: str = "base_link") -> Any:
    """Each block as a cube in its colour where it stands (RViz shows them); a
    DELETEALL first, so blocks no longer seen go."""
    marker = message_class("visualization_msgs/msg/Marker")
    out = [_marker(marker, t_s, frame_id, 0, action=3)]  # DELETEALL
    for k, s in enumerate(sightings, start=1):
        loc = s.location
        out.append(_marker(marker, t_s, frame_id, k, action=0, color=s.color,
                           xyz=(loc.x_mm / 1000, loc.y_mm / 1000, loc.z_mm / 1000),
                           yaw_rad=math.radians(loc.yaw_deg)))
    return message_class(MARKER_ARRAY)(markers=out)


def _marker(cls: Any, t_s: float, frame_id: str, k: int, *, action: int,
            color: str = "", xyz: tuple[float, float, float] = (0.0, 0.0, 0.0),
            yaw_rad: float = 0.0) -> Any:
    r, g, b = BLOCK_COLORS_RGB.get(color, (0.6, 0.6, 0.6))
    geo = "geometry_msgs/msg/"
    pose = message_class(geo + "Pose")(
        position=message_class(geo + "Point")(x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=yaw_quaternion(yaw_rad))
    duration = message_class("builtin_interfaces/msg/Duration")
    return cls(
        header=header(t_s, frame_id), ns=color or "blocks", id=k, type=1, action=action,
        pose=pose, scale=message_class(geo + "Vector3")(x=0.03, y=0.03, z=0.03),
        color=message_class("std_msgs/msg/ColorRGBA")(r=r, g=g, b=b, a=1.0),
        lifetime=duration(sec=1, nanosec=0), frame_locked=False, points=[], colors=[],
        texture_resource="", texture=message_class("sensor_msgs/msg/CompressedImage")(
            header=header(0.0, ""), format="", data=np.zeros(0, dtype=np.uint8)),
        uv_coordinates=[], text=color, mesh_resource="",
        mesh_file=message_class("visualization_msgs/msg/MeshFile")(
            filename="", data=np.zeros(0, dtype=np.uint8)),
        mesh_use_embedded_materials=False)


def laser_scan(t_s: float, scan: LaserScan, frame_id: str) -> Any:
    """The scan at one beam a degree from -180 deg (NaN-free: no return is +inf, as
    REP 117 has it)."""
    increment = 2 * math.pi / SCAN_BEAMS
    ranges, intensities = even_beams(scan, SCAN_BEAMS)
    scan_time = scan.scan_time_s if math.isfinite(scan.scan_time_s) else 0.0
    return message_class(LASER_SCAN)(
        header=header(t_s, frame_id), angle_min=-math.pi,
        angle_max=-math.pi + increment * (SCAN_BEAMS - 1), angle_increment=increment,
        time_increment=scan_time / SCAN_BEAMS, scan_time=scan_time,
        range_min=scan.range_min_m, range_max=scan.range_max_m, ranges=ranges,
        intensities=intensities)


def odometry(t_s: float, odom: BaseOdometry, frame_id: str, child_frame_id: str) -> Any:
    """The base's pose in ``frame_id`` and its twist in its own frame."""
    geo = "geometry_msgs/msg/"
    p, v = odom.pose, odom.twist
    pose = message_class(geo + "Pose")(
        position=message_class(geo + "Point")(x=p.x_m, y=p.y_m, z=0.0),
        orientation=yaw_quaternion(p.yaw_rad))
    vec = message_class(geo + "Vector3")
    twist = message_class(geo + "Twist")(linear=vec(x=v.vx_m_s, y=v.vy_m_s, z=0.0),
                                         angular=vec(x=0.0, y=0.0, z=v.wz_rad_s))
    return message_class(ODOMETRY)(
        header=header(t_s, frame_id), child_frame_id=child_frame_id,
        pose=message_class(geo + "PoseWithCovariance")(pose=pose,
                                                       covariance=np.zeros(36)),
        twist=message_class(geo + "TwistWithCovariance")(twist=twist,
                                                         covariance=np.zeros(36)))


def occupancy_grid(t_s: float, grid: OccupancyGrid, frame_id: str = "map") -> Any:
    """A saved map as map_server publishes it (trinary: 100 occupied, 0 free, -1
    unknown, by the map file's thresholds; the first row is the one at the origin)."""
    data = trinary_cells(grid)
    s, geo = grid.spec, "geometry_msgs/msg/"
    origin = message_class(geo + "Pose")(
        position=message_class(geo + "Point")(x=float(s.origin_x_m), y=float(s.origin_y_m),
                                              z=0.0),
        orientation=yaw_quaternion(0.0))
    info = message_class("nav_msgs/msg/MapMetaData")(
        map_load_time=stamp(t_s), resolution=float(s.resolution_m), width=s.width,
        height=s.height, origin=origin)
    return message_class(OCCUPANCY_GRID)(header=header(t_s, frame_id), info=info,
                                         data=data.reshape(-1))
