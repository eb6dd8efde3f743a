"""busarm.learn on the twin, judged on its truth: the expert's episode (sampled at its rate
from the servos, the task's state from its look), the twin as a gymnasium environment
(the expert's actions replayed to success, a still arm never succeeding, gymnasium's own
checks), and the frame-at-a-time robot (features known before it opens, every action
clipped, the last command read back, a halted bus refusing, closing stopping the arm)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from busarm.errors import ConfigError, HaltedError
from busarm.learn.env import PickPlaceEnv
from busarm.learn.expert import EpisodeTask, run_expert
from busarm.learn.features import DEFAULT_FPS, motor_names
from busarm.learn.frames import ODOMETRY_KEYS, FrameRobot
from busarm.learn.tasks import HELD_OUT_SEED, is_done, task_scene
from busarm.protocol import Command
from busarm.robot import CameraSpec, RobotConfig
from busarm.robot.observation import BASE_KEYS
from busarm.sim.spec import BoardSettings
from busarm.twin.spec import TwinSpec

pytestmark = pytest.mark.slow


def _expert(seed: int, calibration: tuple[Path, Path]):  # type: ignore[no-untyped-def]
    return run_expert(EpisodeTask(0, "one-block", seed, DEFAULT_FPS, *calibration))


def test_an_expert_episode_is_sampled_and_judged_on_the_truth(
        twin_calibration: tuple[Path, Path]) -> None:
    e = _expert(4, twin_calibration)
    block = task_scene("one-block", 4).blocks[0]
    assert e.success and e.why == "" and e.text == f"put the {block.color} block in the " \
                                                 f"{block.color} bin"
    # one frame every 1/20 s of the episode's twin time (the look before it not counted)
    assert e.states.shape == e.actions.shape == (e.frames, 6)
    assert 3.0 * DEFAULT_FPS < e.frames < e.sim_s * DEFAULT_FPS
    look = [math.radians(a) for a in _look()]
    assert np.allclose(e.states[0, :5], look, atol=math.radians(1.0))
    # a frame's action is the servos' setpoint one frame on: where the joints are read
    # the next frame (nearer it than the same frame's reading or the one after) ...
    def off(d: int) -> float:
        n = len(e.actions) - abs(d)
        a = e.actions[max(0, -d):max(0, -d) + n, :5]
        return float(np.abs(a - e.states[max(0, d):max(0, d) + n, :5]).mean())
    assert off(1) < min(off(0), off(2)) / 5
    # ... and while the block is held the gripper's is inside it (its squeeze)
    holding = np.abs(e.states[:, 5] - block.size_mm) < 2.0
    assert holding.sum() > DEFAULT_FPS
    assert np.median(e.states[holding, 5] - e.actions[holding, 5]) > 0.2
    # the look found the block where it is, its bin the twin's tray of its colour
    assert math.dist(e.task_state[:2], (block.x_mm, block.y_mm)) < 10.0
    assert tuple(e.task_state[3:]) == pytest.approx(
        next((b.x_mm, b.y_mm) for b in task_scene("one-block", 4).bins
             if b.color == block.color), abs=1e-3)


def _arm_config():  # type: ignore[no-untyped-def]
    return TwinSpec().arm_config()


def _look() -> tuple[float, ...]:
    return _arm_config().pose("look")


def test_the_environment_replays_the_expert_to_success(
        twin_calibration: tuple[Path, Path]) -> None:
    seed = HELD_OUT_SEED + 7
    e = _expert(seed, twin_calibration)
    assert e.success
    intrinsics, hand_eye = twin_calibration
    env = PickPlaceEnv(camera=CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye))
    try:
        obs, info = env.reset(seed=seed)
        assert info == {"is_success": False, "seed": seed}
        assert np.allclose(obs["environment_state"], e.task_state)
        assert obs["agent_pos"].shape == (6,) and env.observation_space.contains(obs)
        steps = 0
        for action in e.actions:
            obs, reward, terminated, truncated, info = env.step(action)
            steps += 1
            if terminated:
                break
        assert terminated and reward == 1.0 and info["is_success"] and not truncated
        assert steps < e.frames  # done once the block lies in its tray, let go of
        assert env.robot is not None and env.robot.twin is not None
        assert is_done(env.robot.twin, env.robot.bins)
        picture = env.render()
        assert picture.shape == (480, 640, 3) and picture.dtype == np.uint8
        # the same table, the arm held where it is: never done, nothing rewarded
        obs, _ = env.reset(seed=seed)
        for _ in range(30):
            obs, reward, terminated, _, info = env.step(obs["agent_pos"])
            assert reward == 0.0 and not terminated and not info["is_success"]
        # a far target is clipped to one frame's step, and counted
        far = obs["agent_pos"] + np.array([2.0, 0, 0, 0, 0, 0])
        before = obs["agent_pos"][0]
        obs, *_ = env.step(far)
        assert info["clipped"] == 0 and env.clipped == 1
        assert abs(obs["agent_pos"][0] - before) <= math.radians(180) / DEFAULT_FPS
    finally:
        env.close()


def test_gymnasium_checks_the_environment(twin_calibration: tuple[Path, Path]) -> None:
    intrinsics, hand_eye = twin_calibration
    env = PickPlaceEnv(obs_type="pixels_agent_pos",
                       camera=CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye))
    try:
        check_env(env, skip_render_check=True)
        obs, _ = env.reset(seed=HELD_OUT_SEED)
        assert obs["pixels"]["wrist"].shape == (480, 640, 3)
    finally:
        env.close()


def test_a_frame_robot_clips_reads_back_and_obeys_a_halt() -> None:
    mobile = FrameRobot(RobotConfig(TwinSpec(family="arena", seed=1,
                                             controller=BoardSettings()),
                                    camera=CameraSpec(calibrate=False)), cameras=())
    assert set(ODOMETRY_KEYS) <= set(mobile.observation_features)
    assert set(BASE_KEYS) <= set(mobile.action_features) and mobile.robot is None
    try:
        mobile.open()
        chassis = mobile.robot.base.config if mobile.robot and mobile.robot.base else None
        assert chassis is not None
        sent = mobile.act({"base.vx": 5.0, "base.wz": float("nan")})  # too fast; not a number
        assert sent["base.vx"] == pytest.approx(chassis.max_speed_m_s) and sent["base.wz"] == 0
        assert mobile.clipped == 2
        sent = mobile.act({"base.vx": chassis.max_speed_m_s, "base.wz": 5.0})  # the wheels'
        assert sent["base.vx"] / sent["base.wz"] == pytest.approx(chassis.max_speed_m_s / 5.0)
        assert sent["base.vx"] < chassis.max_speed_m_s  # scaled down, its direction kept
    finally:
        mobile.close()
    frames = FrameRobot(RobotConfig(TwinSpec(blocks=0), camera=CameraSpec(calibrate=False)),
                        cameras=("wrist",))
    motors = motor_names(frames.config)
    assert frames.observation_features["wrist"] == (480, 640, 3)
    assert list(frames.action_features) == motors and frames.robot is None
    try:
        robot = frames.open()
        start = frames.state()
        sent = frames.act({motors[0]: start[0] + 3.0, motors[-1]: 500.0})
        assert frames.clipped == 2
        assert sent[motors[-1]] == frames.config.gripper.widest_gap_mm
        assert abs(sent[motors[0]] - start[0]) <= math.radians(180) / DEFAULT_FPS
        robot.clock.sleep(0.3)
        told = frames.commanded()
        assert told[motors[0]] == pytest.approx(sent[motors[0]], abs=math.radians(0.3))
        # a move's shortest time is stretched where a joint's top speed needs it
        far = {f"{j.name}.pos": float(v) for j, v in zip(frames.config.joints,
                                                        frames.state(), strict=False)}
        far[motors[0]] += math.radians(36.0)
        sent_action = robot.send_action({**far, "min_duration_s": 0.05})
        assert sent_action.duration_s == pytest.approx(0.2, abs=0.01)  # 36 deg at 180 deg/s
        with pytest.raises(ConfigError, match="min_duration_s"):
            robot.send_action({**far, "min_duration_s": 0.05, "duration_s": 0.5})
        robot.clock.sleep(0.3)
        robot.arm.bus.halt("e-stop in a test")
        held = frames.state()
        with pytest.raises(HaltedError):
            frames.act({motors[0]: float(held[0]) - 0.1})
        robot.clock.sleep(0.3)
        assert np.allclose(frames.state(), held, atol=math.radians(0.5))
    finally:
        frames.close()


def test_closing_a_frame_robot_that_moved_stops_the_arm() -> None:
    frames = FrameRobot(RobotConfig(TwinSpec(blocks=0), camera=CameraSpec(calibrate=False)),
                        cameras=())
    robot = frames.open()
    assert robot.twin is not None
    stops: list[int] = []
    robot.twin.bus.taps.append(
        lambda r: stops.append(r.servo_id) if r.command is Command.MOVE_STOP else None)
    start = frames.state()
    for k in range(1, 6):  # a base turn under way, a frame at a time
        frames.act({"base_yaw.pos": float(start[0]) + 0.15 * k})
        robot.clock.sleep(0.05)
    frames.close()
    assert stops  # MOVE_STOP (broadcast or each servo): the arm holds where it was
    assert frames.robot is None
