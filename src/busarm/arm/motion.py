"""Time scaling and straight-line paths. Pure: numbers in, numbers out.

A profile maps normalised time ``tau`` in [0, 1] to path progress ``s`` in [0, 1]:

- ``min_jerk``: s = 10 tau^3 - 15 tau^4 + 6 tau^5 (zero speed and acceleration at both
  ends; peak speed 1.875x the average);
- ``trapezoidal``: constant acceleration for the first quarter, cruise, constant
  deceleration for the last quarter (peak speed 4/3 of the average);
- ``linear``: uniform speed (what the servos do on their own within one move);
- ``time_optimal``: the shortest move within a speed, an acceleration and a jerk limit
  (Ruckig's jerk-limited profile): it cruises at the speed limit as far as the line
  allows, where ``min_jerk`` reaches it only for an instant.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from ruckig import InputParameter, Result, Ruckig, Trajectory

from busarm.errors import ConfigError
from busarm.units import check_range

TRAPEZOID_RAMP = 0.25
"""Fraction of a trapezoidal move spent accelerating (and again decelerating)."""
TIME_OPTIMAL = "time_optimal"
LINE_ACCEL_MM_S2 = 3000.0
"""A ``time_optimal`` line's tool acceleration at most (0.3 g: a block held by friction
between the pads does not slip, and the servos' 35 kg torque has margin at full reach)."""
LINE_JERK_MM_S3 = 100_000.0
"""... and its jerk: the acceleration builds up in 30 ms, no kick to set the arm ringing."""
TURN_ACCEL_DEG_S2 = 900.0
"""A ``time_optimal`` line's pitch and roll accelerate at most this fast ..."""
TURN_JERK_DEG_S3 = 9000.0
"""... with at most this jerk (the acceleration built up in 0.1 s)."""


def _min_jerk(tau: float) -> float:
    return tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau))


def _trapezoidal(tau: float) -> float:
    f = TRAPEZOID_RAMP
    peak = 1.0 / (1.0 - f)  # the speed that covers the path in unit time
    if tau < f:
        return 0.5 * peak / f * tau * tau
    if tau > 1.0 - f:
        u = 1.0 - tau
        return 1.0 - 0.5 * peak / f * u * u
    return peak * (tau - 0.5 * f)


def _linear(tau: float) -> float:
    return tau


PROFILES: dict[str, tuple[Callable[[float], float], float]] = {
    "min_jerk": (_min_jerk, 1.875),
    "trapezoidal": (_trapezoidal, 1.0 / (1.0 - TRAPEZOID_RAMP)),
    "linear": (_linear, 1.0),
}
"""name -> (s(tau), peak speed as a multiple of the average speed)."""


PROFILE_NAMES = (*PROFILES, TIME_OPTIMAL)
"""Every profile a straight line may use."""


def check_profile(name: str) -> tuple[Callable[[float], float], float]:
    """A fixed-shape profile's function and its peak-speed factor (``time_optimal``'s
    shape depends on the line: ``line_profile``); ConfigError naming the choices."""
    try:
        return PROFILES[name]
    except (KeyError, TypeError):
        raise ConfigError(
            f"profile {name!r} has no fixed shape; choose one of {', '.join(PROFILES)}"
            if name == TIME_OPTIMAL else
            f"profile {name!r} is unknown; choose one of {', '.join(PROFILE_NAMES)}"
        ) from None


def check_profile_name(name: str) -> None:
    """ConfigError unless ``name`` is one of ``PROFILE_NAMES``."""
    if name != TIME_OPTIMAL:
        check_profile(name)


def line_profile(name: str, length_mm: float, turn_deg: float, speed_mm_s: float,
                 turn_speed_deg_s: float) -> tuple[Callable[[float], float], float]:
    """A line's s(tau) and its shortest duration (s): the tool point no faster than
    ``speed_mm_s``, pitch and roll no faster than ``turn_speed_deg_s``."""
    check_profile_name(name)
    if name != TIME_OPTIMAL:
        fn, _ = check_profile(name)
        return fn, max(duration_for_speed(name, length_mm, speed_mm_s),
                       duration_for_speed(name, turn_deg, turn_speed_deg_s))
    # One path parameter s in [0, 1] for position and angles: its limits the tighter of
    # the two (a line that only turns the wrist is limited by the turn alone).
    limits = []
    if length_mm > 1e-9:
        limits.append(np.array([speed_mm_s, LINE_ACCEL_MM_S2, LINE_JERK_MM_S3]) / length_mm)
    if turn_deg > 1e-9:
        limits.append(np.array([turn_speed_deg_s, TURN_ACCEL_DEG_S2, TURN_JERK_DEG_S3])
                      / turn_deg)
    if not limits:
        return _linear, 0.0
    v, a, j = np.min(limits, axis=0).tolist()
    return _jerk_limited(v, a, j)


def _jerk_limited(v: float, a: float, j: float) -> tuple[Callable[[float], float], float]:
    """Ruckig's time-optimal move of s from 0 to 1 within speed ``v``, acceleration ``a``
    and jerk ``j`` (per s): s(tau) and its duration."""
    given = InputParameter(1)
    given.current_position, given.target_position = [0.0], [1.0]
    given.max_velocity, given.max_acceleration, given.max_jerk = [v], [a], [j]
    trajectory = Trajectory(1)
    if Ruckig(1).calculate(given, trajectory) not in (Result.Working, Result.Finished):
        raise ConfigError(f"no time-optimal profile within {v:g}/s, {a:g}/s2, {j:g}/s3")
    duration = float(trajectory.duration)

    def s_of(tau: float) -> float:
        if tau >= 1.0:
            return 1.0
        return min(1.0, max(0.0, float(trajectory.at_time(tau * duration)[0][0])))

    return s_of, duration


def check_line_request(
    pose: Sequence[float | None], *, speed_mm_s: float, duration_s: float | None,
    profile: str, rate_hz: float, max_rate_hz: float,
) -> None:
    """ConfigError for a straight-line request that cannot be planned, before any bus
    traffic: ``pose`` is (x, y, z mm, pitch, roll deg), pitch and roll may be None."""
    for name, v in zip(("x_mm", "y_mm", "z_mm", "pitch_deg", "roll_deg"), pose, strict=True):
        if v is not None:
            check_range(name, v, -1e4, 1e4)
    check_profile_name(profile)
    check_range("speed_mm_s", speed_mm_s, 0.1, 1000.0, "mm/s")
    check_range("rate_hz", rate_hz, 1.0, max_rate_hz, "Hz")
    if duration_s is not None:
        check_range("duration_s", duration_s, 1.0 / rate_hz, 600.0, "s")


def progress(profile: str, tau: float) -> float:
    """Path progress s(tau) of a profile, tau clamped to [0, 1]."""
    fn, _ = check_profile(profile)
    return fn(min(max(tau, 0.0), 1.0))


def duration_for_speed(profile: str, distance: float, peak_speed: float) -> float:
    """The shortest duration in which ``distance`` is covered with the profile's peak
    speed at most ``peak_speed`` (same units per second)."""
    _, factor = check_profile(profile)
    if not (math.isfinite(peak_speed) and peak_speed > 0):
        raise ConfigError(f"speed {peak_speed!r} must be > 0")
    return abs(distance) * factor / peak_speed


def sample_times(duration_s: float, rate_hz: float) -> list[float]:
    """Waypoint times after the start: every 1/rate_hz, the last one exactly at the end."""
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"duration_s = {duration_s!r} must be > 0")
    n = max(1, math.ceil(duration_s * rate_hz - 1e-9))
    return [duration_s * k / n for k in range(1, n + 1)]


@dataclass(frozen=True)
class LinePath:
    """A straight line of the tool point with pitch (the short way) and roll interpolated."""

    start: tuple[float, float, float, float, float]
    end: tuple[float, float, float, float, float]

    @property
    def length_mm(self) -> float:
        return math.dist(self.start[:3], self.end[:3])

    @property
    def turn_deg(self) -> float:
        """The larger of the pitch and roll changes."""
        return max(abs(_short(self.end[3] - self.start[3])), abs(self.end[4] - self.start[4]))

    def at(self, s: float) -> tuple[float, float, float, float, float]:
        """The pose at progress ``s`` in [0, 1]."""
        a, b = self.start, self.end
        x, y, z = (a[i] + (b[i] - a[i]) * s for i in range(3))
        pitch = a[3] + _short(b[3] - a[3]) * s
        # Roll is the wrist joint itself (within +-120 deg): never the short way via 180.
        roll = a[4] + (b[4] - a[4]) * s
        return (x, y, z, pitch, roll)

    def distance_mm(self, points_mm: Sequence[Sequence[float]]) -> npt.NDArray[np.float64]:
        """Distance of each point from the line segment, in mm."""
        p = np.asarray(points_mm, dtype=float)[:, :3]
        a = np.asarray(self.start[:3])
        d = np.asarray(self.end[:3]) - a
        length2 = float(d @ d)
        if length2 == 0.0:
            return np.linalg.norm(p - a, axis=1)  # type: ignore[no-any-return]
        t = np.clip((p - a) @ d / length2, 0.0, 1.0)
        return np.linalg.norm(p - (a + t[:, None] * d), axis=1)  # type: ignore[no-any-return]


def _short(delta_deg: float) -> float:
    """The shortest signed turn for an angle difference."""
    return (delta_deg + 180.0) % 360.0 - 180.0


__all__ = [
    "LINE_ACCEL_MM_S2",
    "LINE_JERK_MM_S3",
    "PROFILES",
    "PROFILE_NAMES",
    "TIME_OPTIMAL",
    "TRAPEZOID_RAMP",
    "TURN_ACCEL_DEG_S2",
    "TURN_JERK_DEG_S3",
    "LinePath",
    "check_line_request",
    "check_profile",
    "check_profile_name",
    "duration_for_speed",
    "line_profile",
    "progress",
    "sample_times",
]
