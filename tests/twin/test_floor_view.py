"""The floor line through the wrist camera on the arena twin's real renders.

The robot opens on the arena twin behind its board (``TwinSpec(family="arena", seed=N,
controller=BoardSettings())``) with the twin's camera
calibration made by our own flows (the session's ``twin_calibration``), poses the arm to
look ahead (``look_ahead``), and finds the tape in a captured frame through
``floor_camera``; neither reads the twin's truth. The test then compares with the truth:
the chassis's true pose, and the arena's tape centreline put into the base frame by it.
The base is set down on poses along the loop through the chassis's planar joints (the
twin's truth, as a person would carry the robot there), off the tape and turned a little.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest

from busarm.apps.line_follow.floor_look import floor_camera, look_ahead
from busarm.base.config import load_chassis_config
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.perception.floor_view import LOOK_AHEAD_DEG, FloorCamera
from busarm.robot import CameraSpec, RobotConfig
from busarm.robot.robot import Robot
from busarm.sim.spec import BoardSettings
from busarm.twin.arena import Arena, Room, StartPose
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

Points = npt.NDArray[np.float64]
SEEDS = (1, 2, 3)
ALONG = ((0.25, 0.03, 8.0), (0.5, -0.04, -10.0), (0.75, 0.02, 5.0))
"""Poses along the loop: (share of the loop from the start, metres left of the tape,
degrees turned from its direction)."""
LOOK_X_M = 0.25
"""Where the lateral offset is compared: ahead, in view."""


@contextmanager
def robot_on(world: TwinSpec, calibration: tuple[Path, Path]) -> Iterator[tuple[Robot, Twin]]:
    intrinsics, hand_eye = calibration
    with Robot.open(RobotConfig(world, camera=CameraSpec(intrinsics=intrinsics,
                                                         hand_eye=hand_eye))) as robot:
        assert robot.twin is not None
        yield robot, robot.twin


def true_pose(twin: Twin) -> Pose2D:
    twin.sync()
    assert twin.mobile is not None
    with twin.lock:
        return twin.mobile.pose(twin.data)


def set_down(twin: Twin, x_m: float, y_m: float, yaw_rad: float) -> None:
    """Put the chassis at (x, y, yaw) in the arena, standing still (the twin's truth)."""
    with twin.lock:
        for name, value in (("chassis_x", x_m), ("chassis_y", y_m), ("chassis_yaw", yaw_rad)):
            joint = twin.model.joint(name)
            twin.data.qpos[joint.qposadr[0]] = value
            twin.data.qvel[joint.dofadr[0]] = 0.0
        twin.mujoco.mj_forward(twin.model, twin.data)  # where the bodies are, for the camera


def poses_along(twin: Twin) -> list[tuple[float, float, float]]:
    """``ALONG``'s poses on the loop (arena frame)."""
    assert twin.arena is not None
    pts = twin.arena.lines[0].points_m
    n = len(pts)
    out = []
    for share, left_m, turn_deg in ALONG:
        i = (n // 2 + int(share * n)) % n  # the start is the loop's point n // 2
        (ax, ay), (bx, by) = pts[i - 1], pts[(i + 1) % n]
        yaw = math.atan2(by - ay, bx - ax)
        out.append((pts[i][0] - left_m * math.sin(yaw), pts[i][1] + left_m * math.cos(yaw),
                    yaw + math.radians(turn_deg)))
    return out


def tape_in_base(twin: Twin, pose: Pose2D) -> Points:
    """The tape's true centreline (closed) in the base frame of ``pose``."""
    assert twin.arena is not None
    pts = np.array([*twin.arena.lines[0].points_m, twin.arena.lines[0].points_m[0]])
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    d = pts - [pose.x_m, pose.y_m]
    return np.column_stack([d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c])


def distance_to(polyline: Points, points: Points) -> Points:
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    out = []
    for q in points:
        t = np.clip(((q - a) * ab).sum(1) / (ab * ab).sum(1), 0.0, 1.0)
        out.append(np.min(np.hypot(*(a + t[:, None] * ab - q).T)))
    return np.array(out)


def lateral_truth(polyline: Points, x_m: float, near_y_m: float) -> float:
    """The tape's y where it crosses x = ``x_m``, the crossing nearest ``near_y_m``."""
    side = polyline[:, 0] - x_m
    ks = np.flatnonzero((side[:-1] * side[1:] <= 0) & (side[:-1] != side[1:]))
    ys = [polyline[k, 1] + side[k] / (side[k] - side[k + 1]) * (polyline[k + 1, 1]
                                                               - polyline[k, 1]) for k in ks]
    return float(min(ys, key=lambda y: abs(y - near_y_m)))


def grey(image: npt.NDArray[np.uint8]) -> Points:
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.float64)


@pytest.mark.parametrize("seed", SEEDS)
def test_the_tape_where_it_truly_is(seed: int, twin_calibration: tuple[Path, Path]) -> None:
    world = TwinSpec(family="arena", seed=seed, controller=BoardSettings())
    with robot_on(world, twin_calibration) as (robot, twin):
        joints = look_ahead(robot)
        assert joints == pytest.approx(LOOK_AHEAD_DEG, abs=0.5)
        camera = floor_camera(robot)
        for place in [None, *poses_along(twin)]:
            if place is not None:
                set_down(twin, *place)
            before = true_pose(twin)
            image = robot.camera.read().image
            still = true_pose(twin).relative_to(before)
            assert math.hypot(still.x_m, still.y_m) < 1e-4  # the frame shows this pose
            sighting = camera.find_line(image)
            assert sighting is not None, f"seed {seed}: no line seen from {before}"
            tape = tape_in_base(twin, before)
            errors_m = distance_to(tape, sighting.points_m)
            assert np.max(errors_m) < 0.01, f"seed {seed} at {before}: {errors_m.max():.4f} m"
            assert sighting.length_m > 0.3
            assert 0.15 < sighting.points_m[0, 0] < 0.25  # it starts just ahead of the base
            assert sighting.width_m == pytest.approx(0.03, abs=0.006)
            lateral = sighting.lateral_m(LOOK_X_M)
            assert lateral == pytest.approx(lateral_truth(tape, LOOK_X_M, lateral), abs=0.01)
            # Under the base itself, extrapolated 0.2 m back along the near end's arc (the
            # loop bends hardest there at the start: its far end): within 2 cm.
            under = sighting.lateral_m(0.0)
            assert under == pytest.approx(lateral_truth(tape, 0.0, under), abs=0.02)


def test_the_look_ahead_view_shows_floor_and_no_robot(twin_calibration: tuple[Path, Path]
                                                      ) -> None:
    """In an empty room every pixel looked at is bare floor: neither the chassis nor the
    gripper is in it; the gripper begins just below ``floor_rows``."""
    arena = Arena(room=Room(-1.5, 1.5, -1.5, 1.5), start=StartPose(0.0, 0.0, 0.0),
                  name="bare floor")
    world = TwinSpec(arena=arena, controller=BoardSettings())
    with robot_on(world, twin_calibration) as (robot, _twin):
        look_ahead(robot)
        camera = floor_camera(robot)
        image = robot.camera.read().image
    near_m, far_m = camera.view_m()
    assert 0.15 <= near_m <= 0.22 and far_m >= 0.65
    g = grey(image)
    floor_level = float(np.median(g[camera.mask]))
    assert np.all(np.abs(g[camera.mask] - floor_level) < 0.15 * floor_level)
    assert camera.find_line(image) is None
    centre = g[:, 280:361] < 0.5 * floor_level  # the gripper's dark parts
    first_dark_row = int(np.flatnonzero(centre.any(axis=1))[0])
    assert camera.floor_rows <= first_dark_row <= camera.floor_rows + 30


def test_the_floor_camera_needs_a_calibration_and_a_chassis(
        twin_calibration: tuple[Path, Path]) -> None:
    with Robot.open(RobotConfig(TwinSpec(family="arena", seed=1, controller=BoardSettings()),
                                camera=CameraSpec(calibrate=False))) as robot, \
            pytest.raises(ConfigError, match="camera's calibration"):
        floor_camera(robot)
    with robot_on(TwinSpec(), twin_calibration) as (robot, _twin):  # an arm on a table
        with pytest.raises(ConfigError, match="where the arm sits above the floor"):
            floor_camera(robot)
        assert isinstance(floor_camera(robot, chassis=load_chassis_config("jetauto")),
                          FloorCamera)
        before = robot.arm.read_joints_deg()
        with pytest.raises(ConfigError, match=r"speed_deg_s .*500.* 1\.\.90 deg/s"):
            look_ahead(robot, speed_deg_s=500)
        assert robot.arm.read_joints_deg() == before  # nothing was sent
