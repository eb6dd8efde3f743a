"""Where the base is on the floor: wheel odometry, its heading from the IMU's gyro.

A mecanum wheel's rollers slip sideways by design, so the wheels measure the heading
poorly (a turn in place scrubs); a MEMS gyro measures it well but drifts by its bias. The
fusion here takes the translation from the wheels and the heading change from the gyro,
with the gyro's bias learnt whenever the wheels say the base stands still. Without a gyro
reading the wheels' own heading is used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from busarm.base.kinematics import MecanumKinematics, Twist, WheelSpeeds

__all__ = [
    "BIAS_GAIN",
    "MAX_BIAS_RAD_S",
    "STILL_M",
    "STILL_TICKS",
    "TWIST_SMOOTHING_S",
    "GyroTurn",
    "Odometry",
    "Pose2D",
    "wrap_rad",
]


STILL_M = 1e-5
"""Wheel travel (m) below which, over one update, the base is taken to stand still..."""
TWIST_SMOOTHING_S = 0.05
"""The velocity estimate's time constant."""
STILL_TICKS = 3
"""... or below this many encoder counts, if more (a count may dither at rest)."""
BIAS_GAIN = 0.05
"""How much of the gyro's reading while still goes into its bias at each update."""
MAX_BIAS_RAD_S = 0.02
"""A rate larger than this with the wheels still is no bias: the robot is being turned
(picked up and carried, pushed round); it is counted as a turn, not learnt."""


@dataclass(frozen=True)
class GyroTurn:
    """What the gyro measured over a stretch: the sum of its samples' rate x sample
    period (rad, bias included), over how long (s)."""

    turned_rad: float
    time_s: float


@dataclass(frozen=True)
class Pose2D:
    """A pose on the floor: metres, and yaw counter-clockwise in radians (-pi..pi)."""

    x_m: float = 0.0
    y_m: float = 0.0
    yaw_rad: float = 0.0

    @property
    def yaw_deg(self) -> float:
        return math.degrees(self.yaw_rad)

    def __repr__(self) -> str:
        return f"Pose2D(x_m={self.x_m:.4g}, y_m={self.y_m:.4g}, yaw_rad={self.yaw_rad:.4g})"

    def moved_by(self, dx_m: float, dy_m: float, dyaw_rad: float) -> Pose2D:
        """This pose after a displacement given in its own frame (heading at mid-way)."""
        mid = self.yaw_rad + dyaw_rad / 2.0
        c, s = math.cos(mid), math.sin(mid)
        return Pose2D(self.x_m + dx_m * c - dy_m * s, self.y_m + dx_m * s + dy_m * c,
                      wrap_rad(self.yaw_rad + dyaw_rad))

    def relative_to(self, origin: Pose2D) -> Pose2D:
        """This pose seen from ``origin`` (in its frame)."""
        dx, dy = self.x_m - origin.x_m, self.y_m - origin.y_m
        c, s = math.cos(origin.yaw_rad), math.sin(origin.yaw_rad)
        return Pose2D(dx * c + dy * s, -dx * s + dy * c, wrap_rad(self.yaw_rad - origin.yaw_rad))

    def interpolated(self, other: Pose2D, fraction: float) -> Pose2D:
        """The pose ``fraction`` of the way from this one to ``other`` (0: this, 1:
        ``other``): the position on the straight line, the yaw turned the short way round."""
        f = fraction
        return Pose2D(self.x_m + f * (other.x_m - self.x_m),
                      self.y_m + f * (other.y_m - self.y_m),
                      wrap_rad(self.yaw_rad + f * wrap_rad(other.yaw_rad - self.yaw_rad)))


def wrap_rad(angle_rad: float) -> float:
    """``angle_rad`` in -pi..pi."""
    return math.atan2(math.sin(angle_rad), math.cos(angle_rad))


class Odometry:
    """The base's pose from its wheels' turns (and the gyro's yaw rate, when given)."""

    def __init__(self, kinematics: MecanumKinematics, start: Pose2D | None = None) -> None:
        self.kinematics = kinematics
        self.pose = start or Pose2D()
        self.twist = Twist()
        """The latest velocity estimate, in the base's frame."""
        self.gyro_bias_rad_s = 0.0
        cfg = kinematics.config
        # Still: less than STILL_TICKS of travel (an encoder at rest can dither by a count).
        self._still_m = max(STILL_M, STILL_TICKS / cfg.encoder_ticks_per_rev
                            * cfg.wheel_circumference_m)
        self._turns: WheelSpeeds | None = None
        self._at_s: float | None = None

    def reset(self, pose: Pose2D | None = None) -> None:
        """Start again from ``pose`` (default the origin); the gyro's bias is kept."""
        self.pose = pose or Pose2D()
        self.twist = Twist()

    def update(self, wheel_turns: WheelSpeeds, t_s: float, gyro: GyroTurn | None = None,
               *, at_rest: bool | None = None) -> Pose2D:
        """Take each wheel's total turns so far (revolutions, positive forward) at time
        ``t_s``, and what the gyro measured since the last update if it reports; return
        the new pose. ``at_rest``: whether the base is known to stand (nothing
        commanded); None: judged from the wheels alone. The gyro's bias is learnt only
        while at rest and still."""
        last, last_t = self._turns, self._at_s
        self._turns, self._at_s = wheel_turns, t_s
        if last is None or last_t is None or t_s <= last_t:
            return self.pose
        dt = t_s - last_t
        circumference = self.kinematics.config.wheel_circumference_m
        travel = tuple((now - before) * circumference
                       for now, before in zip(wheel_turns, last, strict=True))
        moved = self.kinematics.twist((travel[0], travel[1], travel[2], travel[3]))
        dyaw = moved.wz_rad_s  # the wheels' own heading change (a displacement here)
        if gyro is not None and gyro.time_s > 0:
            if at_rest is not False and max(abs(d) for d in travel) < self._still_m:
                rate = gyro.turned_rad / gyro.time_s
                if abs(rate) <= MAX_BIAS_RAD_S:
                    self.gyro_bias_rad_s += BIAS_GAIN * (rate - self.gyro_bias_rad_s)
            dyaw = gyro.turned_rad - self.gyro_bias_rad_s * gyro.time_s
        self.pose = self.pose.moved_by(moved.vx_m_s, moved.vy_m_s, dyaw)
        # Smoothed over about TWIST_SMOOTHING_S: one update's travel is a few encoder
        # counts, and a count more or less is a speed of several mm/s.
        k = dt / (TWIST_SMOOTHING_S + dt)
        old = self.twist
        self.twist = Twist(old.vx_m_s + k * (moved.vx_m_s / dt - old.vx_m_s),
                           old.vy_m_s + k * (moved.vy_m_s / dt - old.vy_m_s),
                           old.wz_rad_s + k * (dyaw / dt - old.wz_rad_s))
        return self.pose
