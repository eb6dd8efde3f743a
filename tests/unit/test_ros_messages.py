"""ROS 2 messages made from busarm's values: CDR that rosbags reads back to the same
values, frames that agree with the URDF a real parser reads, commands checked whole."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yourdfpy

from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.arm.urdf import write_urdf
from busarm.base.config import Mount
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError, ProtocolError
from busarm.lidar.scan import LaserScan
from busarm.robot.frames import arm_frames, base_frames
from busarm.ros import messages as m
from busarm.ros.sensors import SCAN_BEAMS, laser_scan

CONFIG = load_arm_config("jetauto_pro")


def roundtrip(msg: Any, type_name: str) -> Any:
    raw = m.encode(msg, type_name)
    assert raw[:4] == b"\x00\x01\x00\x00"  # CDR, little-endian
    return m.decode(raw, type_name)


def test_a_joint_state_reads_back() -> None:
    msg = roundtrip(m.joint_state(12.25, ["a", "b"], [0.5, -1.0]), m.JOINT_STATE)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 250_000_000)
    assert msg.name == ["a", "b"] and msg.position.tolist() == [0.5, -1.0]


def test_an_image_reads_back_pixel_for_pixel() -> None:
    image = np.random.default_rng(1).integers(0, 256, (48, 64, 3), dtype=np.uint8)
    msg = roundtrip(m.image_bgr(1.0, "cam", image), m.IMAGE)
    assert (msg.width, msg.height, msg.step, msg.encoding) == (64, 48, 192, "bgr8")
    assert np.array_equal(m.image_array(msg), image)
    msg.encoding = "rgb8"
    assert np.array_equal(m.image_array(msg), image[:, :, ::-1])
    msg.encoding = "mono16"
    with pytest.raises(ConfigError, match="allowed: bgr8, rgb8"):
        m.image_array(msg)


def test_camera_info_has_k_and_p_of_the_camera_matrix() -> None:
    k = [[500.0, 0, 320.5], [0, 501.0, 240.25], [0, 0, 1]]
    msg = roundtrip(m.camera_info(0.0, "cam", 640, 480, k, [0.1, -0.2, 0.001, 0.002],
                                  "pinhole"), m.CAMERA_INFO)
    assert msg.distortion_model == "plumb_bob" and msg.d.tolist() == [0.1, -0.2, 0.001,
                                                                      0.002, 0.0]
    assert msg.k.reshape(3, 3).tolist() == k
    assert msg.p.reshape(3, 4)[:, :3].tolist() == k


def test_a_malformed_payload_is_a_protocol_error() -> None:
    raw = m.encode(m.joint_state(0.0, ["a"], [1.0]), m.JOINT_STATE)
    for bad in (raw[:10], b"", b"\x00\x01\x00\x00" + b"\xff" * 40):
        with pytest.raises(ProtocolError, match="malformed sensor_msgs/msg/JointState"):
            m.decode(bad, m.JOINT_STATE)


def test_arm_frames_agree_with_the_urdf_read_by_a_urdf_parser(tmp_path: Path) -> None:
    urdf = yourdfpy.URDF.load(str(write_urdf(CONFIG, tmp_path / "arm.urdf")),
                              load_meshes=False, build_collision_scene_graph=False,
                              load_collision_meshes=False)
    kin = ArmKinematics.from_config(CONFIG)
    joints = [20.0, -70.0, 95.0, -30.0, 40.0]
    urdf.update_cfg({j.name: math.radians(v) for j, v in zip(CONFIG.joints, joints,
                                                              strict=True)})
    chain, previous = np.eye(4), "base_link"
    for parent, child, transform in arm_frames(CONFIG, kin, joints):
        assert parent == previous  # a chain, as the URDF's joints make it
        chain, previous = chain @ transform, child
        assert np.allclose(urdf.get_transform(child, "base_link"), chain, atol=1e-9), child
    # The transform message carries the same rotation and translation.
    parent, child, x = arm_frames(CONFIG, kin, joints)[2]
    msg = roundtrip(m.tf_message([m.transform(0.0, parent, child, x)]), m.TF_MESSAGE)
    q = msg.transforms[0].transform.rotation
    from scipy.spatial.transform import Rotation
    assert np.allclose(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), x[:3, :3])


def test_the_base_is_in_odom_and_its_mounts_on_it() -> None:
    frames = base_frames(Pose2D(1.0, 2.0, math.pi / 2), Mount(0.1, 0.0, 0.15, 0.0),
                         Mount(0.05, 0.0, 0.2, math.pi))
    names = [(p, c) for p, c, _ in frames]
    assert names == [("odom", "base_footprint"), ("base_footprint", "base_link"),
                     ("base_footprint", "laser")]
    laser_in_odom = frames[0][2] @ frames[2][2]
    assert np.allclose(laser_in_odom[:3, 3], [1.0, 2.05, 0.2])


def test_a_scan_becomes_one_beam_a_degree_nearest_return_kept() -> None:
    angles = np.radians([0.2, 0.4, 90.0, -179.9, 179.8])
    ranges = np.array([2.0, 1.5, 3.0, 0.7, np.nan])
    scan = LaserScan(angles, ranges, np.array([10.0, 20.0, 30.0, 40.0, 0.0]), 0.0, 0.15,
                     12.0, scan_time_s=0.1)
    msg = roundtrip(laser_scan(5.0, scan, "laser"), m.LASER_SCAN)
    assert len(msg.ranges) == SCAN_BEAMS and msg.angle_min == pytest.approx(-math.pi)  # float32
    beam = lambda deg: round((math.radians(deg) + math.pi) / msg.angle_increment) % 360  # noqa: E731
    assert msg.ranges[beam(0.0)] == pytest.approx(1.5) and msg.intensities[beam(0.0)] == 20
    assert msg.ranges[beam(90.0)] == pytest.approx(3.0)
    assert msg.ranges[beam(-180.0)] == pytest.approx(0.7)  # -179.9 deg is the -180 beam
    assert np.isinf(msg.ranges).sum() == SCAN_BEAMS - 3  # no return: +inf (REP 117)


def _trajectory(names: list[str], points: list[tuple[float, list[float]]]) -> Any:
    point = m.message_class("trajectory_msgs/msg/JointTrajectoryPoint")
    duration = m.message_class("builtin_interfaces/msg/Duration")
    empty = np.zeros(0)
    msg = m.message_class(m.JOINT_TRAJECTORY)(header=m.header(0.0, ""), joint_names=names,
                                               points=[point(
        positions=np.asarray(p, dtype=np.float64), velocities=empty, accelerations=empty,
        effort=empty, time_from_start=duration(sec=int(t), nanosec=round(t % 1 * 1e9)))
        for t, p in points])
    return roundtrip(msg, m.JOINT_TRAJECTORY)


NAMES = [j.name for j in CONFIG.joints]


def test_a_trajectory_is_read_in_degrees_and_seconds() -> None:
    got = m.parse_trajectory(_trajectory(["elbow_pitch", "base_yaw"],
                                         [(0.5, [1.0, 0.1]), (1.25, [1.2, 0.2])]), NAMES)
    assert got.joint_names == ("elbow_pitch", "base_yaw")
    assert got.times_s == (0.5, 1.25)
    assert got.positions_deg[1] == pytest.approx((math.degrees(1.2), math.degrees(0.2)))


@pytest.mark.parametrize(("names", "points", "match"), [
    (["elbow"], [(1.0, [0.0])], "unknown: \\['elbow'\\]"),
    (["base_yaw", "base_yaw"], [(1.0, [0.0, 0.0])], "at most once"),
    (["base_yaw"], [], "a trajectory of 0 points"),
    (["base_yaw"], [(0.0, [0.0])], "time_from_start 0 s"),
    (["base_yaw"], [(1.0, [0.0]), (1.0, [0.1])], "point 1: time_from_start 1 s"),
    (["base_yaw"], [(1.0, [0.0, 1.0])], "1 finite angles in rad"),
    (["base_yaw"], [(1.0, [math.nan])], "1 finite angles"),
    (["base_yaw"], [(400.0, [0.0])], "at most 300 s"),
])
def test_a_bad_trajectory_is_refused_naming_what_is_wrong(
        names: list[str], points: list[tuple[float, list[float]]], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        m.parse_trajectory(_trajectory(names, points), NAMES)


def test_a_twist_must_be_finite() -> None:
    vec = m.message_class("geometry_msgs/msg/Vector3")
    twist = m.message_class(m.TWIST)(linear=vec(x=0.1, y=-0.2, z=5.0),
                                     angular=vec(x=1.0, y=1.0, z=0.3))
    assert m.parse_twist(roundtrip(twist, m.TWIST)) == pytest.approx((0.1, -0.2, 0.3))
    twist.angular.z = math.inf
    with pytest.raises(ConfigError, match="finite"):
        m.parse_twist(twist)


def test_a_map_is_published_as_map_server_does() -> None:
    from busarm.nav.grid import GridSpec, OccupancyGrid
    from busarm.ros.sensors import occupancy_grid

    spec = GridSpec(origin_x_m=-1.0, origin_y_m=0.5, resolution_m=0.05, width=4, height=3)
    log_odds = np.zeros((3, 4))
    log_odds[0, 0] = 5.0  # the cell at the origin: occupied
    log_odds[2, 3] = -5.0  # the far corner (highest x and y): free
    msg = roundtrip(occupancy_grid(1.0, OccupancyGrid(spec, log_odds)), m.OCCUPANCY_GRID)
    assert (msg.info.width, msg.info.height) == (4, 3)
    assert msg.info.resolution == pytest.approx(0.05)
    assert (msg.info.origin.position.x, msg.info.origin.position.y) == (-1.0, 0.5)
    assert msg.header.frame_id == "map"
    assert msg.data[0] == 100 and msg.data[11] == 0 and list(msg.data[1:11]) == [-1] * 10
