"""The arm: a config, its kinematics and calibration, and a ServoPort.

``Arm`` moves it: joint moves, straight tool lines (planned by ``busarm.arm.line_plan``),
the gripper and action groups, on the servos of ``busarm.arm.arm_servos.ArmServos``: a
``ServoPort`` (busarm.bus.servo_port), whichever backend carries it.

Every motion is checked in full before the first byte goes out (joint limits, the
servos' own limits, speed limits, reachability of every waypoint), so a bad request
sends nothing. Any exception or Ctrl+C during a motion stops the arm and holds it
(MOVE_STOP) before it propagates; ``with Arm.open(...)`` does the same on leaving the
block with an error.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

from busarm.arm.actions import ActionFrame, ActionGroup
from busarm.arm.arm_servos import DEFAULT_TOLERANCE_DEG, ArmServos
from busarm.arm.calibration import Calibration, load_calibration
from busarm.arm.chain import Joints
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.gripper import HOLD_MIN_PULSES, HOLD_SQUEEZE_PULSES, gripper_state
from busarm.arm.guard import GuardedMove, GuardSettings, LineGuard
from busarm.arm.line_plan import (
    DEFAULT_LINE_SPEED_MM_S,
    DEFAULT_RATE_HZ,
    MAX_RATE_HZ,
    plan_line,
)
from busarm.arm.motion import check_line_request
from busarm.bus.driver import ServoBus
from busarm.bus.ports import PortSpec
from busarm.errors import ConfigError, LimitError

# Action frames are the vendor's files: LX servo positions, whatever the port.
from busarm.protocol.lx_units import POSITION_MAX_PULSES, POSITION_MIN_PULSES
from busarm.units import check_range, listing

DEFAULT_SPEED_DEG_S = 60.0
"""Joint speed of moves that give neither a duration nor a speed."""
HOLD_MOVE_S = 0.05
"""Easing a grip to its hold: the move's time (a few pulses), waited before reading."""


@dataclass(frozen=True)
class GripResult:
    """What the gripper did: where it stopped, and whether it holds something."""

    position_pulses: int
    is_holding: bool
    closed_pulses: int
    """Where it was told to close to."""
    hold_pulses: int | None = None
    """Holding: where it was then told to hold (``HOLD_SQUEEZE_PULSES`` inside where the
    fingers stopped, a light squeeze); None if it holds nothing."""

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

    def __repr__(self) -> str:
        return (f"MotionRecord({self.duration_s:.3f} s, {len(self.commanded_deg)} waypoints, "
                f"{len(self.measured)} measured)")


class Arm(ArmServos):
    """Command an arm in joint degrees or millimetres, on real servos or the simulator."""

    _hold_pulses: int | None = None
    """The hold the gripper was last told (``grip``), None once told anything else."""

    def __repr__(self) -> str:
        return f"Arm({self.config.name!r} on {self.bus.name})"

    @classmethod
    def open(
        cls,
        port: PortSpec | str,
        config: ArmConfig | str | Path | None = None,
        calibration: Calibration | str | Path | None = None,
        **bus_kwargs: object,
    ) -> Arm:
        """Open the bus on ``port`` (a ``PortSpec``: ``SimSpec()``, ``SerialPort(...)``, or a
        serial device's path) and check the arm's servos (and calibration) on it."""
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

    # ------------------------------------------------------------------ joint moves

    def move_joints(
        self,
        joints_deg: Sequence[float],
        *,
        duration_s: float | None = None,
        speed_deg_s: float | None = None,
        min_duration_s: float | None = None,
        wait: bool = True,
        tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
        read_deg: Sequence[float] | None = None,
    ) -> float:
        """Move all joints so that they start and arrive together; returns the duration.

        Give ``duration_s``, ``speed_deg_s`` (the fastest joint's speed; default
        DEFAULT_SPEED_DEG_S) or ``min_duration_s`` (at least this long, longer where a
        joint's top speed needs it: a stream of targets from a teleoperator or a policy).
        No joint ever exceeds its configured ``max_speed_deg_s``: a ``duration_s`` too
        short for that raises LimitError, sending nothing. ``read_deg``: the joints as the
        caller has just read them (within a frame), so the speeds are judged from there
        without reading them again.
        """
        if sum(v is not None for v in (duration_s, speed_deg_s, min_duration_s)) > 1:
            raise ConfigError("give one of duration_s, speed_deg_s, min_duration_s")
        pulses = self.servo_pulses(joints_deg)
        target = self.config.check_joints(joints_deg)
        with self._lock:
            current = self.read_joints_deg() if read_deg is None else tuple(read_deg)
            if len(current) != len(target):
                raise ConfigError(f"read_deg: {len(current)} angles for "
                                  f"{len(target)} joints")
            if min_duration_s is not None:
                check_range("min_duration_s", min_duration_s, 0.0, self.model.max_move_s, "s")
                duration_s = max(min_duration_s, self._joint_move_duration(
                    current, target, None, math.inf))
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
            if not math.isinf(speed):  # inf: each joint at its own top speed
                check_range("speed_deg_s", speed, 0.1, 1000.0, "deg/s")
            duration_s = max(
                d / min(speed, j.max_speed_deg_s)
                for d, j in zip(deltas, self.config.joints, strict=True)
            )
            duration_s = math.ceil(duration_s * 1000.0) / 1000.0  # whole ms, never faster
        check_range("duration_s", duration_s, 0.0, self.model.max_move_s, "s")
        for d, j in zip(deltas, self.config.joints, strict=True):
            if d > 1e-9 and (duration_s <= 0 or d / duration_s > j.max_speed_deg_s * (1 + 1e-9)):
                need = d / j.max_speed_deg_s
                raise LimitError(
                    f"{j.name} would turn {d:.1f} deg in {duration_s:g} s, faster than its "
                    f"{j.max_speed_deg_s:g} deg/s limit: allow at least {need:.2f} s"
                )
        return duration_s

    def home(self, **kwargs: float) -> float:
        """Go to the config's ``home`` pose."""
        return self.move_to_pose("home", **kwargs)

    def move_to_pose(self, name: str, **kwargs: float) -> float:
        """Go to one of the config's named joint poses (``home``, ``look``...: its
        ``[poses]``); ``kwargs`` as ``move_joints``. A ConfigError names the poses there are."""
        return self.move_joints(self.config.pose(name), **kwargs)  # type: ignore[arg-type]

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
        with self._lock:
            current = self.read_joints_deg()
            joints, _ = self.solve(x_mm, y_mm, z_mm, pitch_deg, roll_deg, current_deg=current)
            kwargs.setdefault("read_deg", current)  # (just read: not read again)
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
        return plan_line(
            self.config, self.kin, (x_mm, y_mm, z_mm, pitch_deg, roll_deg),
            start_deg=start_deg, speed_mm_s=speed_mm_s, duration_s=duration_s,
            profile=profile, rate_hz=rate_hz,
        )

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
        if max(steps) > self.model.max_move_s:
            raise ConfigError(f"waypoints must be at most {self.model.max_move_s:g} s apart")
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
            if record:  # the settling after the last waypoint, a sample every 10 ms
                end = t0 + times[-1] + 0.05
                while (now := self.clock.now()) < end:
                    result.measured.append((now - t0, self.read_joints_deg()))
                    # Waited, not read flat out: a read may take no time (a simulated
                    # line without wire timing), and the tail would then never end.
                    self.clock.sleep(min(0.01, end - now))

        with self._lock:
            self._guarded(run)
        return result

    # ------------------------------------------------------------------ gripper

    def _gripper_move(self, position_pulses: int, duration_s: float) -> None:
        g = self.config.gripper
        g.check_pulses(position_pulses)
        self._hold_pulses = None  # (a hold is told by _hold_at only)
        self.bus.move_deg(g.servo_id, self.model.deg_from_pulses(position_pulses), duration_s)

    def open_gripper(self, *, wait: bool = True, gap_mm: float | None = None,
                     until_gap_mm: float | None = None) -> int:
        """Open the gripper fully, or until the fingers are ``gap_mm`` apart (no wider than
        a grasp needs, to miss a neighbour); returns its position in pulses (its target
        if not waited for). ``until_gap_mm``: wait only until they are that far apart
        (a released block is free), the opening going on."""
        g = self.config.gripper
        target = g.open_pulses if gap_mm is None else g.pulses_for_gap_mm(gap_mm)
        duration = self._gripper_travel_s(target)
        self._guarded(lambda: self._gripper_move(target, duration))
        if not wait:
            return target
        if until_gap_mm is not None:
            deadline = self.clock.now() + duration + 0.1
            while self.clock.now() < deadline:
                now = self.bus.read_position_pulses(g.servo_id)
                if g.gap_mm_at(now) >= until_gap_mm:
                    return now
                self.clock.sleep(0.02)
        return self._settle_gripper(target, duration)

    def grip(self, position_pulses: int | None = None) -> GripResult:
        """Close (to ``position_pulses``, default fully closed) and tell whether it holds.

        A gripper that closes on an object stalls short of the target. Holding something,
        it is then told a hold just inside where the fingers stopped (a light squeeze: a
        stalled servo heats to its limit in about half a minute and lets go), and read
        back. ``position_pulses`` is where the fingers stand then.
        """
        g = self.config.gripper
        target = g.closed_pulses if position_pulses is None else position_pulses
        g.check_pulses(target)
        duration = self._gripper_travel_s(target)
        self._guarded(lambda: self._gripper_move(target, duration))
        final = self._settle_gripper(target, duration)
        # The one rule of busarm.arm.gripper: pressing on something = holding.
        if not gripper_state(g, final, target).is_holding:
            return GripResult(final, False, target)
        closing = 1 if g.closed_pulses >= g.open_pulses else -1
        hold = self._hold_from(final, target)
        now = self._hold_at(hold)
        if closing * (hold - now) < HOLD_MIN_PULSES:
            # The fingers went on closing after the settle (the block turned or gave):
            # the hold from where they stand now.
            hold = self._hold_from(now, target)
            now = self._hold_at(hold)
        return GripResult(now, gripper_state(g, now, hold).is_holding, target, hold)

    def check_hold(self) -> bool:
        """Whether the gripper still holds what it gripped.

        Read as ``read_gripper_state`` reads it; where that is unsure (the fingers apart
        but at the hold they were told: the block turned a little in them, or has gone),
        the hold is told a squeeze further in and read again: fingers that stop short of
        it press on something and keep that hold.
        """
        g = self.config.gripper
        with self._lock:
            state = self.read_gripper_state()
            told = self._hold_pulses
            if state.is_holding or state.state != "open" or told is None \
                    or state.target_pulses != told or state.torque_on is False:
                return state.is_holding
            hold = self._hold_from(state.position_pulses, g.closed_pulses)
            now = self._hold_at(hold)
            return gripper_state(g, now, hold).is_holding

    def _hold_from(self, stand: int, limit: int) -> int:
        """A hold ``HOLD_SQUEEZE_PULSES`` inside ``stand``, no further in than ``limit``."""
        g = self.config.gripper
        closing = 1 if g.closed_pulses >= g.open_pulses else -1
        hold = stand + closing * HOLD_SQUEEZE_PULSES
        return limit if closing * (limit - hold) < 0 else hold

    def hold_lighter(self) -> int | None:
        """Ease a hold to the lightest the gripper still reads as holding: told
        ``HOLD_MIN_PULSES`` inside where the fingers stand now (a hot gripper on a long
        carry). Returns the new hold, or None (nothing done) if it holds nothing."""
        g = self.config.gripper
        with self._lock:
            state = self.read_gripper_state()
            if not state.is_holding:
                return None
            closing = 1 if g.closed_pulses >= g.open_pulses else -1
            hold = state.position_pulses + closing * HOLD_MIN_PULSES
            if state.target_pulses is not None and closing * (state.target_pulses - hold) <= 0:
                return state.target_pulses  # already as light
            self._hold_at(hold)
            return hold

    def _hold_at(self, hold: int) -> int:
        """Tell the gripper ``hold`` (a few pulses from where it stands: no travel to
        wait for) and read where the fingers settle."""
        self.config.gripper.check_pulses(hold)
        self._guarded(lambda: self._gripper_move(hold, HOLD_MOVE_S))
        self._hold_pulses = hold
        self.clock.sleep(HOLD_MOVE_S)
        return self.bus.read_position_pulses(self.config.gripper.servo_id)

    close_gripper = grip

    def _gripper_travel_s(self, target: int) -> float:
        """How long the gripper takes from where it is to ``target``: its full travel's
        ``grip_time_s``, in proportion (a short opening is quick)."""
        g = self.config.gripper
        travel = abs(target - self.read_gripper_pulses())
        return max(0.05, g.grip_time_s * travel / abs(g.closed_pulses - g.open_pulses))

    def _settle_gripper(self, target: int, duration_s: float) -> int:
        """Wait for the gripper to arrive or stop moving (blocked); its final position."""
        g = self.config.gripper
        sent = self.clock.now()
        move_end = sent + duration_s + 0.1
        deadline = move_end + 2.0
        start = last = self.bus.read_position_pulses(g.servo_id)
        # Closing, it must arrive nearer than a hold's squeeze (else a gripper still
        # closing on nothing would read as holding); opening, a little short will do.
        closing = (g.closed_pulses - g.open_pulses) * (target - last) > 0
        near = HOLD_MIN_PULSES - 1 if closing else g.holding_margin_pulses // 4 + 1
        if abs(last - target) <= near:
            return last  # there already (opened while the arm moved)
        way = 1 if target > start else -1
        self.clock.sleep(min(duration_s, 0.05))
        still = 0
        while self.clock.now() < deadline:
            self.clock.sleep(0.03)
            now = self.bus.read_position_pulses(g.servo_id)
            if abs(now - target) <= near:
                return now
            still = still + 1 if abs(now - last) <= 1 else 0
            # The servo follows an even ramp to the target: stopped for three polls while
            # the ramp is a margin past it, or after the ramp's end, it is blocked.
            ramp = start + (target - start) * min(1.0, (self.clock.now() - sent) / duration_s)
            if still >= 3 and (self.clock.now() > move_end
                               or way * (ramp - now) > g.holding_margin_pulses):
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
