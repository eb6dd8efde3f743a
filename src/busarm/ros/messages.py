"""ROS 2 messages from and to busarm's values, as CDR bytes (rosbags' Jazzy typestore).

Builders take busarm's values in their own units (deg, mm, s) and make the ROS message in
ROS's (rad, m, stamps); parsers check an incoming message field by field and give it back
in busarm's units, or raise ConfigError naming the bad value and what is allowed. CDR
itself (and each type's RIHS01 hash) is rosbags': nothing here writes bytes by hand.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np
import numpy.typing as npt
from rosbags.typesys import Stores, get_typestore

from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.rmw_zenoh import check_ros_type
from busarm.rotations import quaternion_wxyz

__all__ = [
    "CAMERA_INFO",
    "COMPRESSED_IMAGE",
    "DIAGNOSTIC_ARRAY",
    "EMPTY",
    "FLOAT64",
    "IMAGE",
    "JOINT_STATE",
    "JOINT_TRAJECTORY",
    "LASER_SCAN",
    "MARKER_ARRAY",
    "MAX_TRAJECTORY_POINTS",
    "MAX_TRAJECTORY_S",
    "OCCUPANCY_GRID",
    "ODOMETRY",
    "ROSOUT_LOG",
    "STRING",
    "TF_MESSAGE",
    "TWIST",
    "TYPESTORE",
    "RosType",
    "Trajectory",
    "camera_info",
    "compressed_jpeg",
    "decode",
    "encode",
    "header",
    "image_array",
    "image_bgr",
    "joint_state",
    "message_class",
    "parse_trajectory",
    "parse_twist",
    "quaternion_xyzw",
    "ros_type",
    "stamp",
    "stamp_s",
    "string",
    "tf_message",
    "transform",
    "yaw_quaternion",
]


TYPESTORE = get_typestore(Stores.ROS2_JAZZY)

JOINT_STATE = "sensor_msgs/msg/JointState"
JOINT_TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
ODOMETRY = "nav_msgs/msg/Odometry"
OCCUPANCY_GRID = "nav_msgs/msg/OccupancyGrid"
TWIST = "geometry_msgs/msg/Twist"
STRING = "std_msgs/msg/String"
FLOAT64 = "std_msgs/msg/Float64"
EMPTY = "std_msgs/msg/Empty"
ROSOUT_LOG = "rcl_interfaces/msg/Log"

MAX_TRAJECTORY_POINTS = 10_000
MAX_TRAJECTORY_S = 300.0


@dataclass(frozen=True)
class RosType:
    """A message type: its name (``pkg/msg/Name``) and RIHS01 hash."""

    name: str
    type_hash: str


@cache
def ros_type(name: str) -> RosType:
    """The type ``name`` as this typestore knows it; ConfigError if it does not."""
    check_ros_type(name)
    if name not in TYPESTORE.types:
        raise ConfigError(f"unknown ROS 2 message type {name!r}")
    return RosType(name, TYPESTORE.hash_rihs01(name))


def encode(message: Any, type_name: str) -> bytes:
    """The message as CDR bytes (little-endian, with the encapsulation header)."""
    return bytes(TYPESTORE.serialize_cdr(message, type_name))


def decode(data: bytes, type_name: str) -> Any:
    """The message in ``data``; ProtocolError when it is not a well-formed one."""
    try:
        return TYPESTORE.deserialize_cdr(data, type_name)
    except Exception as exc:  # rosbags raises what its parser meets: struct.error, ...
        raise ProtocolError(f"malformed {type_name} CDR payload ({len(data)} bytes): "
                            f"{type(exc).__name__}: {exc}") from exc


def message_class(type_name: str) -> Any:
    return TYPESTORE.types[type_name]


# ------------------------------------------------------------------ stamps


def stamp(t_s: float) -> Any:
    """A builtin_interfaces/Time for ``t_s`` seconds (since the epoch, or the clock's 0)."""
    sec = math.floor(t_s)
    nanosec = min(round((t_s - sec) * 1e9), 999_999_999)
    return message_class("builtin_interfaces/msg/Time")(sec=int(sec), nanosec=int(nanosec))


def stamp_s(time_msg: Any) -> float:
    return float(time_msg.sec) + float(time_msg.nanosec) * 1e-9


def header(t_s: float, frame_id: str) -> Any:
    return message_class("std_msgs/msg/Header")(stamp=stamp(t_s), frame_id=frame_id)


# ------------------------------------------------------------------ builders


def joint_state(t_s: float, names: Sequence[str], positions_rad: Sequence[float]) -> Any:
    return message_class(JOINT_STATE)(
        header=header(t_s, ""), name=list(names),
        position=np.asarray(positions_rad, dtype=np.float64),
        velocity=np.zeros(0, dtype=np.float64), effort=np.zeros(0, dtype=np.float64))


def string(text: str) -> Any:
    return message_class(STRING)(data=text)


def image_bgr(t_s: float, frame_id: str, image: npt.NDArray[np.uint8]) -> Any:
    """A ``bgr8`` sensor_msgs/Image of an OpenCV frame (rows top first)."""
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ConfigError(f"an image to publish is H x W x 3 uint8 (BGR), got {image.shape} "
                          f"{image.dtype}")
    height, width = image.shape[:2]
    return message_class(IMAGE)(
        header=header(t_s, frame_id), height=height, width=width, encoding="bgr8",
        is_bigendian=0, step=width * 3, data=np.ascontiguousarray(image).reshape(-1))


def image_array(msg: Any) -> npt.NDArray[np.uint8]:
    """A ``bgr8`` or ``rgb8`` sensor_msgs/Image as an OpenCV (BGR) frame; ConfigError if
    it is another encoding or its size does not add up."""
    if msg.encoding not in ("bgr8", "rgb8"):
        raise ConfigError(f"image encoding {msg.encoding!r}; allowed: bgr8, rgb8")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.asarray(msg.data, dtype=np.uint8)
    if step < w * 3 or data.size != h * step:
        raise ConfigError(f"a {w} x {h} image with step {step} needs {h * step} bytes, got "
                          f"{data.size}")
    rows = data.reshape(h, step)[:, :w * 3].reshape(h, w, 3)
    return np.ascontiguousarray(rows if msg.encoding == "bgr8" else rows[:, :, ::-1])


def compressed_jpeg(t_s: float, frame_id: str, jpeg: bytes) -> Any:
    return message_class(COMPRESSED_IMAGE)(
        header=header(t_s, frame_id), format="jpeg",
        data=np.frombuffer(jpeg, dtype=np.uint8))


def camera_info(t_s: float, frame_id: str, width_px: int, height_px: int,
                camera_matrix: npt.ArrayLike, distortion: Sequence[float],
                model: str) -> Any:
    """CameraInfo of a pinhole (``plumb_bob``/``rational_polynomial``) or fisheye
    (``equidistant``) lens: K from the camera matrix, P = [K | 0], R the identity."""
    k = np.asarray(camera_matrix, dtype=np.float64).reshape(3, 3)
    d = [float(v) for v in distortion]
    name = ("equidistant" if model == "fisheye"
            else "rational_polynomial" if len(d) == 8 else "plumb_bob")
    if name == "plumb_bob":
        d = (d + [0.0] * 5)[:5]
    p = np.zeros((3, 4))
    p[:, :3] = k
    roi = message_class("sensor_msgs/msg/RegionOfInterest")(
        x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    return message_class(CAMERA_INFO)(
        header=header(t_s, frame_id), height=height_px, width=width_px,
        distortion_model=name, d=np.asarray(d, dtype=np.float64), k=k.reshape(-1),
        r=np.eye(3).reshape(-1), p=p.reshape(-1), binning_x=0, binning_y=0, roi=roi)


def transform(t_s: float, parent: str, child: str, matrix_m: npt.ArrayLike) -> Any:
    """A geometry_msgs/TransformStamped of a 4 x 4 homogeneous transform in metres."""
    m = np.asarray(matrix_m, dtype=np.float64)
    x, y, z, w = quaternion_xyzw(m[:3, :3])
    vec = message_class("geometry_msgs/msg/Vector3")(x=float(m[0, 3]), y=float(m[1, 3]),
                                                     z=float(m[2, 3]))
    rot = message_class("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w)
    return message_class("geometry_msgs/msg/TransformStamped")(
        header=header(t_s, parent), child_frame_id=child,
        transform=message_class("geometry_msgs/msg/Transform")(translation=vec, rotation=rot))


def tf_message(transforms: Sequence[Any]) -> Any:
    return message_class(TF_MESSAGE)(transforms=list(transforms))


def quaternion_xyzw(rotation: npt.ArrayLike) -> tuple[float, float, float, float]:
    """A rotation matrix as a unit quaternion in ROS's order (x, y, z, w), w >= 0."""
    w, x, y, z = quaternion_wxyz(rotation)
    return x, y, z, w


def yaw_quaternion(yaw_rad: float) -> Any:
    return message_class("geometry_msgs/msg/Quaternion")(
        x=0.0, y=0.0, z=math.sin(yaw_rad / 2), w=math.cos(yaw_rad / 2))


# ------------------------------------------------------------------ parsers


@dataclass(frozen=True)
class Trajectory:
    """A checked JointTrajectory: joint names, times after its start (s, increasing) and
    at each time every named joint's angle (deg)."""

    joint_names: tuple[str, ...]
    times_s: tuple[float, ...]
    positions_deg: tuple[tuple[float, ...], ...]


def parse_trajectory(msg: Any, known_joints: Sequence[str]) -> Trajectory:
    """A JointTrajectory checked for what can be checked without the arm: joint names
    known and not repeated, 1..MAX_TRAJECTORY_POINTS points, each with one finite position
    per joint, times increasing from > 0 to at most MAX_TRAJECTORY_S (the arm's own limits
    are the caller's to check)."""
    names = tuple(str(n) for n in msg.joint_names)
    unknown = [n for n in names if n not in known_joints]
    if not names or unknown or len(set(names)) != len(names):
        raise ConfigError(f"trajectory joint_names {list(names)}: give each of "
                          f"{', '.join(known_joints)} at most once (unknown: {unknown})")
    points = list(msg.points)
    if not 1 <= len(points) <= MAX_TRAJECTORY_POINTS:
        raise ConfigError(f"a trajectory of {len(points)} points; allowed: 1.."
                          f"{MAX_TRAJECTORY_POINTS}")
    times: list[float] = []
    positions: list[tuple[float, ...]] = []
    for k, point in enumerate(points):
        t = float(point.time_from_start.sec) + float(point.time_from_start.nanosec) * 1e-9
        low = times[-1] if times else 0.0
        if not low < t <= MAX_TRAJECTORY_S:
            raise ConfigError(f"trajectory point {k}: time_from_start {t:g} s; allowed: "
                              f"more than {low:g} s (the point before), at most "
                              f"{MAX_TRAJECTORY_S:g} s")
        values = [float(v) for v in point.positions]
        if len(values) != len(names) or not all(math.isfinite(v) for v in values):
            raise ConfigError(f"trajectory point {k}: positions {values}; allowed: "
                              f"{len(names)} finite angles in rad, one per joint name")
        times.append(t)
        positions.append(tuple(math.degrees(v) for v in values))
    return Trajectory(names, tuple(times), tuple(positions))


def parse_twist(msg: Any) -> tuple[float, float, float]:
    """(vx m/s, vy m/s, wz rad/s) of a geometry_msgs/Twist; ConfigError if any is not
    finite (linear.z, angular.x and angular.y are ignored: a floor robot)."""
    values = (float(msg.linear.x), float(msg.linear.y), float(msg.angular.z))
    if not all(math.isfinite(v) for v in values):
        raise ConfigError(f"cmd_vel (linear.x, linear.y, angular.z) = {values}: each must "
                          "be a finite number")
    return values
