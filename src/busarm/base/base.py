"""The mobile base through the controller board: drive, move by, stop, odometry, watchdog.

``Base(link, config)`` commands the four wheel motors of a ``BoardLink`` in the user's
units. ``drive`` is a velocity command to repeat (as ROS's cmd_vel is): each call scales
the asked twist down to the body's and the wheels' limits and steps the commanded twist
toward it by no more than the acceleration limits allow for the time since the last
call, so no motor command beyond a limit ever reaches the board. If ``drive`` is not
called again within ``config.command_timeout_s`` the watchdog stops the wheels: on the
wall clock a background thread; on a simulated clock (``SimClock``) a callback run after
each step of simulated time, since simulated time passes only when someone waits on it.

Odometry: with busarm's ``MotorEncoders`` report (the simulated board sends it) from the
encoder counts; the vendor's stock firmware sends none, and then from the commanded wheel
speeds, integrated, as the vendor's own odometry does (``odometry_source`` says which).
The heading comes from the IMU's gyro when the board reports it (``Odometry``).
"""

from __future__ import annotations

import bisect
import math
import threading
from collections import deque
from contextlib import suppress
from dataclasses import dataclass
from types import TracebackType

from busarm.base.config import ChassisConfig
from busarm.base.kinematics import MecanumKinematics, Twist, WheelSpeeds
from busarm.base.odometry import GyroTurn, Odometry, Pose2D, wrap_rad
from busarm.bus.board import BoardLink
from busarm.clock import SimClock
from busarm.errors import BusArmError, ConfigError
from busarm.protocol.board import (
    MOTOR_COUNT,
    BoardReport,
    ImuSample,
    MotorEncoders,
    MotorSpeeds,
)
from busarm.units import check_range, range_text

__all__ = [
    "BREAK_S",
    "COMMANDS_STOP_S",
    "CONTROL_PERIOD_S",
    "DETECT_S",
    "DETECT_SAMPLES",
    "DONE_M",
    "DONE_RAD",
    "GAIN_PER_S",
    "HISTORY_SAMPLES",
    "IMU_FRESH_S",
    "MAX_PENDING_REPORTS",
    "MAX_STEP_S",
    "MEASURE_S",
    "MOVE_MAX_M",
    "MOVE_MAX_RAD",
    "ODOMETRY_PERIOD_S",
    "PROFILE_MARGIN",
    "REPORT_PERIOD_S",
    "SETTLE_S",
    "Base",
    "BaseOdometry",
    "ReportStream",
]


CONTROL_PERIOD_S = 0.02
"""How often ``move_by`` reads the odometry and commands the wheels."""
MAX_STEP_S = 0.1
"""The longest time one ``drive`` call's acceleration step may count (a first command
after a pause ramps from standing, not in one jump)."""
DETECT_S = 0.3
"""How long a new Base listens for encoder reports before it integrates commands."""
DETECT_SAMPLES = 3
"""IMU reports heard without an encoder report before the firmware is taken to send none."""
IMU_FRESH_S = 0.1
"""An IMU sample older than this is not used for the heading."""
REPORT_PERIOD_S = 0.01
"""The board's IMU and encoder report period until its own is measured (100 Hz)."""
MEASURE_S = 0.1
"""A report stream's period is measured over at least this long."""
BREAK_S = 0.2
"""A longer silence breaks a report stream (its period is measured anew after it)."""
GAIN_PER_S = 3.0
"""``move_by``'s feedback on the odometry's error (m/s per m, rad/s per rad)."""
PROFILE_MARGIN = 0.8
"""``move_by`` plans its profile within this share of each limit (room for feedback)."""
DONE_M = 0.003
DONE_RAD = math.radians(0.5)
SETTLE_S = 2.0
"""How long ``move_by`` keeps correcting after its profile ends before it gives up."""
COMMANDS_STOP_S = 0.3
"""Without encoders, how long ``wait_stopped`` allows the firmware's speed loop to stop
the wheels (the simulated one takes about 0.25 s from full speed to 1%)."""
ODOMETRY_PERIOD_S = 0.02
"""How often the base reads the board's reports when nothing else does."""
MAX_PENDING_REPORTS = 20_000
HISTORY_SAMPLES = 300
"""``pose_at`` looks back this many odometry updates (3 s of encoder reports)."""
MOVE_MAX_M = 100.0
MOVE_MAX_RAD = 20 * math.pi
_INT32 = 2**32


class ReportStream:
    """A stream of periodic reports (the board's IMU, its encoders): how long each one
    stands for. That is the board's sample period, measured as the mean spacing of the
    reports since the stream last broke off, not the time since the last one arrived:
    reports read together arrive together. A break (longer than ``BREAK_S``: reports
    lost, or none read) stands for itself, up to ``stale_s``."""

    def __init__(self, period_s: float, stale_s: float = IMU_FRESH_S) -> None:
        self.period_s = period_s
        self.stale_s = stale_s
        self._first_s = self._last_s = -math.inf
        self._count = 0

    def span_s(self, at_s: float) -> float:
        gap = at_s - self._last_s
        self._last_s = at_s
        if gap > BREAK_S:
            self._first_s, self._count = at_s, 0
            return min(gap, self.stale_s) if math.isfinite(gap) else self.period_s
        self._count += 1
        if at_s - self._first_s >= MEASURE_S:
            self.period_s = (at_s - self._first_s) / self._count
        return self.period_s


@dataclass(frozen=True)
class BaseOdometry:
    """Where the base is (from where it started) and how fast it goes, in its own frame."""

    pose: Pose2D
    twist: Twist
    at_s: float
    source: str
    """``encoders`` or ``commands`` (what the wheels' travel is taken from)."""


class Base:
    """The mecanum base on ``link``'s wheel motors. Thread-safe; a context manager that
    leaves the wheels stopped (it does not close the link, which it does not own)."""

    def __init__(self, link: BoardLink, config: ChassisConfig) -> None:
        self.link = link
        self.config = config
        self.clock = link.clock
        self.kinematics = MecanumKinematics(config)
        self.watchdog_stops = 0
        """How many times the watchdog stopped the wheels."""
        self._odometry = Odometry(self.kinematics)
        self._history: deque[tuple[float, Pose2D]] = deque(maxlen=HISTORY_SAMPLES)
        self._lock = threading.RLock()
        self._command = Twist()
        self._command_at_s = self.clock.now()
        self._deadline_s = math.inf
        self._turns = [0.0] * 4
        self._last_ticks: tuple[int, ...] | None = None
        self._integrated_to_s = self.clock.now()
        self._closed = threading.Event()
        self._reports: deque[tuple[BoardReport, float]] = deque(maxlen=MAX_PENDING_REPORTS)
        self._gyro_at_s = -math.inf
        self._gyro_turned_rad = self._gyro_time_s = 0.0
        self._imu_stream = ReportStream(REPORT_PERIOD_S)
        self._encoder_stream = ReportStream(REPORT_PERIOD_S, stale_s=math.inf)
        self._encoder_time_s = 0.0
        self._polled_at_s = self.clock.now()
        link.add_listener(self._on_report)
        self.odometry_source = self._detect_source()
        self._update()
        self._thread: threading.Thread | None = None
        if isinstance(self.clock, SimClock):
            self.clock.attach(self._on_sim_step)
        else:
            self._thread = threading.Thread(target=self._watch, name="base-watchdog",
                                            daemon=True)
            self._thread.start()

    def __repr__(self) -> str:
        return (f"Base({self.config.name!r} on {self.link.transport.name}, odometry from "
                f"{self.odometry_source})")

    # ------------------------------------------------------------------ commands

    def drive(self, vx_m_s: float, vy_m_s: float, wz_rad_s: float) -> Twist:
        """Go at this twist (m/s forward, m/s left, rad/s counter-clockwise), scaled down
        to the limits and reached at no more than the acceleration limits; call it again
        within ``command_timeout_s`` or the wheels stop. Returns the twist commanded."""
        cfg = self.config
        for name, value, lim, unit in (("vx", vx_m_s, cfg.max_speed_m_s, "m/s"),
                                       ("vy", vy_m_s, cfg.max_speed_m_s, "m/s"),
                                       ("wz", wz_rad_s, cfg.max_yaw_rate_rad_s, "rad/s")):
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value):
                raise ConfigError(f"drive: {name} = {value!r} {unit} is not a finite number; "
                                  f"allowed: {range_text(-lim, lim, unit)} (faster is "
                                  "scaled down)")
        target = self.kinematics.limit_twist(Twist(vx_m_s, vy_m_s, wz_rad_s))
        self._check_open()
        with self._lock:
            now = self.clock.now()
            step_s = min(max(now - self._command_at_s, 0.0), MAX_STEP_S)
            command = self._toward(target, step_s)
            self._send(command, now)
            self._deadline_s = now + cfg.command_timeout_s
        return command

    def stop(self) -> None:
        """Every wheel to 0 at once (no ramp)."""
        with self._lock:
            self._send(Twist(), self.clock.now())
            self._deadline_s = math.inf

    def move_by(self, dx_m: float, dy_m: float, dyaw_rad: float) -> Pose2D:
        """Move by (dx forward, dy left) metres and turn by ``dyaw_rad`` counter-clockwise,
        all in the frame the base has now, on a smooth (minimum-jerk) profile within the
        limits, closed on the odometry; returns where the odometry says it ended
        (relative to the start), stopped. Waits on the robot's clock."""
        check_range("dx", dx_m, -MOVE_MAX_M, MOVE_MAX_M, "m")
        check_range("dy", dy_m, -MOVE_MAX_M, MOVE_MAX_M, "m")
        check_range("dyaw", dyaw_rad, -MOVE_MAX_RAD, MOVE_MAX_RAD, "rad")
        self._check_open()
        dyaw = dyaw_rad
        duration_s = self._profile_s(math.hypot(dx_m, dy_m), abs(dyaw))
        start = self._update().pose
        t0 = self.clock.now()
        try:
            while True:
                t = self.clock.now() - t0
                tau = min(t / duration_s, 1.0)
                s = tau**3 * (10 - 15 * tau + 6 * tau**2)
                rate = 30 * tau**2 * (1 - tau) ** 2 / duration_s
                here = self._update().pose.relative_to(start)
                ex, ey = dx_m * s - here.x_m, dy_m * s - here.y_m
                eyaw = wrap_rad(dyaw * s - here.yaw_rad)
                if tau >= 1.0 and math.hypot(ex, ey) < DONE_M and abs(eyaw) < DONE_RAD:
                    break
                if t > duration_s + SETTLE_S:
                    break  # blocked or slipping: stop where it is (the result says where)
                wx = dx_m * rate + GAIN_PER_S * ex  # in the start frame
                wy = dy_m * rate + GAIN_PER_S * ey
                c, sn = math.cos(here.yaw_rad), math.sin(here.yaw_rad)
                self.drive(c * wx + sn * wy, -sn * wx + c * wy, dyaw * rate + GAIN_PER_S * eyaw)
                self.clock.sleep(CONTROL_PERIOD_S)
        finally:
            self.stop()
        self.wait_stopped()
        return self._update().pose.relative_to(start)

    def odometry(self) -> BaseOdometry:
        """The pose since this Base started (or the last ``reset_odometry``) and the
        velocity, from what the board has reported by now."""
        with self._lock:
            odom = self._update()
            return BaseOdometry(odom.pose, odom.twist, self.clock.now(), self.odometry_source)

    def pose_at(self, at_s: float) -> Pose2D:
        """The odometry's pose at ``at_s`` (this clock's time, within the last
        HISTORY_SAMPLES reports; interpolated between them): where the base was when a
        sensor measured something."""
        with self._lock:
            self._update()
            history = list(self._history)
        if not history or at_s >= history[-1][0]:
            return self._odometry.pose
        if at_s <= history[0][0]:
            return history[0][1]
        times = [t for t, _ in history]
        k = bisect.bisect_right(times, at_s)
        (t0, a), (t1, b) = history[k - 1], history[k]
        f = (at_s - t0) / (t1 - t0) if t1 > t0 else 1.0
        return a.interpolated(b, f)

    def reset_odometry(self, pose: Pose2D | None = None) -> None:
        """Count the pose from ``pose`` (default the origin) from now on."""
        with self._lock:
            self._update()
            self._odometry.reset(pose)
            self._history.clear()

    @property
    def command(self) -> Twist:
        """The twist last sent to the wheels."""
        return self._command

    def close(self) -> None:
        """Stop the wheels and the watchdog (the link stays open)."""
        if self._closed.is_set():
            return
        try:
            with suppress(BusArmError):
                self.stop()
        finally:
            self._closed.set()
            if isinstance(self.clock, SimClock):
                self.clock.detach(self._on_sim_step)
            if self._thread is not None:
                self._thread.join(timeout=1.0)

    def __enter__(self) -> Base:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ inside

    def _check_open(self) -> None:
        if self._closed.is_set():
            raise ConfigError("this Base is closed; open a new one to drive the wheels")

    def _toward(self, target: Twist, step_s: float) -> Twist:
        """The command ``step_s`` of the acceleration limits nearer ``target`` (the change
        scaled as a whole, so a ramp keeps its direction)."""
        now = self._command
        dvx, dvy = target.vx_m_s - now.vx_m_s, target.vy_m_s - now.vy_m_s
        dwz = target.wz_rad_s - now.wz_rad_s
        if dvx == dvy == dwz == 0.0:
            return target
        if step_s <= 0.0:
            return now
        cfg = self.config
        worst = max(abs(dvx) / (cfg.max_accel_m_s2 * step_s),
                    abs(dvy) / (cfg.max_accel_m_s2 * step_s),
                    abs(dwz) / (cfg.max_yaw_accel_rad_s2 * step_s))
        if worst <= 1.0:
            return target
        return Twist(now.vx_m_s + dvx / worst, now.vy_m_s + dvy / worst,
                     now.wz_rad_s + dwz / worst)

    def _send(self, command: Twist, now: float) -> None:
        """Integrate the old command up to now, then send the new one (within the link's
        own wheel limit too: a float's rounding never makes the board refuse a stop)."""
        self._update()
        speeds = self.kinematics.motor_speeds(command)
        limit = min(self.config.max_wheel_rev_s, self.link.wheel_limit_rev_s)
        worst = max(abs(v) for v in speeds.values()) / limit
        if worst > 1.0:
            command = command.scaled(1.0 / worst)
            speeds = {m: max(-limit, min(limit, v / worst)) for m, v in speeds.items()}
        self.link.set_motor_speeds(speeds)
        self._command, self._command_at_s = command, now

    def _profile_s(self, distance_m: float, turn_rad: float) -> float:
        """The minimum-jerk profile's duration: its peak speed (1.875/T of the way per
        second) and acceleration (5.774/T^2) within PROFILE_MARGIN of every limit."""
        cfg = self.config
        rate = [cfg.max_speed_m_s / max(distance_m, 1e-9),
                cfg.max_wheel_m_s / max(math.sqrt(2) * distance_m
                                        + self.kinematics.k_m * turn_rad, 1e-9),
                cfg.max_yaw_rate_rad_s / max(turn_rad, 1e-9)]
        accel = [cfg.max_accel_m_s2 / max(distance_m, 1e-9),
                 cfg.max_yaw_accel_rad_s2 / max(turn_rad, 1e-9)]
        return max(1.875 / (PROFILE_MARGIN * min(rate)),
                   math.sqrt(5.7735 / (PROFILE_MARGIN * min(accel))), 0.2)

    def wait_stopped(self) -> None:
        """Wait (a second at most) for the wheels to come to rest after the stop."""
        end = self.clock.now() + 1.0
        while self.clock.now() < end:
            self.clock.sleep(CONTROL_PERIOD_S)
            if self.odometry_source == "commands":
                # Nothing measures the wheels: allow their speed loop its time to stop.
                self.clock.sleep(COMMANDS_STOP_S)
                return
            twist = self._update().twist
            if abs(twist.vx_m_s) + abs(twist.vy_m_s) < 1e-3 and abs(twist.wz_rad_s) < 0.01:
                return

    def _detect_source(self) -> str:
        """``encoders`` once one encoder report came, ``commands`` when IMU reports come
        without them (the stock firmware) or nothing comes in DETECT_S."""
        link = self.link
        end = self.clock.now() + DETECT_S
        imu_before = link.readings.imu_at_s
        samples = 0
        while self.clock.now() < end:
            for report in link.poll(min(0.02, max(end - self.clock.now(), 0.0))):
                if isinstance(report, ImuSample):
                    samples += 1
            if link.readings.encoders is not None and samples >= DETECT_SAMPLES:
                return "encoders"
            if samples >= DETECT_SAMPLES and link.readings.imu_at_s > imu_before:
                return "commands"  # encoders come at the IMU's rate when they come at all
        return "encoders" if link.readings.encoders is not None else "commands"

    def _update(self, *, poll: bool = True) -> Odometry:
        """Fold in every report the board has sent since the last update, in order (and
        with the stock firmware, the commanded speeds up to now)."""
        with self._lock:
            if poll:
                self.link.poll()
            self._fold_reports()
            if self.odometry_source == "commands":
                self._fold_commands(self.clock.now())
            return self._odometry

    def _fold_reports(self) -> None:
        while self._reports:
            report, at_s = self._reports.popleft()
            if isinstance(report, ImuSample):
                self._take_gyro(report.gyro_rad_s[2], at_s)
                if self.odometry_source == "commands":
                    self._fold_commands(at_s)
            elif isinstance(report, MotorEncoders) and self.odometry_source == "encoders":
                # Every one, in order: counts are totals, and each stands for a period.
                self._count_ticks(report.ticks)
                self._encoder_time_s += self._encoder_stream.span_s(at_s)
                self._fold(at_s, self._encoder_time_s)

    def _fold_commands(self, at_s: float) -> None:
        """The wheels' travel from their commanded speeds up to ``at_s``."""
        wheels = self.kinematics.wheels_from_motors(
            {m: self.link.wheel_targets_rev_s.get(m, 0.0) for m in range(1, MOTOR_COUNT + 1)})
        dt = max(at_s - self._integrated_to_s, 0.0)
        self._turns = [t + w * dt for t, w in zip(self._turns, wheels, strict=True)]
        self._fold(at_s, at_s)

    def _take_gyro(self, rate_rad_s: float, at_s: float) -> None:
        """One gyro sample: its rate counts for the time it stands for (up to where the
        gyro goes stale)."""
        span = min(self._imu_stream.span_s(at_s), IMU_FRESH_S)
        self._gyro_turned_rad += rate_rad_s * span
        self._gyro_time_s += span
        self._gyro_at_s = at_s

    def _fold(self, at_s: float, travel_at_s: float) -> None:
        """Fold the wheels' turns as of ``at_s`` into the odometry (``travel_at_s``: the
        time the travel is reckoned on: the encoders' own sample times)."""
        self._integrated_to_s = max(self._integrated_to_s, at_s)
        gyro = (GyroTurn(self._gyro_turned_rad, self._gyro_time_s)
                if at_s - self._gyro_at_s < IMU_FRESH_S else None)
        self._gyro_turned_rad = self._gyro_time_s = 0.0
        # At rest: nothing commanded for long enough that the speed loops have stopped.
        at_rest = self._command.is_zero and at_s - self._command_at_s > COMMANDS_STOP_S
        turns: WheelSpeeds = (self._turns[0], self._turns[1], self._turns[2], self._turns[3])
        self._odometry.update(turns, travel_at_s, gyro, at_rest=at_rest)
        self._history.append((at_s, self._odometry.pose))

    def _on_report(self, report: BoardReport, at_s: float) -> None:
        """The link's listener: takes note only (it runs with the link in use)."""
        if isinstance(report, ImuSample | MotorEncoders):
            self._reports.append((report, at_s))

    def _count_ticks(self, ticks: tuple[int, int, int, int]) -> None:
        last, self._last_ticks = self._last_ticks, ticks
        if last is None:
            return
        per_rev = self.config.encoder_ticks_per_rev
        for i, motor in enumerate(self.config.motors):
            delta = (ticks[motor.motor - 1] - last[motor.motor - 1] + _INT32 // 2) % _INT32 \
                - _INT32 // 2  # the counter wraps at 32 bits
            self._turns[i] += motor.sign * delta / per_rev

    # ------------------------------------------------------------------ watchdog

    def _expired(self) -> bool:
        return self.clock.now() > self._deadline_s

    def _watch(self) -> None:
        """The wall clock's watchdog thread; it also keeps the odometry up to date (every
        report folded in while it is fresh, whoever else reads the link or not)."""
        period_s = min(self.config.command_timeout_s / 5.0, ODOMETRY_PERIOD_S)
        while not self._closed.wait(period_s):
            with self._lock:
                with suppress(BusArmError):
                    self._update()
                if self._expired():
                    with suppress(BusArmError):
                        self._watchdog_stop()

    def _on_sim_step(self) -> None:
        """The simulated clock's watchdog: after each step of simulated time. It runs in
        whichever thread waits on the clock, holding the clock: it takes no lock another
        thread may hold while it waits on the clock (it tries the Base's, and writes the
        stop frame on the transport itself, not through the link's lock)."""
        now = self.clock.now()
        due = now - self._polled_at_s >= ODOMETRY_PERIOD_S
        if not (due or self._expired()) or not self._lock.acquire(blocking=False):
            return
        try:
            if due:  # read the reports as they come, as the wall clock's thread does
                self._polled_at_s = now
                with suppress(BusArmError):
                    self.link.poll_if_idle()
                self._fold_reports()
            if self._expired():
                self._integrate_commands_to_now()
                stop = MotorSpeeds(tuple((m, 0.0) for m in range(1, MOTOR_COUNT + 1)))
                with suppress(BusArmError):
                    self.link.transport.write(stop.encode())
                self.link.wheel_targets_rev_s = dict.fromkeys(range(1, MOTOR_COUNT + 1), 0.0)
                self._stopped_by_watchdog()
        finally:
            self._lock.release()

    def _integrate_commands_to_now(self) -> None:
        if self.odometry_source == "commands":
            self._update(poll=False)  # (polling would take the link's lock)

    def _watchdog_stop(self) -> None:
        self._send(Twist(), self.clock.now())
        self._stopped_by_watchdog()

    def _stopped_by_watchdog(self) -> None:
        self._command, self._command_at_s = Twist(), self.clock.now()
        self._deadline_s = math.inf
        self.watchdog_stops += 1
