"""The arm: a config, its kinematics and calibration, and a ServoBus.

Every motion is checked in full before the first byte goes out (joint limits, the
servos' own limits, speed limits, reachability of every waypoint), so a bad request
sends nothing. Any exception or Ctrl+C during a motion stops the arm and holds it
(MOVE_STOP) before it propagates; ``with Arm.open(...)`` does the same on leaving the
block with an error.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

from busarm.arm.actions import ActionFrame, ActionGroup
from busarm.arm.calibration import Calibration, load_calibration
from busarm.arm.config import ArmConfig, JointConfig, load_arm_config
from busarm.arm.gripper import GripperState, gripper_state
from busarm.arm.guard import GuardedMove, GuardSettings, LineGuard
from busarm.arm.kinematics import ArmKinematics, Joints, Pose
from busarm.arm.motion import (
    LinePath,
    check_line_request,
    check_profile,
    duration_for_speed,
    sample_times,
)
from busarm.bus.driver import ServoBus
from busarm.clock import Clock
from busarm.errors import (
    BusTimeoutError,
    CalibrationError,
    ConfigError,
    LimitError,
    UnreachableError,
    UnreliableLineError,
)
from busarm.units import (
    CENTER_PULSES,
    DEG_PER_PULSE,
    MOVE_TIME_MAX_MS,
    POSITION_MAX_PULSES,
    POSITION_MIN_PULSES,
    check_range,
    listing,
)

log = logging.getLogger(__name__)

DEFAULT_SPEED_DEG_S = 60.0
"""Joint speed of moves that give neither a duration nor a speed."""
DEFAULT_LINE_SPEED_MM_S = 80.0
DEFAULT_RATE_HZ = 50.0
MAX_RATE_HZ = 100.0
SETTLE_TIMEOUT_S = 1.0
"""How long settled_joints_deg waits for the servos to stand still after a move's end."""
SETTLE_POLL_S = 0.1
DEFAULT_TOLERANCE_DEG = 1.5
"""Position feedback is whole pulses (0.24 deg), and a loaded servo settles a pulse or two
short; a wait within this counts as arrived."""
MAX_LINE_S = 600.0
"""The longest straight-line move planned."""
JUMP_DEG = 20.0
"""A joint change between two waypoints above this is a jump, not motion (at 50 Hz and
180 deg/s a joint moves 3.6 deg per waypoint)."""
MAX_TURN_SPEED_DEG_S = 90.0
"""Pitch and roll change no faster than this on a Cartesian line."""


@dataclass(frozen=True)
class GripResult:
    """What the gripper did: where it stopped, and whether it holds something."""

    position_pulses: int
    is_holding: bool
    closed_pulses: int

    @property
    def short_of_closed_pulses(self) -> int:
        return abs(self.closed_pulses - self.position_pulses)


@dataclass
class MotionRecord:
    """A streamed motion: the commanded waypoints and, if recorded, measured joints."""

    duration_s: float
    commanded_deg: list[tuple[float, ...]] = field(default_factory=list)
    measured: list[tuple[float, tuple[float, ...]]] = field(default_factory=list)
    """(seconds since the start, joint angles in degrees) read back during the motion."""


class Arm:
    """Command an arm in joint degrees or millimetres, on real servos or the simulator."""

    def __init__(
        self,
        bus: ServoBus,
        config: ArmConfig,
        calibration: Calibration | None = None,
        *,
        check: bool = True,
    ) -> None:
        self.bus = bus
        self.clock: Clock = bus.clock
        """Every wait of the arm's is on its bus's clock (simulated time on a twin)."""
        self.config = config
        self.kin = ArmKinematics.from_config(config)
        self.calibration = calibration or Calibration.identity(config)
        self.calibration.check_against(config)
        self._sw = {c.servo_id: c.software_offset_deg for c in self.calibration.joints}
        self._lock = threading.RLock()
        # Pulse limits per servo: the joint limits mapped through the calibration and
        # rounded inward, so a rounded command can never land outside a limit.
        self._pulse_limits: dict[int, tuple[int, int]] = {}
        for j in config.joints:
            self._pulse_limits[j.servo_id] = self._joint_pulse_limits(j)
        g = config.gripper
        self._pulse_limits[g.servo_id] = (g.min_pulses, g.max_pulses)
        if check:
            self._check_servos()
        for sid, (lo, hi) in self._pulse_limits.items():
            bus.set_limits_deg(
                sid, (lo - CENTER_PULSES) * DEG_PER_PULSE, (hi - CENTER_PULSES) * DEG_PER_PULSE
            )

    @classmethod
    def open(
        cls,
        port: str,
        config: ArmConfig | str | Path | None = None,
        calibration: Calibration | str | Path | None = None,
        **bus_kwargs: object,
    ) -> Arm:
        """Open the bus on ``port`` and check the arm's servos (and calibration) on it."""
        cfg = config if isinstance(config, ArmConfig) else load_arm_config(config or "jetauto_pro")
        cal = (
            calibration if isinstance(calibration, Calibration) or calibration is None
            else load_calibration(calibration)
        )
        bus = ServoBus.open(port, **bus_kwargs)  # type: ignore[arg-type]
        try:
            return cls(bus, cfg, cal)
        except BaseException:
            bus.close()
            raise

    def close(self) -> None:
        self.bus.close()

    def __enter__(self) -> Arm:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        # The bus's own exit: on an exception, the emergency stop (if anything was written
        # since the last one), then close.
        self.bus.__exit__(exc_type, exc, tb)

    # ------------------------------------------------------------------ checks

    def _joint_pulse_limits(self, j: JointConfig) -> tuple[int, int]:
        a = self.pulses_exact(j, j.min_deg)
        b = self.pulses_exact(j, j.max_deg)
        lo, hi = math.ceil(min(a, b) - 1e-9), math.floor(max(a, b) + 1e-9)
        lo, hi = max(lo, POSITION_MIN_PULSES), min(hi, POSITION_MAX_PULSES)
        if lo >= hi:
            raise CalibrationError(
                f"{j.name}: with its calibration the joint range maps outside the servo"
            )
        return lo, hi

    def _check_servos(self) -> None:
        """Every servo answers; stored offsets match the calibration; narrow the pulse
        limits to each servo's own stored angle limits."""
        for j in self.config.joints:
            cal = next(c for c in self.calibration.joints if c.servo_id == j.servo_id)
            try:
                offset_deg = self.bus.read_offset_deg(j.servo_id)
                lo_deg, hi_deg = self.bus.read_angle_limits_deg(j.servo_id)
            except UnreliableLineError:
                raise  # not "does not answer": it may, late (the driver's words)
            except BusTimeoutError as exc:
                raise BusTimeoutError(
                    f"{j.name} (servo {j.servo_id}) does not answer: check the cable, the "
                    f"power and the ID (`busarm scan`)",
                    servo_id=j.servo_id, command=exc.command, timeout_s=exc.timeout_s,
                ) from exc
            if abs(offset_deg - cal.hardware_offset_deg) > 1e-6:
                raise CalibrationError(
                    f"{j.name} (servo {j.servo_id}) has a stored offset of {offset_deg:+.2f} deg "
                    f"but the calibration says {cal.hardware_offset_deg:+.2f} deg: was the servo "
                    f"replaced or re-zeroed? Run `busarm arm calibrate`"
                )
            self._narrow(j.servo_id, lo_deg, hi_deg)
        g = self.config.gripper
        try:
            lo_deg, hi_deg = self.bus.read_angle_limits_deg(g.servo_id)
        except UnreliableLineError:
            raise
        except BusTimeoutError as exc:
            raise BusTimeoutError(
                f"the gripper (servo {g.servo_id}) does not answer",
                servo_id=g.servo_id, command=exc.command, timeout_s=exc.timeout_s,
            ) from exc
        self._narrow(g.servo_id, lo_deg, hi_deg)

    def _narrow(self, servo_id: int, lo_deg: float, hi_deg: float) -> None:
        lo, hi = self._pulse_limits[servo_id]
        slo = round(lo_deg / DEG_PER_PULSE) + CENTER_PULSES
        shi = round(hi_deg / DEG_PER_PULSE) + CENTER_PULSES
        nlo, nhi = max(lo, slo), min(hi, shi)
        if nlo >= nhi:
            raise LimitError(
                f"servo {servo_id}'s stored angle limits {slo}..{shi} pulses leave nothing of "
                f"its configured range {lo}..{hi}: widen them with `busarm limits`"
            )
        self._pulse_limits[servo_id] = (nlo, nhi)

    # ------------------------------------------------------------------ conversions

    @property
    def pulse_limits(self) -> dict[int, tuple[int, int]]:
        """Each servo's allowed positions (pulses): its joint's limits, the gripper's range."""
        return dict(self._pulse_limits)

    def pulses_exact(self, joint: JointConfig, angle_deg: float) -> float:
        """The (fractional) servo position for a joint angle, with the calibration."""
        servo_deg = joint.servo_deg_from_angle_deg(angle_deg) + self._sw[joint.servo_id]
        return CENTER_PULSES + servo_deg / DEG_PER_PULSE

    def joint_deg_from_servo_deg(self, joint: JointConfig, servo_deg: float) -> float:
        return joint.angle_deg_from_servo_deg(servo_deg - self._sw[joint.servo_id])

    def servo_pulses(self, joints_deg: Sequence[float]) -> dict[int, int]:
        """Servo positions for joint angles; LimitError before anything is sent if any
        joint is outside its limits or would leave its servo's range."""
        angles = self.config.check_joints(joints_deg)
        out = {}
        for j, a in zip(self.config.joints, angles, strict=True):
            p = self.pulses_exact(j, a)
            lo, hi = self._pulse_limits[j.servo_id]
            # Within the joint limits the exact value is within [lo, hi] up to the
            # inward rounding of the limits; clamping moves it by under one pulse.
            if not lo - 1.0 <= p <= hi + 1.0:
                raise LimitError(
                    f"{j.name} = {a:.2f} deg needs servo {j.servo_id} at {p:.0f} pulses, outside "
                    f"its limits {lo}..{hi} pulses (servo angle limits or calibration)"
                )
            out[j.servo_id] = min(max(round(p), lo), hi)
        return out

    def joints_from_pulses(self, pulses: Mapping[int, float]) -> Joints:
        """Joint angles for servo positions (calibrated)."""
        a = [
            self.joint_deg_from_servo_deg(j, (pulses[j.servo_id] - CENTER_PULSES) * DEG_PER_PULSE)
            for j in self.config.joints
        ]
        return (a[0], a[1], a[2], a[3], a[4])

    # ------------------------------------------------------------------ reading

    def read_joints_deg(self) -> Joints:
        """The measured joint angles (one position read per joint)."""
        with self._lock:
            pulses = {
                j.servo_id: self.bus.read_position_pulses(j.servo_id) for j in self.config.joints
            }
        return self.joints_from_pulses(pulses)

    def read_pose(self) -> Pose:
        """The tool pose from the measured joints."""
        return self.kin.fk(self.read_joints_deg())

    def read_gripper_pulses(self) -> int:
        return self.bus.read_position_pulses(self.config.gripper.servo_id)

    def read_gripper_state(self) -> GripperState:
        """Open, closed or holding (``busarm.arm.gripper``), from the gripper's position,
        the position it was last told and its torque, read back."""
        sid = self.config.gripper.servo_id
        position = self.bus.read_position_pulses(sid)
        target = self.bus.last_target_pulses(sid)
        return gripper_state(self.config.gripper, position, target, self.bus.read_torque(sid))

    # ------------------------------------------------------------------ joint moves

    def move_joints(
        self,
        joints_deg: Sequence[float],
        *,
        duration_s: float | None = None,
        speed_deg_s: float | None = None,
        wait: bool = True,
        tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
    ) -> float:
        """Move all joints so that they start and arrive together; returns the duration.

        Give ``duration_s`` or ``speed_deg_s`` (the fastest joint's speed; default
        DEFAULT_SPEED_DEG_S). No joint ever exceeds its configured ``max_speed_deg_s``:
        a duration too short for that raises LimitError, sending nothing.
        """
        if duration_s is not None and speed_deg_s is not None:
            raise ConfigError("give duration_s or speed_deg_s, not both")
        pulses = self.servo_pulses(joints_deg)
        target = self.config.check_joints(joints_deg)
        with self._lock:
            current = self.read_joints_deg()
            duration = self._joint_move_duration(current, target, duration_s, speed_deg_s)
            self._guarded(lambda: self._send_pulses(pulses, duration))
            if wait:
                self.wait(target, tolerance_deg=tolerance_deg)
        return duration

    def _joint_move_duration(
        self, current: Sequence[float], target: Sequence[float],
        duration_s: float | None, speed_deg_s: float | None,
    ) -> float:
        deltas = [abs(t - c) for t, c in zip(target, current, strict=True)]
        if duration_s is None:
            speed = DEFAULT_SPEED_DEG_S if speed_deg_s is None else speed_deg_s
            check_range("speed_deg_s", speed, 0.1, 1000.0, "deg/s")
            duration_s = max(
                d / min(speed, j.max_speed_deg_s)
                for d, j in zip(deltas, self.config.joints, strict=True)
            )
            duration_s = math.ceil(duration_s * 1000.0) / 1000.0  # whole ms, never faster
        check_range("duration_s", duration_s, 0.0, MOVE_TIME_MAX_MS / 1000.0, "s")
        for d, j in zip(deltas, self.config.joints, strict=True):
            if d > 1e-9 and (duration_s <= 0 or d / duration_s > j.max_speed_deg_s * (1 + 1e-9)):
                need = d / j.max_speed_deg_s
                raise LimitError(
                    f"{j.name} would turn {d:.1f} deg in {duration_s:g} s, faster than its "
                    f"{j.max_speed_deg_s:g} deg/s limit: allow at least {need:.2f} s"
                )
        return duration_s

    def command_joints(self, joints_deg: Sequence[float], duration_s: float) -> None:
        """Send joint targets to arrive in ``duration_s``, reading nothing and not waiting
        (a caller that streams small steps and knows where the arm is: a jog). Joint
        limits are checked; the caller keeps each step within the joints' speeds."""
        check_range("duration_s", duration_s, 0.0, MOVE_TIME_MAX_MS / 1000.0, "s")
        self._send_pulses(self.servo_pulses(joints_deg), duration_s)

    def _send_pulses(self, pulses: Mapping[int, int], duration_s: float) -> None:
        targets = {sid: (p - CENTER_PULSES) * DEG_PER_PULSE for sid, p in pulses.items()}
        self.bus.sync_move_deg(targets, duration_s)

    def wait(
        self,
        joints_deg: Sequence[float],
        *,
        tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
        timeout_s: float | None = None,
    ) -> Joints:
        """Wait until the measured joints are within ``tolerance_deg`` of ``joints_deg``.

        Default timeout: the end of the last commanded move plus 2 s. Raises
        MotionTimeoutError naming the joints that did not arrive.
        """
        target = self.config.check_joints(joints_deg)
        servo_targets = {
            j.servo_id: (self.pulses_exact(j, a) - CENTER_PULSES) * DEG_PER_PULSE
            for j, a in zip(self.config.joints, target, strict=True)
        }
        # Joint and servo degrees differ only by sign and offset: the tolerance carries over.
        positions = self.bus.wait_until_reached(
            servo_targets, tolerance_deg=tolerance_deg, timeout_s=timeout_s
        )
        return self.joints_from_pulses(
            {sid: deg / DEG_PER_PULSE + CENTER_PULSES for sid, deg in positions.items()}
        )

    def settled_joints_deg(self, *, timeout_s: float = SETTLE_TIMEOUT_S) -> Joints:
        """The measured joints once the last commanded move has ended and the servos
        stand still (two reads SETTLE_POLL_S apart within a pulse), or ``timeout_s`` after
        its end: where the arm stays, as a later read finds it. A ``wait`` returns within
        tolerance, while the servos may still be closing the last degree or two."""
        end_s = self.bus.move_end_s(j.servo_id for j in self.config.joints)
        self.clock.sleep(max(end_s - self.clock.now(), 0.0))
        deadline = self.clock.now() + timeout_s
        last = self.read_joints_deg()
        while self.clock.now() < deadline:
            self.clock.sleep(SETTLE_POLL_S)
            now = self.read_joints_deg()
            if max(abs(a - b) for a, b in zip(now, last, strict=True)) <= DEG_PER_PULSE:
                return now
            last = now
        return last

    def home(self, **kwargs: float) -> float:
        """Go to the config's ``home`` pose."""
        return self.move_joints(self.config.pose("home"), **kwargs)  # type: ignore[arg-type]

    def stop(self) -> None:
        """Stop every servo where it is and hold it (MOVE_STOP)."""
        self.bus.emergency_stop()

    def hold_here(self) -> list[int]:
        """Torque on where each servo stands (a move to its present position), so that
        nothing jumps. Servos found outside their limits are left limp (never commanded
        outside them); returns their IDs."""
        limp = []
        for sid in self.config.servo_ids:
            position = self.bus.read_position_pulses(sid)
            lo, hi = self._pulse_limits[sid]
            if lo <= position <= hi:
                self.bus.move_pulses(sid, position, 0)
            else:
                limp.append(sid)
        return limp

    def set_torque(self, enabled: bool) -> None:
        """Torque on (hold) or off (limp: the arm falls under its own weight) for all servos."""
        for sid in self.config.servo_ids:
            self.bus.set_torque(sid, enabled)

    # ------------------------------------------------------------------ Cartesian

    def solve(
        self, x_mm: float, y_mm: float, z_mm: float, pitch_deg: float | None = None,
        roll_deg: float | None = None, *, current_deg: Sequence[float] | None = None,
    ) -> tuple[Joints, float]:
        """Joint angles and pitch for a tool point; without a pitch the free-pitch rule
        picks it (nearest the config's preferred pitch, then the smallest motion)."""
        if pitch_deg is None:
            return self.kin.ik_free_pitch(
                x_mm, y_mm, z_mm, roll_deg,
                preferred_pitch_deg=self.config.preferred_pitch_deg, current_deg=current_deg,
            )
        return self.kin.ik_best(
            x_mm, y_mm, z_mm, pitch_deg, roll_deg, current_deg=current_deg
        ), float(pitch_deg)

    def move_to(
        self, x_mm: float, y_mm: float, z_mm: float, pitch_deg: float | None = None,
        roll_deg: float | None = None, **kwargs: object,
    ) -> Joints:
        """Joint-interpolated move to a tool pose (synchronized arrival); returns the joints.

        Keyword arguments are move_joints'.
        """
        joints, _ = self.solve(
            x_mm, y_mm, z_mm, pitch_deg, roll_deg, current_deg=self.read_joints_deg()
        )
        self.move_joints(joints, **kwargs)  # type: ignore[arg-type]
        return joints

    def plan_line(
        self,
        x_mm: float, y_mm: float, z_mm: float, pitch_deg: float | None = None,
        roll_deg: float | None = None, *,
        start_deg: Sequence[float],
        speed_mm_s: float = DEFAULT_LINE_SPEED_MM_S,
        duration_s: float | None = None,
        profile: str = "min_jerk",
        rate_hz: float = DEFAULT_RATE_HZ,
    ) -> tuple[list[float], list[Joints]]:
        """Waypoint times and joints of a straight tool line from ``start_deg``.

        Pure planning (no bus): every waypoint solved and checked; the duration is
        stretched until no joint exceeds its speed limit between waypoints. Raises
        UnreachableError naming the first waypoint that cannot be reached.
        """
        check_line_request(
            (x_mm, y_mm, z_mm, pitch_deg, roll_deg), speed_mm_s=speed_mm_s,
            duration_s=duration_s, profile=profile, rate_hz=rate_hz, max_rate_hz=MAX_RATE_HZ,
        )
        fn, _ = check_profile(profile)
        start_q = self.config.check_joints(start_deg)
        start = self.kin.fk(start_q)
        pitch = start.pitch_deg if pitch_deg is None else pitch_deg
        roll = start.roll_deg if roll_deg is None else roll_deg
        end = (float(x_mm), float(y_mm), float(z_mm), float(pitch), float(roll))
        path = LinePath(tuple(start), end)  # type: ignore[arg-type]
        # The end must be reachable from the start's branch; check it first for a clear error.
        self.kin.ik_best(*end, current_deg=start_q)
        if duration_s is None:
            duration_s = max(
                duration_for_speed(profile, path.length_mm, speed_mm_s),
                duration_for_speed(profile, path.turn_deg, MAX_TURN_SPEED_DEG_S),
                1.0 / rate_hz,
            )
        for _ in range(8):
            times = sample_times(duration_s, rate_hz)
            joints: list[Joints] = []
            previous: Sequence[float] = start_q
            for k, t in enumerate(times, start=1):
                pose = path.at(fn(t / duration_s))
                try:
                    q = self.kin.ik_best(*pose, current_deg=previous)
                except UnreachableError as exc:
                    raise UnreachableError(
                        f"the line leaves the workspace at waypoint {k}/{len(times)} "
                        f"({pose[0]:.1f}, {pose[1]:.1f}, {pose[2]:.1f}) mm: {exc}",
                        exc.reason, exc.joint,
                    ) from None
                joints.append(q)
                previous = q
            steps = zip([start_q, *joints[:-1]], joints, strict=True)
            if any(abs(a - b) > JUMP_DEG for p, q in steps for a, b in zip(p, q, strict=True)):
                raise LimitError(
                    "the line needs a joint to jump (it passes a singularity, such as the "
                    "base axis, or switches elbow): move there with move_to instead"
                )
            ratio = self._speed_ratio(start_q, times, joints)
            if ratio <= 1.0:
                return times, joints
            duration_s *= ratio * 1.02
            if duration_s > MAX_LINE_S:
                break
        raise LimitError(
            f"the line would take over {MAX_LINE_S:g} s within the joints' speed limits: "
            "move there with move_to, or in shorter lines"
        )

    def _speed_ratio(
        self, start: Sequence[float], times: list[float], joints: list[Joints]
    ) -> float:
        """The largest joint speed between waypoints over its limit (1.0 = at the limit)."""
        worst = 0.0
        prev_t, prev_q = 0.0, start
        for t, q in zip(times, joints, strict=True):
            dt = t - prev_t
            for j, a, b in zip(self.config.joints, q, prev_q, strict=True):
                worst = max(worst, abs(a - b) / dt / j.max_speed_deg_s)
            prev_t, prev_q = t, q
        return worst

    def move_line(
        self,
        x_mm: float, y_mm: float, z_mm: float, pitch_deg: float | None = None,
        roll_deg: float | None = None, *,
        speed_mm_s: float = DEFAULT_LINE_SPEED_MM_S,
        duration_s: float | None = None,
        profile: str = "min_jerk",
        rate_hz: float = DEFAULT_RATE_HZ,
        record: bool = False,
        wait: bool = True,
    ) -> MotionRecord:
        """Move the tool point along a straight line with a smooth speed profile.

        Waypoints from interpolated IK are streamed at ``rate_hz``; each is a
        synchronized move lasting one period, sent one period ahead, so the servos move
        continuously. Without a pitch or roll the start's are kept. ``record`` reads the
        joints back during the motion (for tracking checks and the demo's tool path).
        """
        with self._lock:
            start = self.read_joints_deg()
            times, joints = self.plan_line(
                x_mm, y_mm, z_mm, pitch_deg, roll_deg, start_deg=start, speed_mm_s=speed_mm_s,
                duration_s=duration_s, profile=profile, rate_hz=rate_hz,
            )
            result = self.stream(times, joints, record=record)
            if wait:
                self.wait(joints[-1])
            return result

    def move_line_guarded(
        self,
        x_mm: float, y_mm: float, z_mm: float, pitch_deg: float | None = None,
        roll_deg: float | None = None, *,
        speed_mm_s: float = DEFAULT_LINE_SPEED_MM_S,
        duration_s: float | None = None,
        profile: str = "min_jerk",
        rate_hz: float = DEFAULT_RATE_HZ,
        guard: GuardSettings | None = None,
    ) -> GuardedMove:
        """``move_line``, watched for contact (busarm.arm.guard): a joint that stops short
        of its commanded path stops the arm, which goes straight back to the line's start;
        then ContactError (``backed_off`` False: it could not, and is stopped, holding).
        Bad arguments: ConfigError before anything is sent."""
        check_line_request(
            (x_mm, y_mm, z_mm, pitch_deg, roll_deg), speed_mm_s=speed_mm_s,
            duration_s=duration_s, profile=profile, rate_hz=rate_hz, max_rate_hz=MAX_RATE_HZ,
        )
        with self._lock:
            watch = LineGuard(self, guard, DEFAULT_TOLERANCE_DEG)
            start = watch.settled_start()
            times, joints = self.plan_line(
                x_mm, y_mm, z_mm, pitch_deg, roll_deg, start_deg=start, speed_mm_s=speed_mm_s,
                duration_s=duration_s, profile=profile, rate_hz=rate_hz,
            )
            return watch.run(times, joints, start)

    def stream(
        self, times: Sequence[float], joints: Sequence[Sequence[float]], *, record: bool = False
    ) -> MotionRecord:
        """Send joint waypoints on schedule (times in s after the start, increasing).

        Every waypoint is converted and checked before the first is sent. On any
        exception (Ctrl+C included) the arm is stopped and held, then it propagates.
        """
        if len(times) != len(joints) or not times:
            raise ConfigError("stream needs as many times as waypoints, at least one")
        pulses = [self.servo_pulses(q) for q in joints]
        steps = [b - a for a, b in zip([0.0, *times[:-1]], times, strict=True)]
        if min(steps) <= 0:
            raise ConfigError("waypoint times must increase")
        if max(steps) > MOVE_TIME_MAX_MS / 1000.0:
            raise ConfigError("waypoints must be at most 30 s apart")
        result = MotionRecord(duration_s=times[-1])

        def run() -> None:
            t0 = self.clock.now()
            for k, (step, p) in enumerate(zip(steps, pulses, strict=True)):
                send_at = t0 + times[k] - step
                delay = send_at - self.clock.now()
                if delay > 0:
                    self.clock.sleep(delay)
                # Late (a slow bus): the servo still arrives one step after this send.
                self._send_pulses(p, step)
                result.commanded_deg.append(tuple(joints[k]))
                if record:
                    result.measured.append((self.clock.now() - t0, self.read_joints_deg()))
            if record:
                end = t0 + times[-1] + 0.05
                while self.clock.now() < end:
                    result.measured.append((self.clock.now() - t0, self.read_joints_deg()))

        with self._lock:
            self._guarded(run)
        return result

    def _guarded(self, action: Callable[[], None]) -> None:
        """Run a motion; on any exception stop and hold the arm, then re-raise."""
        try:
            action()
        except BaseException:
            self.bus.emergency_stop()
            raise

    # ------------------------------------------------------------------ gripper

    def _gripper_move(self, position_pulses: int, duration_s: float) -> None:
        g = self.config.gripper
        g.check_pulses(position_pulses)
        self.bus.move_pulses(g.servo_id, position_pulses, round(duration_s * 1000))

    def open_gripper(self, *, wait: bool = True, gap_mm: float | None = None) -> int:
        """Open the gripper fully, or until the fingers are ``gap_mm`` apart (no wider than
        a grasp needs, to miss a neighbour); returns its position in pulses."""
        g = self.config.gripper
        target = g.open_pulses if gap_mm is None else g.pulses_for_gap_mm(gap_mm)
        duration = self._gripper_travel_s(target)
        self._guarded(lambda: self._gripper_move(target, duration))
        if wait:
            return self._settle_gripper(target, duration)
        return target

    def grip(self, position_pulses: int | None = None) -> GripResult:
        """Close (to ``position_pulses``, default fully closed) and tell whether it holds.

        A gripper that closes on an object stalls short of the target: if it settles
        more than ``holding_margin_pulses`` short, it is holding something.
        """
        g = self.config.gripper
        target = g.closed_pulses if position_pulses is None else position_pulses
        g.check_pulses(target)
        duration = self._gripper_travel_s(target)
        self._guarded(lambda: self._gripper_move(target, duration))
        final = self._settle_gripper(target, duration)
        # The one rule of busarm.arm.gripper: stalled short of where it was told = holding.
        holding = gripper_state(g, final, target).is_holding
        return GripResult(final, holding, target)

    close_gripper = grip

    def _gripper_travel_s(self, target: int) -> float:
        """How long the gripper takes from where it is to ``target``: its full travel's
        ``grip_time_s``, in proportion (a short opening is quick)."""
        g = self.config.gripper
        travel = abs(target - self.read_gripper_pulses())
        return max(0.05, g.grip_time_s * travel / abs(g.closed_pulses - g.open_pulses))

    def _settle_gripper(self, target: int, duration_s: float) -> int:
        """Wait for the gripper to arrive or stop moving (blocked); its final position."""
        sid = self.config.gripper.servo_id
        margin = self.config.gripper.holding_margin_pulses
        move_end = self.clock.now() + duration_s + 0.1
        deadline = move_end + 2.0
        self.clock.sleep(min(duration_s, 0.05))
        last = self.bus.read_position_pulses(sid)
        still = 0
        while self.clock.now() < deadline:
            self.clock.sleep(0.03)
            now = self.bus.read_position_pulses(sid)
            if abs(now - target) <= margin // 4 + 1:
                return now
            still = still + 1 if abs(now - last) <= 1 else 0
            # Stopped short for three polls after the move should have ended: blocked.
            if still >= 3 and self.clock.now() > move_end:
                return now
            last = now
        return last

    # ------------------------------------------------------------------ action groups

    def action_targets(
        self, group: ActionGroup
    ) -> list[tuple[float, tuple[float, ...], int | None]]:
        """Check a whole action group before playing it: (seconds, joints, gripper pulses).

        The file's pulses are the vendor's nominal servo positions (its servos carry
        their calibration in their hardware offsets); they become joint angles through
        the config's pulse map, so the software calibration applies on playback.
        """
        columns = self.config.action_columns
        if group.servo_count != len(columns):
            raise ConfigError(
                f"the action group has {group.servo_count} servo columns; this arm maps "
                f"{len(columns)} (servos {listing(columns)})"
            )
        out = []
        gid = self.config.gripper.servo_id
        for n, frame in enumerate(group.frames, start=1):
            by_id = dict(zip(columns, frame.positions_pulses, strict=True))
            try:
                joints = tuple(
                    j.angle_deg_from_pulses(by_id[j.servo_id]) if j.servo_id in by_id
                    else math.nan
                    for j in self.config.joints
                )
                if any(math.isnan(a) for a in joints):
                    raise ConfigError("the action group does not drive every joint")
                self.servo_pulses(joints)
                grip = by_id.get(gid)
                if grip is not None:
                    self.config.gripper.check_pulses(grip)
            except ConfigError as exc:
                raise ConfigError(f"action frame {n}: {exc}") from None
            out.append((frame.duration_ms / 1000.0, self.config.check_joints(joints), grip))
        return out

    def play(
        self, group: ActionGroup, *, stop_event: threading.Event | None = None,
        speed_scale: float = 1.0, on_frame: Callable[[int], None] | None = None,
    ) -> int:
        """Play an action group frame by frame; returns how many frames were played.

        Each frame moves every servo over its time, then waits that time (the vendor's
        playback). Setting ``stop_event`` stops the arm and holds it between or during
        frames. The whole group is checked before the first frame is sent. ``on_frame(n)``
        is called as frame n (from 1) has been sent, so an interruption can say where.
        """
        check_range("speed_scale", speed_scale, 0.1, 10.0)
        frames = self.action_targets(group)
        stop = stop_event or threading.Event()
        played = 0

        # Speeds too, frame to frame (the first from where the arm is), before any move.
        previous: Sequence[float] = self.read_joints_deg()
        for n, (seconds, joints, _) in enumerate(frames, start=1):
            try:
                self._joint_move_duration(previous, joints, seconds / speed_scale, None)
            except LimitError as exc:
                raise LimitError(f"action frame {n}: {exc}") from None
            previous = joints

        def run() -> None:
            nonlocal played
            gid = self.config.gripper.servo_id
            for seconds, joints, grip in frames:
                if stop.is_set():
                    break
                duration = seconds / speed_scale
                pulses = self.servo_pulses(joints)
                if grip is not None:
                    pulses[gid] = grip
                self._send_pulses(pulses, duration)
                played += 1
                if on_frame is not None:
                    on_frame(played)
                if self.clock.wait(stop, duration):
                    break
            if stop.is_set():
                self.stop()

        with self._lock:
            self._guarded(run)
        return played

    def record_frame(self, duration_ms: int) -> ActionFrame:
        """The present pose as an action frame (the vendor's nominal pulses)."""
        columns = self.config.action_columns
        joints = self.read_joints_deg()
        by_id: dict[int, int] = {}
        for j, a in zip(self.config.joints, joints, strict=True):
            nominal = j.pulses_from_angle_deg(a)
            by_id[j.servo_id] = min(max(round(nominal), POSITION_MIN_PULSES), POSITION_MAX_PULSES)
        gid = self.config.gripper.servo_id
        if gid in columns:
            by_id[gid] = min(
                max(self.read_gripper_pulses(), POSITION_MIN_PULSES), POSITION_MAX_PULSES
            )
        try:
            return ActionFrame(duration_ms, tuple(by_id[c] for c in columns))
        except KeyError as exc:
            raise ConfigError(f"action column servo {exc} is not part of this arm") from None


__all__ = ["DEFAULT_SPEED_DEG_S", "Arm", "GripResult", "MotionRecord"]
