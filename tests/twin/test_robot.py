"""The robot layer: one object for every job, on the twin and (refusals) on hardware."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from busarm.bus.ports import SerialPort
from busarm.errors import CameraError, ConfigError
from busarm.robot import ArmSpec, CameraSpec, Robot, RobotConfig
from busarm.sim.spec import SimSpec
from busarm.twin.scene import Block, Scene
from busarm.twin.spec import TwinSpec


def test_a_twin_robot_has_its_camera_bins_clock_and_a_calibration_made_in_it(
        tmp_path: Path) -> None:
    wall = time.monotonic()
    with Robot.open(RobotConfig(TwinSpec(seed=4, blocks=2),
                                camera=CameraSpec(folder=tmp_path))) as robot:
        assert robot.is_twin and robot.twin is not None
        assert robot.clock is robot.twin.clock and robot.clock.is_simulated
        assert sorted(robot.cameras) == ["overview", "wrist"]
        assert robot.camera.read().image.shape == (480, 640, 3)
        assert robot.bins == {b.color: (b.x_mm, b.y_mm) for b in robot.twin.scene.bins}
        cal = robot.require_camera_calibration()
        assert cal.source == "calibrated in the twin" and cal.twin_run is not None
        # Our flows found the camera the twin really mounted (which they never read).
        truth = robot.twin.mount.cam2link[:3, 3]
        assert np.linalg.norm(cal.hand_eye.cam2link[:3, 3] - truth) < 3.0
        assert cal.twin_run.hand_eye_error_mm < 3.0
        assert (tmp_path / "camera.json").is_file() and (tmp_path / "hand_eye.json").is_file()
        # Waiting on the robot's clock moves the twin: simulated seconds, not wall ones.
        start = robot.clock.now()
        robot.arm.move_joints(robot.config.pose("home"))
        moved_s = robot.clock.now() - start
        assert moved_s > 0.3
        np.testing.assert_allclose(robot.twin.joints_deg(), robot.config.pose("home"),
                                   atol=1.0)
        assert robot.twin.sim_time_s == pytest.approx(robot.clock.now(), abs=0.01)
    assert robot.twin.is_closed
    assert time.monotonic() - wall < 120


def test_the_same_calibration_files_give_the_same_robot_on_another_scene(
        twin_calibration: tuple[Path, Path]) -> None:
    # The files a twin robot's calibration wrote (the camera's folder: the session's, made
    # as the test above makes its own), on a twin with another table.
    scene = Scene(blocks=(Block("red", 200.0, 30.0, 0.0),))
    with Robot.open(RobotConfig(TwinSpec(scene=scene),
                                camera=CameraSpec(intrinsics=twin_calibration[0],
                                                  hand_eye=twin_calibration[1]))) as robot:
        cal = robot.require_camera_calibration()
        assert cal.twin_run is None and "camera.json" in cal.source
        seen = robot.locator().locate_averaged([(robot.camera.read().image,
                                                 robot.arm.read_joints_deg())])
        assert [s.color for s in seen] == ["red"]
        assert abs(seen[0].location.x_mm - 200.0) < 4 and abs(seen[0].location.y_mm - 30) < 4


def test_missing_parts_are_refused_before_the_port_is_opened() -> None:
    port = SerialPort("socket://127.0.0.1:9")  # nothing listens: opening it would fail
    with pytest.raises(ConfigError, match=r"on socket://127.0.0.1:9 this job needs the wrist "
                                          r"camera \(--camera\); the camera's calibration"):
        Robot.open(RobotConfig(port), needs=("camera", "camera_calibration"))
    with pytest.raises(ConfigError, match="where the bins are"):
        Robot.open(RobotConfig(port, camera=CameraSpec("/dev/video9")), needs=("bins",))
    with pytest.raises(ConfigError, match="needs wings; allowed: camera"):
        Robot.open(RobotConfig(port), needs=("wings",))
    # A scene is the twin's alone: the simulator's description has no place for one.
    with pytest.raises(TypeError, match="scene"):
        SimSpec(scene=Scene())  # type: ignore[call-arg]
    with pytest.raises(ConfigError, match="give both camera calibration files"):
        Robot.open(RobotConfig(SimSpec(), camera=CameraSpec(intrinsics=Path("camera.json"))))
    with pytest.raises(ConfigError, match="needs the intrinsics it was made with"):
        Robot.open(RobotConfig(camera=CameraSpec(hand_eye=Path("hand_eye.json"))))


def test_a_robot_without_a_camera_says_what_is_missing() -> None:
    with Robot.open(RobotConfig(SimSpec(realtime=True))) as robot:
        assert not robot.clock.is_simulated
    # The simulator in this process: simulated time.
    with Robot.open(RobotConfig(SimSpec())) as robot:
        assert not robot.is_twin and robot.clock.is_simulated
        assert not robot.has_camera and robot.bins == {}
        with pytest.raises(ConfigError, match="needs the wrist camera"):
            _ = robot.camera
        with pytest.raises(ConfigError, match="--intrinsics FILE"):
            robot.locator()


def test_a_camera_that_cannot_open_closes_the_twin_it_made() -> None:
    with pytest.raises(CameraError):
        Robot.open(RobotConfig(TwinSpec(blocks=0),
                               camera=CameraSpec("/nonexistent/folder", calibrate=False)))


def test_an_exception_in_the_job_stops_and_holds_the_arm() -> None:
    with pytest.raises(RuntimeError, match="job failed"), Robot.open(
            RobotConfig(TwinSpec(blocks=0), camera=CameraSpec(calibrate=False))) as robot:
        robot.arm.move_joints(robot.config.pose("home"), wait=False)
        robot.clock.sleep(0.2)  # mid-move
        twin = robot.twin
        assert twin is not None
        raise RuntimeError("job failed")
    # MOVE_STOP reached every servo mid-move: each holds (loaded) where it was, short of
    # home, and its firmware drives it nowhere else from then on.
    now = twin.clock.now()
    for servo in twin.servos:
        assert servo.is_loaded
        servo.advance(now)
        stopped_at = servo.position_pulses
        servo.advance(now + 2.0)
        assert servo.position_pulses == pytest.approx(stopped_at, abs=0.5), servo
    shoulder = twin.config.joints[1]
    home_pulses = shoulder.pulses_from_angle_deg(twin.config.pose("home")[1])
    assert abs(twin.servos[1].position_pulses - home_pulses) > 5


def test_the_twins_arm_is_the_one_given_to_the_twin_or_by_the_program() -> None:
    from busarm.arm.config import load_arm_config

    armpi = str(Path(__file__).parents[1] / "data" / "armpi_style.toml")
    no_calibration = CameraSpec(calibrate=False)
    with Robot.open(RobotConfig(TwinSpec(config=armpi, blocks=0),
                                camera=no_calibration)) as robot:
        assert robot.config.name == "ArmPi-style test arm" == robot.twin.config.name  # type: ignore[union-attr]
    with Robot.open(RobotConfig(TwinSpec(blocks=0), ArmSpec(config=armpi),
                                camera=no_calibration)) as robot:
        assert robot.config.name == "ArmPi-style test arm"
    with pytest.raises(ConfigError, match="is not the arm config given"):
        Robot.open(RobotConfig(TwinSpec(config=armpi, blocks=0),
                               ArmSpec(config=load_arm_config()), camera=no_calibration))


def test_an_action_group_plays_on_the_twins_clock() -> None:
    from busarm.arm.actions import read_d6a

    group = read_d6a(Path(__file__).parents[1] / "data" / "vendor" /
                     "arm_calibration_pose.d6a")
    with Robot.open(RobotConfig(TwinSpec(blocks=0),
                                camera=CameraSpec(calibrate=False))) as robot:
        start = robot.clock.now()
        assert robot.arm.play(group) == len(group.frames)
        # Each frame's time passed on the twin (not on the wall), and the arm got there.
        assert robot.clock.now() - start >= sum(f.duration_ms for f in group.frames) / 1000
        target = robot.arm.action_targets(group)[-1][1]
        np.testing.assert_allclose(robot.arm.read_joints_deg(), target, atol=1.5)
