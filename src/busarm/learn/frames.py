"""A robot driven one frame at a time, as LeRobot drives robots: flat observations in, one
frame's action out, every action clipped to the limits before it is sent.

``FrameRobot(description, fps=20, cameras=("wrist",))`` knows its features before it is
opened (LeRobot asks first): each motor (``NAME.pos`` in rad, ``gripper.gap_mm``), with a
base ``base.vx``, ``base.vy`` (m/s) and ``base.wz`` (rad/s) as actions and its odometry as
observations, and each camera's picture (height, width, 3; RGB). ``observe()`` reads them
(``Robot.get_observation``); ``act(values)`` clips the joints and gripper
(busarm.learn.limits) and the twist to the chassis's limits, sends it as a move of one
frame (``Robot.send_action``: the robot's own checks, e-stop included: a halted bus
refuses it) and returns what was sent.

Who sends the actions does not matter to the limits. When actions stop coming, the
servos hold the last target and the wheels stop on the chassis's command timeout.
Closing (``close``: LeRobot's disconnect, which its loops call on an error too) stops the
arm and the wheels.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.arm.config import ArmConfig, load_arm_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.clock import Clock
from busarm.errors import ConfigError
from busarm.learn.features import DEFAULT_FPS, motor_names
from busarm.learn.limits import ActionLimits
from busarm.robot import Robot, RobotConfig
from busarm.robot.observation import BASE_KEYS, send_action
from busarm.twin.lens import lens_by_name
from busarm.twin.spec import TwinSpec
from busarm.units import listing

__all__ = [
    "HEADING_KEPT_S",
    "ODOMETRY_KEYS",
    "FrameRobot",
    "has_base",
    "next_frame",
]

HEADING_KEPT_S = 1.0
"""An action's step is judged from the last one sent within this long (the firmware's
setpoint is there); after a longer pause, from where the arm is read."""
ODOMETRY_KEYS = ("base.x", "base.y", "base.yaw", "base.vx", "base.vy", "base.wz")
"""A base's observation: its odometry's pose (m, rad) and velocity (m/s, rad/s)."""


def next_frame(due_s: float, period_s: float, clock: Clock) -> float:
    """Wait on ``clock`` until the frame after the one due at ``due_s``; its time. A
    frame more than a period late is not caught up on (no frames back to back): the next
    is a period from now."""
    due_s += period_s
    now = clock.now()
    if now > due_s + period_s:
        return now
    clock.sleep(max(0.0, due_s - now))
    return due_s


def has_base(description: RobotConfig) -> bool:
    """Whether the described robot has a base: one described, or a twin's arena behind
    its board."""
    world = description.world
    return description.base is not None or (
        isinstance(world, TwinSpec) and world.controller is not None
        and (world.family == "arena" or world.arena is not None))


def _arm_config(description: RobotConfig) -> ArmConfig:
    given = description.arm.config
    if isinstance(given, ArmConfig):
        return given
    if isinstance(description.world, TwinSpec):
        return description.world.arm_config(None if given is None else load_arm_config(given))
    return load_arm_config(given) if given is not None else load_arm_config()


class FrameRobot:
    """The robot ``description`` says, one frame at a time (the module docstring)."""

    def __init__(self, description: RobotConfig, *, fps: int = DEFAULT_FPS,
                 cameras: Sequence[str] = ("wrist",),
                 camera_size: tuple[int, int] = (480, 640)) -> None:
        self.description = description
        self.config = _arm_config(description)
        self.limits = ActionLimits.of(self.config, fps)
        self.motors = tuple(motor_names(self.config))
        self.base = has_base(description)
        self.cameras = tuple(cameras)
        if isinstance(description.world, TwinSpec):
            lens = lens_by_name(description.world.lens)
            sizes = {"wrist": (lens.height_px, lens.width_px), "overview": (480, 640)}
        else:
            sizes = {"wrist": camera_size}
        unknown = [c for c in self.cameras if c not in sizes]
        if unknown:
            raise ConfigError(f"cameras {listing(unknown)}: this robot has "
                              f"{listing(sizes)}")
        self.camera_sizes = {c: sizes[c] for c in self.cameras}
        self.robot: Robot | None = None
        self._read: tuple[float, npt.NDArray[np.float64]] | None = None
        self._told: tuple[float, npt.NDArray[np.float64]] | None = None
        self.clipped = 0
        """Action values clipped to the limits since it was opened."""

    def __repr__(self) -> str:
        state = "open" if self.robot is not None else "closed"
        return f"FrameRobot({self.description.world.name}, {state})"

    # ------------------------------------------------------------------ features

    @property
    def observation_features(self) -> dict[str, Any]:
        out: dict[str, Any] = {name: float for name in self.motors}
        if self.base:
            out.update({key: float for key in ODOMETRY_KEYS})
        for role, (h, w) in self.camera_sizes.items():
            out[role] = (h, w, 3)
        return out

    @property
    def action_features(self) -> dict[str, Any]:
        out: dict[str, Any] = {name: float for name in self.motors}
        if self.base:
            out.update({key: float for key in BASE_KEYS})
        return out

    # ------------------------------------------------------------------ use

    def open(self) -> Robot:
        """Open the robot (once; a camera of another size than declared: ConfigError,
        and it is closed again); the robot."""
        if self.robot is None:
            robot = Robot.open(self.description)
            try:
                for role, (h, w) in self.camera_sizes.items():
                    cam = robot.cameras.get(role)
                    if cam is None or (cam.height_px, cam.width_px) != (h, w):
                        got = "none" if cam is None else f"{cam.width_px}x{cam.height_px}"
                        raise ConfigError(f"camera {role}: {w}x{h} pictures were declared, "
                                          f"the robot gives {got}")
            except BaseException:
                robot.close()
                raise
            self.robot = robot
        return self.robot

    def close(self) -> None:
        """Stop the arm where it is if it was told anything (MOVE_STOP: it holds), stop
        the wheels, and close the robot."""
        told, self._read, self._told = self._told, None, None
        if self.robot is not None:
            robot, self.robot = self.robot, None
            try:
                if told is not None:
                    robot.arm.stop()  # never raises
            finally:
                robot.close()

    def _open_robot(self) -> Robot:
        if self.robot is None:
            raise ConfigError("the robot is not connected: open() it first")
        return self.robot

    def observe(self) -> dict[str, Any]:
        """Every observation feature, read now (images RGB)."""
        seen = self._open_robot().get_observation(cameras=list(self.cameras), scan=False)
        flat = seen.as_dict(rgb=True)
        self._read = (seen.t_s, np.array([float(flat[name]) for name in self.motors]))
        return {key: (float(flat[key]) if kind is float else np.ascontiguousarray(flat[key]))
                for key, kind in self.observation_features.items()}

    def state(self) -> npt.NDArray[np.float64]:
        """The motors now, in their order (rad; the gripper's gap in mm)."""
        seen = self._open_robot().get_observation(cameras=False, scan=False)
        flat = seen.as_dict()
        self._read = (seen.t_s, np.array([float(flat[name]) for name in self.motors]))
        return self._read[1].copy()

    def _measured(self, robot: Robot) -> npt.NDArray[np.float64]:
        """The motors as read within the last frame (by ``observe``, as a LeRobot loop
        does before each action), else read now."""
        if self._read is not None and robot.clock.now() - self._read[0] < self.limits.frame_s:
            return self._read[1].copy()
        return self.state()

    def commanded(self) -> dict[str, float]:
        """Where the arm was last told to go (each servo's last target, read back:
        MOVE_TIME_READ), in the motors' form: the action of whoever drives it (a
        dashboard's jog, a program). A servo never told anything reads where it is."""
        robot = self._open_robot()
        arm, bus = robot.arm, robot.arm.bus
        now = self.state()
        pulses = {}
        for j, rad in zip(self.config.joints, now, strict=False):
            told = bus.last_target_pulses(j.servo_id)
            pulses[j.servo_id] = (told if told is not None
                                  else arm.pulses_exact(j, float(np.degrees(rad))))
        out = dict(zip(self.motors, [float(np.radians(a)) for a in arm.joints_from_pulses(pulses)],
                       strict=False))
        grip = bus.last_target_pulses(self.config.gripper.servo_id)
        gap = self.config.gripper.gap_mm_at(grip) if grip is not None else float(now[-1])
        out[self.motors[-1]] = min(max(gap, 0.0), self.config.gripper.widest_gap_mm)
        return out

    def act(self, action: Mapping[str, float]) -> dict[str, float]:
        """Clip ``action`` (the action features; a motor left out stays where it is) to
        the limits, send it as one frame's move, and return what was sent."""
        robot = self._open_robot()
        unknown = [k for k in action if k not in self.action_features]
        if unknown:
            raise ConfigError(f"action keys {listing(map(repr, unknown))} are not known; "
                              f"allowed: {listing(self.action_features)}")
        measured = self._measured(robot)
        now = robot.clock.now()
        heading, since = None, None
        if self._told is not None and now - self._told[0] < HEADING_KEPT_S:
            heading, since = self._told[1], now - self._told[0]
        start = measured if heading is None else heading
        asked = np.array([float(action.get(name, s)) for name, s in zip(self.motors, start,
                                                                         strict=True)])
        values, changed = self.limits.clip(asked, measured, heading, since_s=since)
        self.clipped += changed
        send: dict[str, float] = self.limits.flat(values)
        if self.base and any(k in action for k in BASE_KEYS):
            send.update(self._twist(robot, action))
        # The firmware moves each servo on from its setpoint, which is at the heading once
        # the last move's frame is over (the clip above allowed for one still under way).
        send_action(robot, send, read_deg=np.degrees(start[:-1]).tolist())
        self._told = (now, values)
        self._read = None  # the arm is on its way: the next action reads it again
        return {k: v for k, v in send.items() if k in self.action_features}

    def _twist(self, robot: Robot, action: Mapping[str, float]) -> dict[str, float]:
        """The twist asked (a value not a number: 0), scaled down, its direction kept, to
        the chassis's speeds and its wheels' together."""
        assert robot.base is not None
        asked = [float(action.get(key, 0.0)) for key in BASE_KEYS]
        finite = [v if np.isfinite(v) else 0.0 for v in asked]
        twist = MecanumKinematics(robot.base.config).limit_twist(Twist(*finite))
        sent = (twist.vx_m_s, twist.vy_m_s, twist.wz_rad_s)
        self.clipped += sum(a != s for a, s in zip(asked, sent, strict=True))
        return dict(zip(BASE_KEYS, sent, strict=True))
