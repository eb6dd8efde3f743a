"""One observation of the whole robot, and one action for it: typed, stamped, checked.

``robot.get_observation()`` reads every part once: the arm's joints (rad, by the arm
config's names) and its gripper (the fingers' gap in mm, as the arm models it), the base's
odometry when there is a base, a Lidar scan when there is a Lidar, a frame from each
camera. Each carries its own stamp on the robot's clock (``robot.clock``: simulated
seconds on a twin), so what was seen can be lined up with where the robot was.
``Observation.as_dict()`` gives the flat form datasets take (LeRobot's):
``{"shoulder_pitch.pos": rad, ..., "gripper.gap_mm": mm, "base.x": m, ..., "wrist": image}``.

``robot.send_action(action)`` takes an ``Action`` (joint targets in rad and a move time,
a gripper gap, a base twist in m/s and rad/s) or the same flat dict. Every value is
checked against its limit (the arm config's joint limits and the servos' own with the
calibration, the gripper's travel, the chassis config's speeds) before anything is sent:
a value beyond one is a ConfigError naming its key, the value and the range, and nothing
moves. Units are SI at this face (rad, m, s); the gripper's gap is in mm, as everything
the arm does on its table is.
"""

from __future__ import annotations

import math
import types
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from busarm.base.base import BaseOdometry
from busarm.base.config import ChassisConfig
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.clock import Clock
from busarm.errors import ConfigError
from busarm.lidar.scan import LaserScan, LidarSource
from busarm.units import check_range, fixed_number, listing, plain_number, range_text
from busarm.vision.camera import CameraFrame

if TYPE_CHECKING:
    from busarm.arm.arm import Arm
    from busarm.robot.robot import Robot

__all__ = [
    "BASE_KEYS",
    "DEFAULT_SCAN_S",
    "DURATION_KEY",
    "GRIPPER_KEY",
    "JOINT_SUFFIX",
    "MAX_STALE_SCANS",
    "MIN_DURATION_KEY",
    "SCAN_TIMEOUT_S",
    "Action",
    "ActionLike",
    "CheckedAction",
    "Observation",
    "check_action",
    "observe",
    "send_action",
]


JOINT_SUFFIX = ".pos"
"""A joint's key in the flat form: its name and this (``shoulder_pitch.pos``), in rad."""
GRIPPER_KEY = "gripper.gap_mm"
"""The gripper's key in the flat form: the fingers' gap, mm."""
DURATION_KEY = "duration_s"
"""An action's joint move time in the flat form, s."""
MIN_DURATION_KEY = "min_duration_s"
"""An action's shortest joint move time in the flat form, s: longer where a joint's top
speed needs it (a stream of targets, one a frame, from a teleoperator or a policy)."""
BASE_KEYS = ("base.vx", "base.vy", "base.wz")
"""A base twist in the flat form: m/s forward, m/s left, rad/s counter-clockwise."""
SCAN_TIMEOUT_S = 1.0
"""How long an observation waits for the Lidar's next revolution (an A1 turns at 5-10 Hz)."""
MAX_STALE_SCANS = 100
"""At most this many queued revolutions are passed over for the newest (10 s at 10 Hz)."""
DEFAULT_SCAN_S = 0.2
"""A revolution's time when a scan does not say (the A1's slowest, 5 Hz)."""

FlatValue = float | npt.NDArray[np.generic]
"""A value of the flat form: a number, or an array (an image, a scan's ranges)."""


def _frozen_map(values: Mapping[str, float]) -> Mapping[str, float]:
    """A read-only copy: a frozen dataclass should not change under its holder."""
    return types.MappingProxyType(dict(values))


@dataclass(frozen=True, eq=False)
class Observation:
    """The whole robot at one moment, each part stamped on the robot's clock.

    ``t_s`` is when reading began; the arm's joints and gripper are read first, at
    ``t_s``. The base's odometry has its own stamp (``base.at_s``), the scan its own
    (``scan.stamp_s``: when its revolution began), each frame its own (``timestamp_s``).
    """

    t_s: float
    """When the observation was taken (and the arm read): the robot's clock, s."""
    joints_rad: Mapping[str, float]
    """Each arm joint's measured angle, by the arm config's names, in its order (rad)."""
    gripper_gap_mm: float
    """How far apart the gripper's fingers are (0 closed), mm."""
    base: BaseOdometry | None = None
    """The base's odometry (pose in m and rad, twist, its stamp ``at_s``); None: no base."""
    scan: LaserScan | None = None
    """The Lidar's newest complete revolution; None: no Lidar, or not asked for."""
    frames: Mapping[str, CameraFrame] = field(default_factory=dict)
    """A frame from each camera asked for, by role (``wrist``, a twin's ``overview``)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "joints_rad", _frozen_map(self.joints_rad))
        object.__setattr__(self, "frames", types.MappingProxyType(dict(self.frames)))

    def __repr__(self) -> str:
        parts = [f"t={self.t_s:.3f} s", f"{len(self.joints_rad)} joints",
                 f"gripper {self.gripper_gap_mm:.0f} mm"]
        if self.base is not None:
            p = self.base.pose
            parts.append(f"base ({fixed_number(p.x_m, 2)}, {fixed_number(p.y_m, 2)}, "
                         f"{fixed_number(p.yaw_deg, 1)} deg)")
        if self.scan is not None:
            parts.append(f"scan {len(self.scan)} pts")
        parts.append(f"cameras {sorted(self.frames)}")
        return f"Observation({', '.join(parts)})"

    @property
    def stamps(self) -> dict[str, float]:
        """When each part was read, on the robot's clock: ``arm``, ``base``, ``scan`` and
        ``camera.ROLE`` (the parts there are)."""
        out = {"arm": self.t_s}
        if self.base is not None:
            out["base"] = self.base.at_s
        if self.scan is not None:
            out["scan"] = self.scan.stamp_s
        out.update({f"camera.{role}": f.timestamp_s for role, f in self.frames.items()})
        return out

    def as_dict(self, *, rgb: bool = False) -> dict[str, FlatValue]:
        """The flat form (LeRobot's): ``NAME.pos`` (rad) for each joint,
        ``gripper.gap_mm``, with a base ``base.x``, ``base.y`` (m), ``base.yaw`` (rad),
        ``base.vx``, ``base.vy`` (m/s), ``base.wz`` (rad/s), with a scan
        ``lidar.angles`` (rad) and ``lidar.ranges`` (m, NaN: no return), and each
        camera's image under its role. Images are BGR as busarm's cameras give them;
        ``rgb`` flips them to RGB (a view, no copy), as LeRobot's datasets hold them."""
        out: dict[str, FlatValue] = {f"{name}{JOINT_SUFFIX}": rad
                                     for name, rad in self.joints_rad.items()}
        out[GRIPPER_KEY] = self.gripper_gap_mm
        if self.base is not None:
            pose, twist = self.base.pose, self.base.twist
            out.update({"base.x": pose.x_m, "base.y": pose.y_m, "base.yaw": pose.yaw_rad,
                        "base.vx": twist.vx_m_s, "base.vy": twist.vy_m_s,
                        "base.wz": twist.wz_rad_s})
        if self.scan is not None:
            out["lidar.angles"] = self.scan.angles_rad
            out["lidar.ranges"] = self.scan.ranges_m
        for role, frame in self.frames.items():
            out[role] = frame.image[..., ::-1] if rgb else frame.image
        return out


@dataclass(frozen=True)
class Action:
    """What to do next: joint targets (rad, every joint by name, reached in
    ``duration_s``), a gripper gap (mm), a base twist (m/s, rad/s); any of them.

    The joints start and arrive together; without ``duration_s`` at the arm's default
    speed (busarm.arm.arm.DEFAULT_SPEED_DEG_S for the joint that turns furthest). The
    gripper goes at its own pace (its config's ``grip_time_s`` for the full travel). A
    base twist is a velocity command to repeat, as ``Base.drive`` is: sent again within
    the chassis's ``command_timeout_s`` or the wheels stop.
    """

    joints_rad: Mapping[str, float] | None = None
    gripper_gap_mm: float | None = None
    duration_s: float | None = None
    base: Twist | None = None
    min_duration_s: float | None = None
    """Instead of ``duration_s``: the joints' move takes at least this long, longer where a
    joint's top speed needs it (never refused for speed)."""

    def __post_init__(self) -> None:
        if self.joints_rad is not None:
            object.__setattr__(self, "joints_rad", _frozen_map(self.joints_rad))

    def __repr__(self) -> str:
        parts = []
        if self.joints_rad is not None:
            parts.append("joints_rad={" + ", ".join(
                f"{name!r}: {rad:.4g}" for name, rad in self.joints_rad.items()) + "}")
        for name in ("gripper_gap_mm", "duration_s", "min_duration_s", "base"):
            if getattr(self, name) is not None:
                parts.append(f"{name}={getattr(self, name)!r}")
        return f"Action({', '.join(parts)})"

    def as_dict(self) -> dict[str, float]:
        """The flat form: ``NAME.pos`` (rad), ``gripper.gap_mm``, ``duration_s``,
        ``base.vx``, ``base.vy`` (m/s), ``base.wz`` (rad/s): those it has."""
        out: dict[str, float] = {}
        if self.joints_rad is not None:
            out.update({f"{name}{JOINT_SUFFIX}": rad for name, rad in self.joints_rad.items()})
        if self.gripper_gap_mm is not None:
            out[GRIPPER_KEY] = self.gripper_gap_mm
        if self.duration_s is not None:
            out[DURATION_KEY] = self.duration_s
        if self.min_duration_s is not None:
            out[MIN_DURATION_KEY] = self.min_duration_s
        if self.base is not None:
            out.update(zip(BASE_KEYS, (self.base.vx_m_s, self.base.vy_m_s,
                                       self.base.wz_rad_s), strict=True))
        return out

    @classmethod
    def from_dict(cls, values: Mapping[str, float]) -> Action:
        """An action from its flat form (``as_dict``'s keys). A base twist's missing
        components are 0; a key of none of these forms is a ConfigError (a misspelt key
        must not be left out quietly)."""
        known = {GRIPPER_KEY, DURATION_KEY, MIN_DURATION_KEY, *BASE_KEYS}
        unknown = [k for k in values if k not in known and not (
            isinstance(k, str) and k.endswith(JOINT_SUFFIX) and len(k) > len(JOINT_SUFFIX))]
        if unknown:
            raise ConfigError(f"action keys {listing(map(repr, unknown))} are not known; "
                              f"allowed: JOINT{JOINT_SUFFIX} (rad), {GRIPPER_KEY}, "
                              f"{DURATION_KEY}, {MIN_DURATION_KEY}, {', '.join(BASE_KEYS)}")
        joints = {k[:-len(JOINT_SUFFIX)]: v for k, v in values.items()
                  if k.endswith(JOINT_SUFFIX)}
        twist = None
        if any(k in values for k in BASE_KEYS):
            vx, vy, wz = (values.get(k, 0.0) for k in BASE_KEYS)
            twist = Twist(vx, vy, wz)
        return cls(joints or None, values.get(GRIPPER_KEY), values.get(DURATION_KEY), twist,
                   values.get(MIN_DURATION_KEY))


ActionLike = Action | Mapping[str, float]
"""What ``send_action`` takes: an Action, or its flat form (``Action.as_dict``'s keys)."""


@dataclass(frozen=True)
class CheckedAction:
    """An action whose every value is within its limit, in the units the parts take."""

    joints_deg: tuple[float, ...] | None
    gripper_gap_mm: float | None
    duration_s: float | None
    twist: Twist | None
    min_duration_s: float | None = None


def _within(key: str, value: object, lo: float, hi: float, unit: str,
            also: str = "") -> float:
    """``check_range``'s check and words, the key for the name; ``also`` adds the range
    in a unit a person may know better (the joints' degrees)."""
    try:
        return check_range(key, value, lo, hi, unit)
    except ConfigError as exc:
        raise ConfigError(f"{exc}{also}") from None


def _joint_targets(arm: Arm, joints_rad: Mapping[str, float]) -> tuple[float, ...]:
    """Every joint's target in degrees, each within its config limits and its servo's."""
    names = [j.name for j in arm.config.joints]
    unknown = [n for n in joints_rad if n not in names]
    if unknown:
        raise ConfigError(f"{listing(n + JOINT_SUFFIX for n in unknown)}: {arm.config.name} "
                          f"has no such joint; its joints: {listing(names)}")
    missing = [n + JOINT_SUFFIX for n in names if n not in joints_rad]
    if missing:
        raise ConfigError(f"an action moves every joint or none: {listing(missing)} "
                          "missing (rad)")
    targets = []
    for j in arm.config.joints:
        rad = _within(j.name + JOINT_SUFFIX, joints_rad[j.name], math.radians(j.min_deg),
                      math.radians(j.max_deg), "rad",
                      f" ({range_text(j.min_deg, j.max_deg, 'deg')})")
        targets.append(math.degrees(rad))
    arm.servo_pulses(targets)  # the servos' own ranges, with the calibration: LimitError
    return tuple(targets)


def _twist(chassis: ChassisConfig, twist: Twist) -> Twist:
    """The twist, each component within the chassis's limit and the wheels' together."""
    vx = _within(BASE_KEYS[0], twist.vx_m_s, -chassis.max_speed_m_s, chassis.max_speed_m_s,
                 "m/s")
    vy = _within(BASE_KEYS[1], twist.vy_m_s, -chassis.max_speed_m_s, chassis.max_speed_m_s,
                 "m/s")
    limit = chassis.max_yaw_rate_rad_s
    wz = _within(BASE_KEYS[2], twist.wz_rad_s, -limit, limit, "rad/s",
                 f" ({plain_number(round(math.degrees(limit), 6))} deg/s either way)")
    checked = Twist(vx, vy, wz)
    try:  # each within its limit, but together a wheel may need more than it has
        MecanumKinematics(chassis).check_limits(checked)
    except ConfigError as exc:
        raise ConfigError(f"{', '.join(BASE_KEYS)}: {exc}") from None
    return checked


def check_action(action: Action, arm: Arm, chassis: ChassisConfig | None) -> CheckedAction:
    """Every value of ``action`` checked against its limit (``arm``'s joints and gripper,
    ``chassis``'s speeds; None: the robot has no base), sending nothing: ConfigError
    naming the first key beyond one, its value and the range."""
    if action.joints_rad is None and action.gripper_gap_mm is None and action.base is None:
        raise ConfigError("the action has nothing to do: give joint targets "
                          f"(JOINT{JOINT_SUFFIX}), {GRIPPER_KEY} or a base twist "
                          f"({', '.join(BASE_KEYS)})")
    duration = None
    if action.duration_s is not None:
        if action.joints_rad is None:
            raise ConfigError(f"{DURATION_KEY} is the joints' move time: give joint targets "
                              "with it (the gripper goes at its own pace)")
        duration = _within(DURATION_KEY, action.duration_s, 0.0, arm.model.max_move_s, "s")
    least = None
    if action.min_duration_s is not None:
        if action.joints_rad is None or action.duration_s is not None:
            raise ConfigError(f"{MIN_DURATION_KEY} is the joints' shortest move time: give "
                              f"joint targets with it, and not {DURATION_KEY} too")
        least = _within(MIN_DURATION_KEY, action.min_duration_s, 0.0, arm.model.max_move_s,
                        "s")
    joints = None if action.joints_rad is None else _joint_targets(arm, action.joints_rad)
    gap = None
    if action.gripper_gap_mm is not None:
        gap = _within(GRIPPER_KEY, action.gripper_gap_mm, 0.0,
                      arm.config.gripper.widest_gap_mm, "mm")
    twist = None
    if action.base is not None:
        if chassis is None:
            raise ConfigError(f"{', '.join(BASE_KEYS)}: this robot has no base (its wheels "
                              "are on the controller board: a board:// port with a chassis, "
                              "BaseSpec(...) on hardware, a twin in an arena with "
                              "controller=BoardSettings())")
        twist = _twist(chassis, action.base)
    return CheckedAction(joints, gap, duration, twist, least)


def send_action(robot: Robot, action: ActionLike, *,
                read_deg: Sequence[float] | None = None) -> Action:
    """Check every value of ``action`` (an Action or its flat form), then send it: the
    joints first (whose speed check, which needs where the arm is now, comes before
    their move is sent, so a refusal there too leaves everything as it was), then the
    gripper, then the base. Returns what was sent: the joints' move time, and the twist
    the wheels were given (``Base.drive`` ramps toward the asked one within the
    acceleration limits). Waits for nothing. ``read_deg``: the joints as just read
    (``Arm.move_joints``), not read again."""
    asked = action if isinstance(action, Action) else Action.from_dict(action)
    checked = check_action(asked, robot.arm, None if robot.base is None
                           else robot.base.config)
    duration = None
    if checked.joints_deg is not None:
        duration = robot.arm.move_joints(checked.joints_deg, duration_s=checked.duration_s,
                                         min_duration_s=checked.min_duration_s, wait=False,
                                         read_deg=read_deg)
    if checked.gripper_gap_mm is not None:
        robot.arm.open_gripper(wait=False, gap_mm=checked.gripper_gap_mm)
    sent = None
    if checked.twist is not None and robot.base is not None:
        t = checked.twist
        sent = robot.base.drive(t.vx_m_s, t.vy_m_s, t.wz_rad_s)
    return Action(asked.joints_rad, checked.gripper_gap_mm, duration, sent)


def _camera_roles(robot: Robot, cameras: bool | str | Collection[str]) -> list[str]:
    """The roles of the cameras asked for: all (True), none (False), or those named."""
    if cameras is True:
        return list(robot.cameras)
    if cameras is False:
        return []
    named = [cameras] if isinstance(cameras, str) else list(cameras)
    unknown = [r for r in named if r not in robot.cameras]
    if unknown:
        raise ConfigError(f"no camera {listing(unknown)} on this robot; its cameras: "
                          f"{listing(robot.cameras) or 'none'}")
    return named


def _newest_scan(lidar: LidarSource, clock: Clock, timeout_s: float) -> LaserScan:
    """The newest complete revolution: those the Lidar queued since it was last read (a
    pause of a second queues ten) are passed over; with none queued, the next is waited
    for. A revolution is stale when a whole newer one has ended since it did."""
    scan = lidar.read_scan(timeout_s)
    for _ in range(MAX_STALE_SCANS):
        period = scan.scan_time_s if math.isfinite(scan.scan_time_s) else DEFAULT_SCAN_S
        if scan.stamp_s + period >= clock.now() - period:
            break
        scan = lidar.read_scan(timeout_s)
    return scan


def observe(robot: Robot, *, cameras: bool | str | Collection[str] = True,
            scan: bool = True, scan_timeout_s: float = SCAN_TIMEOUT_S) -> Observation:
    """Read every part of ``robot`` once (see ``Robot.get_observation``): the arm first,
    then the base's odometry, the cameras, and last the Lidar's newest revolution (when
    none is queued, the next is waited for: on a twin that moves its time on by up to a
    revolution)."""
    roles = _camera_roles(robot, cameras)
    check_range("scan_timeout_s", scan_timeout_s, 0.01, 60.0, "s")
    t_s = robot.clock.now()
    joints = robot.arm.read_joints_deg()
    gap = robot.arm.config.gripper.gap_mm_at(robot.arm.read_gripper_pulses())
    odometry = robot.base.odometry() if robot.base is not None else None
    frames = {role: robot.cameras[role].read() for role in roles}
    laser = (_newest_scan(robot.lidar, robot.clock, scan_timeout_s)
             if scan and robot.lidar is not None else None)
    return Observation(
        t_s, {j.name: math.radians(a) for j, a in zip(robot.arm.config.joints, joints,
                                                       strict=True)},
        min(gap, robot.arm.config.gripper.widest_gap_mm), odometry, laser, frames)
