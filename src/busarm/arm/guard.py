"""Guarded straight lines: a move that notices it is blocked, backs off and says so.

``Arm.move_line_guarded`` streams a straight tool line as ``Arm.move_line`` does and, in
the slack between waypoints (every ``sample_every``-th; the sends keep their times),
reads the joints back. Each reading is compared with where the commands sent so far
have that joint at that moment (each waypoint a uniform move lasting one period from
when it was actually sent). A free servo trails its command by a little, more when it
moves fast; one whose link has landed on something stalls (its torque is capped) while
the command goes on, so its lag grows at the joint's speed. A joint that trails by more
than ``max_lag_deg + lag_time_s * |commanded speed|`` at ``confirm_samples`` readings in
a row (a suspect reading is confirmed at the very next waypoint) has stopped short; so
has one still more than that, or the arrival tolerance, off its target once the line
has ended and had ``SETTLE_S`` to settle.

Then the arm is stopped and held (MOVE_STOP), goes straight back to where the line
started at ``backoff_speed_mm_s``, and ``ContactError`` says which joint, how far along
the line and where the tool was. If the way back fails too, the arm is stopped and
holding and the ``ContactError`` says it did not back off (the cause chained).

Calibration on the twin (``tests/twin/test_contact.py`` repeats a smaller sweep): 276
free lines over the workspace (descents, lifts and sideways lines; pitch -90 and -45,
roll 0 and 40; peak speeds 60, 120, 200 and 300 mm/s) trailed by at most 0.50, 0.66,
0.98 and 1.09 deg, never over 0.46 of the allowance. Fingers landing on a block were
caught 65-85 ms after the touch at 200 mm/s, 77-101 ms at 120 mm/s and 148-167 ms at
60 mm/s (a slow joint takes longer to fall a threshold behind). Real servos trail
more: measure yours with ``GuardedMove.worst_lag_fraction`` on free lines and raise the
allowance to keep it under about 0.5.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from busarm.arm.chain import Joints, Pose
from busarm.errors import ConfigError, ContactError, MotionTimeoutError
from busarm.units import check_int_range, check_range

if TYPE_CHECKING:
    from busarm.arm.arm import Arm

DEFAULT_MAX_LAG_DEG = 1.0
"""Lag behind the commanded path allowed a joint at rest: gravity sag and whole pulses
(free twin joints: up to 0.4 deg below 5 deg/s)."""
DEFAULT_LAG_TIME_S = 0.01
"""Further lag allowed per deg/s of commanded joint speed (free twin joints: about
0.006 s, up to 1.1 deg at 60-200 deg/s)."""
DEFAULT_SAMPLE_EVERY = 2
"""Read the joints back after every this many waypoints (at 50 Hz: every 40 ms)."""
DEFAULT_CONFIRM_SAMPLES = 2
"""Readings in a row over the threshold, on the same joint, that make a contact."""
DEFAULT_BACKOFF_SPEED_MM_S = 50.0
"""Peak tool speed of the way back after a contact."""
SETTLE_S = 0.25
"""After the line's last waypoint, the servos' time to close their normal lag."""
SETTLE_TIMEOUT_S = 2.0
"""After the line, the longest wait for the joints to arrive (as ``Arm.wait``)."""
POLL_S = 0.02
START_STILL_DEG = 0.3
START_STILL_READINGS = 3
"""Readings a poll apart, each joint's within START_STILL_DEG (a pulse and a little), say
the arm stands still: their span (~60 ms) is over a quarter of its ringing period."""
START_SETTLE_MAX_S = 0.5


@dataclass(frozen=True)
class LagSample:
    """One reading during a guarded line."""

    t_s: float
    """Seconds since the line started (when its first waypoint was sent)."""
    measured_deg: Joints
    lag_deg: tuple[float, ...]
    """|commanded - measured| per joint, each at the moment that joint was read."""
    allowed_deg: tuple[float, ...]
    """The lag allowed per joint at that moment (more while the joint is commanded fast)."""


@dataclass
class GuardedMove:
    """A guarded line that arrived: its readings, to see how close it came to tripping."""

    duration_s: float
    joint_names: tuple[str, ...]
    samples: list[LagSample] = field(default_factory=list)
    late_s: float = 0.0
    """The latest any waypoint was sent after its time (readings must not delay them)."""

    @property
    def worst_lag_deg(self) -> float:
        """The largest lag of any joint at any reading."""
        return max((max(s.lag_deg) for s in self.samples), default=0.0)

    @property
    def worst_joint(self) -> str | None:
        """The joint with the largest lag (None without readings)."""
        if not self.samples:
            return None
        worst = max(self.samples, key=lambda s: max(s.lag_deg))
        return self.joint_names[worst.lag_deg.index(max(worst.lag_deg))]

    @property
    def worst_lag_fraction(self) -> float:
        """The largest lag as a fraction of what was allowed then (1.0 would trip)."""
        return max((lag / allowed for s in self.samples
                    for lag, allowed in zip(s.lag_deg, s.allowed_deg, strict=True)), default=0.0)


@dataclass(frozen=True)
class GuardSettings:
    """How a guarded line is watched; checked on construction (ConfigError).

    A joint may trail its commanded path by ``max_lag_deg`` plus ``lag_time_s`` times
    its commanded speed (a servo follows its command with a small delay); more than that
    at ``confirm_samples`` readings in a row is contact.
    """

    max_lag_deg: float = DEFAULT_MAX_LAG_DEG
    lag_time_s: float = DEFAULT_LAG_TIME_S
    sample_every: int = DEFAULT_SAMPLE_EVERY
    confirm_samples: int = DEFAULT_CONFIRM_SAMPLES
    backoff_speed_mm_s: float = DEFAULT_BACKOFF_SPEED_MM_S

    def __post_init__(self) -> None:
        check_range("max_lag_deg", self.max_lag_deg, 0.3, 90.0, "deg")
        check_range("lag_time_s", self.lag_time_s, 0.0, 1.0, "s")
        check_int_range("sample_every", self.sample_every, 1, 50)
        check_int_range("confirm_samples", self.confirm_samples, 1, 20)
        check_range("backoff_speed_mm_s", self.backoff_speed_mm_s, 5.0, 200.0, "mm/s")

    def allowed_deg(self, speed_deg_s: float) -> float:
        """The lag allowed a joint commanded at ``speed_deg_s``."""
        return self.max_lag_deg + self.lag_time_s * abs(speed_deg_s)


class _Commanded:
    """Where the commands sent so far have each joint at a given time: each waypoint a
    uniform move from where the previous left it, starting when it was actually sent."""

    def __init__(self, t0: float, start_deg: Sequence[float]) -> None:
        q = tuple(start_deg)
        self._segments: list[tuple[float, tuple[float, ...], float, tuple[float, ...]]] = [
            (t0, q, t0, q)
        ]

    def add(self, sent_s: float, step_s: float, target_deg: Sequence[float]) -> None:
        self._segments.append((sent_s, self.at(sent_s)[0], sent_s + step_s, tuple(target_deg)))

    @property
    def end_s(self) -> float:
        return self._segments[-1][2]

    def at(self, t_s: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Commanded joint angles (deg) and speeds (deg/s) at clock time ``t_s``."""
        # Readings come after the last send almost always: search from the end.
        for t_a, q_a, t_b, q_b in reversed(self._segments):
            if t_s >= t_a:
                if t_s >= t_b:
                    return q_b, (0.0,) * len(q_b)
                f = (t_s - t_a) / (t_b - t_a)
                return (tuple(a + (b - a) * f for a, b in zip(q_a, q_b, strict=True)),
                        tuple((b - a) / (t_b - t_a) for a, b in zip(q_a, q_b, strict=True)))
        q0 = self._segments[0][1]
        return q0, (0.0,) * len(q0)


class _Contact(Exception):
    """Internal: the watch saw a joint stop short (carries the reading)."""

    def __init__(self, joint: int, sample: LagSample, detected_s: float) -> None:
        super().__init__()
        self.joint = joint
        self.sample = sample
        self.detected_s = detected_s


class LineGuard:
    """One guarded line on ``arm``: stream, watch, and on contact stop, back off, raise."""

    def __init__(self, arm: Arm, settings: GuardSettings | None, tolerance_deg: float) -> None:
        if settings is not None and not isinstance(settings, GuardSettings):
            raise ConfigError(f"guard must be a GuardSettings, got {settings!r}")
        self.arm = arm
        self.settings = settings if settings is not None else GuardSettings()
        self.tolerance_deg = tolerance_deg
        self.names = tuple(j.name for j in arm.config.joints)
        self._streak = [0] * len(self.names)
        self._read_cost_s = 0.0
        self._t0 = 0.0

    def settled_start(self) -> Joints:
        """The joints once they stand still (``START_STILL_READINGS`` readings within a
        pulse): a joint still ringing after the last move would read as lag on the line."""
        arm, clock = self.arm, self.arm.clock
        deadline = clock.now() + START_SETTLE_MAX_S
        recent = [arm.read_joints_deg()]
        while clock.now() < deadline:
            clock.sleep(POLL_S)
            recent = [*recent[1 - START_STILL_READINGS:], arm.read_joints_deg()]
            spans = [max(q) - min(q) for q in zip(*recent, strict=True)]
            if len(recent) == START_STILL_READINGS and max(spans) <= START_STILL_DEG:
                break
        return recent[-1]

    def run(self, times: Sequence[float], joints: Sequence[Joints], start: Joints) -> GuardedMove:
        """Stream the planned line, watching it; the record, or ContactError."""
        arm = self.arm
        pulses = [arm.servo_pulses(q) for q in joints]  # all checked before the first send
        steps = [b - a for a, b in zip([0.0, *times[:-1]], times, strict=True)]
        result = GuardedMove(times[-1], self.names)
        try:
            self._stream(times, steps, pulses, joints, start, result)
        except _Contact as contact:
            arm.stop()  # first thing: the servos stop pushing on whatever is there
            self._back_off(contact, start, joints[-1])
        except BaseException:
            arm.stop()  # as every motion of the arm's: stopped and holding, then it goes on
            raise
        return result

    def _stream(
        self, times: Sequence[float], steps: Sequence[float], pulses: Sequence[dict[int, int]],
        joints: Sequence[Joints], start: Joints, result: GuardedMove,
    ) -> None:
        arm, clock = self.arm, self.arm.clock
        t0 = clock.now()
        self._t0 = t0
        commanded = _Commanded(t0, start)
        due = 0
        for k, (step, p) in enumerate(zip(steps, pulses, strict=True)):
            delay = t0 + times[k] - step - clock.now()
            if delay > 0:
                clock.sleep(delay)
            # Late (a slow bus): the servo still arrives one step after this send.
            result.late_s = max(result.late_s, clock.now() - (t0 + times[k] - step))
            commanded.add(clock.now(), step, joints[k])
            arm._send_pulses(p, step)
            due += 1
            # A joint over the threshold is confirmed (or cleared) at the next waypoint.
            every = 1 if any(self._streak) else self.settings.sample_every
            if k + 1 < len(steps) and due >= every:
                slack = t0 + times[k + 1] - steps[k + 1] - clock.now()
                # Readings fit between sends; past twice the cadence one is taken anyway
                # (the next send is late by the read, which the servos absorb).
                if slack >= self._read_cost_s or due >= 2 * every:
                    result.samples.append(self._sample(commanded, settled=False))
                    due = 0
        self._settle(commanded, result)

    def _settle(self, commanded: _Commanded, result: GuardedMove) -> None:
        """Watch until every joint is within tolerance of the line's end."""
        clock = self.arm.clock
        deadline = commanded.end_s + SETTLE_TIMEOUT_S
        while True:
            settled = clock.now() >= commanded.end_s + SETTLE_S
            sample = self._sample(commanded, settled=settled)
            result.samples.append(sample)
            if clock.now() >= commanded.end_s and max(sample.lag_deg) <= self.tolerance_deg:
                return
            if clock.now() >= deadline:
                raise MotionTimeoutError(
                    f"the guarded line did not arrive within {SETTLE_TIMEOUT_S:g} s after its "
                    f"end: lags {_fmt(sample.lag_deg)} deg"
                )
            clock.sleep(POLL_S)

    def _sample(self, commanded: _Commanded, *, settled: bool) -> LagSample:
        """Read every joint, each compared with the command at its own reading, and
        count the readings over the allowance in a row; raises _Contact."""
        arm, clock = self.arm, self.arm.clock
        began = clock.now()
        measured: list[float] = []
        lags: list[float] = []
        allowed: list[float] = []
        for k, j in enumerate(arm.config.joints):
            before = clock.now()
            p = arm.bus.read_position_pulses(j.servo_id)
            # The servo answered somewhere within the transaction: its middle.
            q, speed = commanded.at(0.5 * (before + clock.now()))
            a = arm.joint_deg_from_servo_deg(j, arm.model.deg_from_pulses(p))
            measured.append(a)
            lags.append(abs(q[k] - a))
            # Once settled a free servo is within tolerance: anything more is stopped short.
            limit = self.settings.allowed_deg(speed[k])
            allowed.append(min(limit, self.tolerance_deg) if settled else limit)
        self._read_cost_s = clock.now() - began
        sample = LagSample(began - self._t0, _joints(measured), tuple(lags), tuple(allowed))
        for k, (lag, limit) in enumerate(zip(lags, allowed, strict=True)):
            self._streak[k] = self._streak[k] + 1 if lag > limit else 0
        worst = max(range(len(lags)), key=lambda k: (self._streak[k], lags[k] / allowed[k]))
        if self._streak[worst] >= self.settings.confirm_samples:
            raise _Contact(worst, sample, clock.now())
        return sample

    def _back_off(self, contact: _Contact, start: Joints, end: Joints) -> None:
        """Straight back to the line's start; raises ContactError either way."""
        arm = self.arm
        origin, target = arm.kin.fk(start), arm.kin.fk(end)
        tool = arm.kin.fk(contact.sample.measured_deg)
        joint = self.names[contact.joint]
        lag = contact.sample.lag_deg[contact.joint]
        along = _along_mm(origin, target, tool)
        what = (f"contact: {joint} stopped {lag:.1f} deg short of its commanded path "
                f"{along:.1f} mm along the line, the tool at ({tool.x_mm:.1f}, "
                f"{tool.y_mm:.1f}, {tool.z_mm:.1f}) mm")

        def error(message: str, backed_off: bool) -> ContactError:
            return ContactError(
                message, joint=joint, lag_deg=lag, along_mm=along,
                tool_mm=(tool.x_mm, tool.y_mm, tool.z_mm), backed_off=backed_off,
                detected_s=contact.detected_s,
            )

        try:
            arm.move_line(*origin, speed_mm_s=self.settings.backoff_speed_mm_s)
        except BaseException as exc:
            arm.stop()
            if not isinstance(exc, Exception):
                raise  # Ctrl+C: stopped and holding, and it goes on up
            raise error(f"{what}; backing off failed ({exc}): the arm is stopped and holding",
                        False) from exc
        raise error(f"{what}; the arm backed off to the line's start ({origin.x_mm:.1f}, "
                    f"{origin.y_mm:.1f}, {origin.z_mm:.1f}) mm", True)


def _along_mm(origin: Pose, target: Pose, tool: Pose) -> float:
    """How far ``tool`` is along the line from ``origin`` towards ``target`` (mm)."""
    d = (target.x_mm - origin.x_mm, target.y_mm - origin.y_mm, target.z_mm - origin.z_mm)
    length = math.hypot(*d)
    if length < 1e-9:
        return 0.0
    v = (tool.x_mm - origin.x_mm, tool.y_mm - origin.y_mm, tool.z_mm - origin.z_mm)
    return sum(a * b for a, b in zip(v, d, strict=True)) / length


def _joints(values: Sequence[float]) -> Joints:
    return (values[0], values[1], values[2], values[3], values[4])


def _fmt(values: Sequence[float]) -> str:
    return ", ".join(f"{v:.1f}" for v in values)


__all__ = [
    "DEFAULT_BACKOFF_SPEED_MM_S",
    "DEFAULT_CONFIRM_SAMPLES",
    "DEFAULT_LAG_TIME_S",
    "DEFAULT_MAX_LAG_DEG",
    "DEFAULT_SAMPLE_EVERY",
    "GuardSettings",
    "GuardedMove",
    "LagSample",
    "LineGuard",
]
