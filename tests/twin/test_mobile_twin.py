"""The mobile twin through the real path:
``Robot.open(RobotConfig(TwinSpec(family="arena", ..., controller=BoardSettings())))``
drives the twin's chassis with the Base on the simulated controller board, and reads the
twin's ray-cast Lidar through the simulated A1's bytes. The twin's truth (the chassis's
pose, its path, noise-free ranges, the arena's geometry) is read only here, in the tests.

Everything runs on the twin's simulated clock: a drive of a few simulated seconds takes
about as long on the wall clock.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from itertools import pairwise

import numpy as np
import pytest

from busarm.base.odometry import Pose2D, wrap_rad
from busarm.errors import ConfigError
from busarm.lidar.scan import LaserScan
from busarm.protocol.board import BoardReport
from busarm.protocol.rplidar import A1_RANGE_MAX_M, A1_RANGE_MIN_M
from busarm.robot import BaseSpec, CameraSpec, RobotConfig
from busarm.robot.robot import Robot
from busarm.sim.spec import BoardSettings, SimSpec
from busarm.twin.arena import Arena, Room, Solid, StartPose
from busarm.twin.arena_model import CHASSIS_SIZE_M
from busarm.twin.lidar import LidarNoise, TwinLidarWorld
from busarm.twin.mobile import PATH_PERIOD_S
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

ARENA_1 = TwinSpec(family="arena", seed=1, controller=BoardSettings())
HALF_LENGTH_M = CHASSIS_SIZE_M[0] / 2
Q2_M = 0.00025
"""The A1's range quantum on the wire (a quarter millimetre)."""
BEAM_RAD = 2 * math.pi / 200
"""The twin's A1: 2000 samples/s at 10 revolutions/s, 1.8 degrees apart."""


@contextmanager
def robot_on(world: TwinSpec) -> Iterator[tuple[Robot, Twin]]:
    """The robot in ``world`` (no camera calibration) and its twin, for the truth."""
    with Robot.open(RobotConfig(world, camera=CameraSpec(calibrate=False))) as robot:
        assert robot.twin is not None
        yield robot, robot.twin


def true_pose(twin: Twin) -> Pose2D:
    """Where the chassis really is now (arena frame)."""
    twin.sync()
    assert twin.mobile is not None
    with twin.lock:
        return twin.mobile.pose(twin.data)


def lidar_origin(twin: Twin) -> tuple[float, float, float]:
    """The Lidar's true (x, y, heading) in the arena, from the chassis's pose and the
    Lidar's place on the chassis config."""
    pose = true_pose(twin)
    assert twin.chassis is not None
    mount = twin.chassis.lidar
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    return (pose.x_m + c * mount.x_m - s * mount.y_m, pose.y_m + s * mount.x_m + c * mount.y_m,
            pose.yaw_rad + mount.yaw_rad)


def scans(robot: Robot, count: int) -> list[LaserScan]:
    assert robot.lidar is not None
    return [robot.lidar.read_scan(timeout_s=1.0) for _ in range(count)]


def range_at(scan: LaserScan, bearing_rad: float) -> float:
    """The scan's range on the beam nearest ``bearing_rad``."""
    diff = np.abs(np.remainder(scan.angles_rad - bearing_rad + math.pi, 2 * math.pi) - math.pi)
    return float(scan.ranges_m[int(np.argmin(diff))])


def drive_for(robot: Robot, seconds: float, vx_m_s: float, vy_m_s: float, wz_rad_s: float,
              step_s: float = 0.05) -> None:
    """``base.drive`` repeated every ``step_s`` for ``seconds`` of the robot's clock."""
    assert robot.base is not None
    end = robot.clock.now() + seconds
    while robot.clock.now() < end:
        robot.base.drive(vx_m_s, vy_m_s, wz_rad_s)
        robot.clock.sleep(step_s)


def stop_and_settle(robot: Robot) -> None:
    assert robot.base is not None
    robot.base.stop()
    robot.base.wait_stopped()


# ---------------------------------------------------------------------- the base


@pytest.mark.parametrize("slip", [True, False], ids=["slip", "no-slip"])
def test_move_by_moves_the_chassis_along_its_heading(slip: bool) -> None:
    with robot_on(replace(ARENA_1, slip=slip)) as (robot, twin):
        assert robot.base is not None and robot.lidar is not None
        assert robot.base.odometry_source == "encoders"
        start = true_pose(twin)
        assert twin.arena is not None
        assert start.yaw_deg == pytest.approx(twin.arena.start.yaw_deg, abs=0.01)
        said = robot.base.move_by(0.5, 0.0, 0.0)
        moved = true_pose(twin).relative_to(start)  # in the start's frame: x ahead
        odometry = robot.base.odometry().pose
        assert said.x_m == pytest.approx(0.5, abs=0.005)
        assert abs(moved.y_m) < 0.01
        if slip:  # the floor took a little less than the wheels turned
            assert 0.46 < moved.x_m < odometry.x_m - 0.003
            assert moved.x_m < 0.5
        else:
            assert moved.x_m == pytest.approx(0.5, abs=0.005)
            assert odometry.x_m == pytest.approx(moved.x_m, abs=0.002)
            assert odometry.y_m == pytest.approx(moved.y_m, abs=0.002)
            assert math.degrees(odometry.yaw_rad) == pytest.approx(
                math.degrees(moved.yaw_rad), abs=0.2)


def test_a_wall_stops_the_base_while_its_wheels_spin_on() -> None:
    room = Room(-0.6, 0.6, -0.6, 0.6)  # the +x wall's face at x = 0.6 m
    arena = Arena(room=room, start=StartPose(0.0, 0.0, 0.0), name="wall ahead")
    with robot_on(TwinSpec(arena=arena, controller=BoardSettings())) as (robot, twin):
        assert robot.base is not None
        front_m = []
        end = robot.clock.now() + 3.0  # 0.45 m to the wall; the drive asks for about 0.9
        while robot.clock.now() < end:
            robot.base.drive(0.3, 0.0, 0.0)
            robot.clock.sleep(0.05)
            front_m.append(true_pose(twin).x_m + HALF_LENGTH_M)
        stop_and_settle(robot)
        truth = true_pose(twin)
        odometry = robot.base.odometry().pose
    assert max(front_m) <= room.x_max_m + 0.003  # against it, never through it
    assert front_m[-1] > room.x_max_m - 0.01  # and it did reach it
    assert abs(truth.y_m) < 0.01 and abs(truth.yaw_deg) < 1.0
    assert odometry.x_m > truth.x_m + 0.2  # the encoders counted the wheels spinning


def test_twin_without_a_board_has_a_lidar_but_no_base() -> None:
    with robot_on(TwinSpec(family="arena", seed=1)) as (robot, _twin):
        assert robot.base is None
        assert robot.lidar is not None
        assert np.count_nonzero(scans(robot, 1)[0].valid) > 100
    with pytest.raises(ConfigError, match="board://"):
        Robot.open(RobotConfig(SimSpec(), base=BaseSpec("jetauto"),
                               camera=CameraSpec(calibrate=False)))


def test_odometry_sees_every_report_while_servo_reads_take_them() -> None:
    with robot_on(replace(ARENA_1, slip=False)) as (robot, twin):
        base = robot.base
        assert base is not None
        in_reads: list[int] = [0]
        reading = [False]

        def count(_report: BoardReport, _at_s: float) -> None:
            in_reads[0] += reading[0]

        base.link.add_listener(count)
        start = true_pose(twin)
        odom_start = base.odometry().pose
        end = robot.clock.now() + 2.0
        while robot.clock.now() < end:
            base.drive(0.0, 0.0, 0.5)
            reading[0] = True
            robot.arm.read_joints_deg()
            reading[0] = False
        stop_and_settle(robot)
        turned_deg = math.degrees(true_pose(twin).relative_to(start).yaw_rad)
        odom_deg = math.degrees(wrap_rad(base.odometry().pose.yaw_rad - odom_start.yaw_rad))
    assert in_reads[0] > 100  # the servo reads took most of the board's reports
    assert turned_deg > 40  # ~0.5 rad/s for 2 s, after the ramp
    assert odom_deg == pytest.approx(turned_deg, abs=0.5)


def test_the_true_path_follows_the_chassis() -> None:
    with robot_on(replace(ARENA_1, slip=False)) as (robot, twin):
        assert twin.mobile is not None
        path = twin.mobile.path
        start = true_pose(twin)
        before = len(path)
        t0 = robot.clock.now()
        drive_for(robot, 1.0, 0.2, 0.0, 0.0)
        during = true_pose(twin)
        _t, x, y = path[-1]
        assert math.hypot(x - during.x_m, y - during.y_m) <= 0.2 * PATH_PERIOD_S + 0.002
        stop_and_settle(robot)
        robot.clock.sleep(0.2)
        here = true_pose(twin)
        elapsed_s = robot.clock.now() - t0
        added = path[before:]
        t_last, x_last, y_last = path[-1]
    assert len(added) >= elapsed_s / PATH_PERIOD_S - 2
    assert t_last == pytest.approx(twin.sim_time_s, abs=PATH_PERIOD_S)
    assert (x_last, y_last) == pytest.approx((here.x_m, here.y_m), abs=1e-4)
    # Every point on the straight line from the start to here, in order along it.
    c, s = math.cos(start.yaw_rad), math.sin(start.yaw_rad)
    along = [(px - start.x_m) * c + (py - start.y_m) * s for _t, px, py in added]
    across = [-(px - start.x_m) * s + (py - start.y_m) * c for _t, px, py in added]
    assert all(b >= a - 1e-6 for a, b in pairwise(along))
    assert max(abs(v) for v in across) < 0.005
    assert along[-1] == pytest.approx(here.relative_to(start).x_m, abs=1e-4)
    assert along[-1] > 0.1


# ---------------------------------------------------------------------- the Lidar


def test_lidar_without_noise_measures_the_true_ranges() -> None:
    with robot_on(TwinSpec(family="arena", seed=1, lidar_noise=False)) as (robot, twin):
        truth_world = TwinLidarWorld(twin, LidarNoise.none())
        for scan in scans(robot, 3):
            true = truth_world.true_ranges(scan.angles_rad)
            in_reach = (true >= A1_RANGE_MIN_M) & (true <= A1_RANGE_MAX_M)
            assert np.array_equal(scan.valid, in_reach)
            assert np.count_nonzero(in_reach) > 150
            assert np.max(np.abs(scan.ranges_m[in_reach] - true[in_reach])) < 0.01


def test_an_inner_wall_is_seen_by_the_lidar_and_stops_the_chassis() -> None:
    wall = Solid(1.5, 0.0, 0.1, 3.0, 0.3)  # across the whole room: no way round it
    arena = Arena(Room(-1.0, 3.0, -1.5, 1.5), start=StartPose(0.0, 0.0, 0.0), walls=(wall,))
    with robot_on(TwinSpec(arena=arena, controller=BoardSettings(), lidar_noise=False)
                  ) as (robot, twin):
        x, y, heading = lidar_origin(twin)
        ahead = range_at(scans(robot, 2)[-1], -heading)  # the beam along the arena's +x
        assert ahead == pytest.approx(wall.x_m - wall.size_x_m / 2 - x, abs=0.01)
        drive_for(robot, 8.0, 0.25, 0.0, 0.0)  # 2 m of driving toward a wall 1.3 m off
        stop_and_settle(robot)
        assert twin.mobile is not None
        assert "inner_wall0" in {name for _, name in twin.mobile.contacts}
        front = true_pose(twin).x_m + CHASSIS_SIZE_M[0] / 2
        assert front == pytest.approx(wall.x_m - wall.size_x_m / 2, abs=0.03)


def test_lidar_noise_is_unbiased_with_its_dropouts() -> None:
    noise = LidarNoise()
    with robot_on(TwinSpec(family="arena", seed=1)) as (robot, twin):
        truth_world = TwinLidarWorld(twin, LidarNoise.none())
        # The same rays, whose only loss is at grazing incidence: random dropouts are the
        # returns lost among these.
        grazing = TwinLidarWorld(twin, LidarNoise(0.0, 0.0, 0.0, noise.grazing_deg))
        residuals, lost, could = [], 0, 0
        for scan in scans(robot, 10):
            true = truth_world.true_ranges(scan.angles_rad)
            returns = np.array([grazing(float(b)) for b in scan.angles_rad])
            seen = np.isfinite(returns) & (returns >= A1_RANGE_MIN_M)
            could += int(np.count_nonzero(seen))
            lost += int(np.count_nonzero(seen & ~scan.valid))
            both = seen & scan.valid
            residuals += list(scan.ranges_m[both] - true[both])
    r = np.array(residuals)
    assert np.count_nonzero(np.abs(r) > 4 * Q2_M) > len(r) / 2
    assert abs(float(np.mean(r))) < 0.001
    assert 0.001 < float(np.std(r)) < 0.05
    assert could > 1500
    assert 0.4 * noise.dropout < lost / could < 2.0 * noise.dropout


def _nearest_m(x: float, y: float, room: Room, boxes: tuple[Solid, ...]) -> float:
    """From (x, y) to the nearest wall face or side of an upright (yaw 0) box."""
    walls = (x - room.x_min_m, room.x_max_m - x, y - room.y_min_m, room.y_max_m - y)
    to_boxes = [math.hypot(max(abs(x - b.x_m) - b.size_x_m / 2, 0.0),
                           max(abs(y - b.y_m) - b.size_y_m / 2, 0.0)) for b in boxes]
    return min(*walls, *to_boxes)


@pytest.mark.parametrize(("room", "start", "boxes", "bearing_deg"), [
    # An empty 3 x 3 m room, facing +x: the wall ahead is nearest.
    (Room(-1.5, 1.5, -1.5, 1.5), StartPose(0.0, 0.0, 0.0), (), 0.0),
    # Facing +y in a room wider to the right: the -x wall, on the Lidar's left.
    (Room(-1.0, 2.0, -1.5, 1.5), StartPose(0.0, 0.0, 90.0), (), 90.0),
    # A box ahead and to the right, its near side square to the beam at -90 degrees.
    (Room(-1.5, 1.5, -1.5, 1.5), StartPose(0.0, 0.0, 0.0),
     (Solid(0.06, -0.75, 0.6, 0.3, 0.3),), -90.0),
], ids=["empty", "turned", "box"])
def test_the_nearest_return_is_the_nearest_thing(room: Room, start: StartPose,
                                                 boxes: tuple[Solid, ...],
                                                 bearing_deg: float) -> None:
    arena = Arena(room=room, boxes=boxes, start=start, name="bare room")
    with robot_on(TwinSpec(arena=arena, lidar_noise=False)) as (robot, twin):
        x, y, _heading = lidar_origin(twin)
        expected_m = _nearest_m(x, y, room, boxes)
        for scan in scans(robot, 2):
            nearest = scan.nearest()
            assert nearest is not None
            range_m, bearing_rad = nearest
            assert range_m == pytest.approx(expected_m, abs=0.002)
            assert math.degrees(bearing_rad) == pytest.approx(bearing_deg, abs=0.01)


def test_a_box_moved_into_view_appears_in_the_scan() -> None:
    with robot_on(TwinSpec(family="arena", seed=1, lidar_noise=False)) as (robot, twin):
        before = scans(robot, 1)[0]
        distance_m = 0.6  # to the box's near face, straight ahead
        assert range_at(before, 0.0) > distance_m + 0.3  # nothing there yet
        assert twin.arena is not None
        box = twin.arena.boxes[0]
        x, y, heading = lidar_origin(twin)
        centre_m = distance_m + box.size_x_m / 2
        with twin.lock:  # a person steps in front of the robot, square to it
            mocap = int(twin.model.body("box0").mocapid[0])
            twin.data.mocap_pos[mocap] = (x + centre_m * math.cos(heading),
                                          y + centre_m * math.sin(heading), 0.0)
            twin.data.mocap_quat[mocap] = (math.cos(heading / 2), 0.0, 0.0,
                                           math.sin(heading / 2))
        scans(robot, 1)  # the revolution under way began before it stepped in
        after = scans(robot, 1)[0]
        true = TwinLidarWorld(twin, LidarNoise.none()).true_ranges(after.angles_rad)
    half_width_rad = math.atan2(box.size_y_m / 2, distance_m)
    bearing = np.remainder(after.angles_rad + math.pi, 2 * math.pi) - math.pi
    on_box = np.abs(bearing) < half_width_rad - BEAM_RAD
    beside = np.abs(bearing) > half_width_rad + BEAM_RAD
    assert np.count_nonzero(on_box) >= 3
    assert np.all(before.ranges_m[on_box] > distance_m + 0.3)  # clear before it came
    assert np.allclose(after.ranges_m[on_box], distance_m / np.cos(bearing[on_box]), atol=0.005)
    # Elsewhere the scan is the world as it is now (where the box stood, what is behind).
    assert np.array_equal(after.valid[beside], np.isfinite(true[beside]))
    assert np.allclose(after.ranges_m[beside], true[beside], atol=0.005, equal_nan=True)
