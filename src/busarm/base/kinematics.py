"""Mecanum kinematics: the body's twist (vx, vy, wz) and the four wheels' speeds, both ways.

With rollers at 45 degrees in the usual X pattern (seen from above), a wheel's rim speed
is ``vx -+ vy -+ k wz`` with ``k`` half the track plus half the wheelbase:

    front_left  = vx - vy - k wz        front_right = vx + vy + k wz
    rear_left   = vx + vy - k wz        rear_right  = vx - vy + k wz

(the vendor firmware's equations, field notes section 5). The inverse is exact: four
wheel speeds that come from a twist give that twist back; speeds that do not (a wheel
slipping) give the least-squares twist. ``limit_twist`` scales a twist down, keeping its
direction, until no body limit and no wheel limit is exceeded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from busarm.base.config import ChassisConfig
from busarm.errors import ConfigError
from busarm.units import range_text

__all__ = [
    "MecanumKinematics",
    "Twist",
    "WheelSpeeds",
]


WheelSpeeds = tuple[float, float, float, float]
"""Per wheel, in busarm.base.config.WHEELS order (front_left, rear_left, front_right,
rear_right)."""


@dataclass(frozen=True)
class Twist:
    """The base's velocity in its own frame: m/s forward and left, rad/s counter-clockwise."""

    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    wz_rad_s: float = 0.0

    def scaled(self, factor: float) -> Twist:
        return Twist(self.vx_m_s * factor, self.vy_m_s * factor, self.wz_rad_s * factor)

    @property
    def is_zero(self) -> bool:
        return self.vx_m_s == 0.0 and self.vy_m_s == 0.0 and self.wz_rad_s == 0.0


class MecanumKinematics:
    """Twist <-> wheel rim speeds (m/s) and wheel turn rates (rev/s) for one chassis."""

    def __init__(self, config: ChassisConfig) -> None:
        self.config = config
        self.k_m = config.half_spread_m

    def wheel_speeds_m_s(self, twist: Twist) -> WheelSpeeds:
        """Each wheel's rim speed for ``twist`` (positive rolls the base forward)."""
        vx, vy, turn = twist.vx_m_s, twist.vy_m_s, self.k_m * twist.wz_rad_s
        return (vx - vy - turn, vx + vy - turn, vx + vy + turn, vx - vy + turn)

    def twist(self, wheels_m_s: WheelSpeeds) -> Twist:
        """The body's twist from the wheels' rim speeds (least squares if they disagree)."""
        fl, rl, fr, rr = wheels_m_s
        return Twist((fl + rl + fr + rr) / 4.0, (-fl + rl + fr - rr) / 4.0,
                     (-fl - rl + fr + rr) / (4.0 * self.k_m))

    def wheel_rev_s(self, twist: Twist) -> WheelSpeeds:
        """Each wheel's turn rate (rev/s, positive forward) for ``twist``."""
        c = self.config.wheel_circumference_m
        fl, rl, fr, rr = self.wheel_speeds_m_s(twist)
        return (fl / c, rl / c, fr / c, rr / c)

    def twist_from_rev_s(self, wheels_rev_s: WheelSpeeds) -> Twist:
        c = self.config.wheel_circumference_m
        fl, rl, fr, rr = wheels_rev_s
        return self.twist((fl * c, rl * c, fr * c, rr * c))

    def motor_speeds(self, twist: Twist) -> dict[int, float]:
        """The board's motor commands (motor number -> rev/s, signed as mounted)."""
        return {m.motor: m.sign * rev_s for m, rev_s in
                zip(self.config.motors, self.wheel_rev_s(twist), strict=True)}

    def wheels_from_motors(self, motor_rev_s: dict[int, float]) -> WheelSpeeds:
        """Wheel turn rates (positive forward) from the motors' own (signed as mounted)."""
        fl, rl, fr, rr = (m.sign * motor_rev_s[m.motor] for m in self.config.motors)
        return (fl, rl, fr, rr)

    def limit_twist(self, twist: Twist) -> Twist:
        """``twist`` scaled down (direction kept) to the body's and the wheels' limits;
        ConfigError for a value that is not a number."""
        for name, value in (("vx", twist.vx_m_s), ("vy", twist.vy_m_s),
                            ("wz", twist.wz_rad_s)):
            if not math.isfinite(value):
                raise ConfigError(f"{name} = {value!r}; it must be a finite number")
        cfg = self.config
        ratios = [abs(twist.vx_m_s) / cfg.max_speed_m_s, abs(twist.vy_m_s) / cfg.max_speed_m_s,
                  abs(twist.wz_rad_s) / cfg.max_yaw_rate_rad_s]
        ratios += [abs(v) / cfg.max_wheel_m_s for v in self.wheel_speeds_m_s(twist)]
        worst = max(ratios)
        return twist if worst <= 1.0 else twist.scaled(1.0 / worst)

    def check_limits(self, twist: Twist) -> None:
        """ConfigError naming the first value beyond a body limit, or the wheel speed a
        combination of them would need (for a person's command: refused, not scaled)."""
        cfg = self.config
        self.limit_twist(twist)  # a value that is not a number: its own error
        for name, value, limit, unit in (
                ("vx", twist.vx_m_s, cfg.max_speed_m_s, "m/s"),
                ("vy", twist.vy_m_s, cfg.max_speed_m_s, "m/s"),
                ("wz", math.degrees(twist.wz_rad_s),
                 round(math.degrees(cfg.max_yaw_rate_rad_s), 6), "deg/s")):
            if abs(value) > limit * (1 + 1e-9):
                raise ConfigError(f"{name} = {value:g} {unit} is beyond the chassis's limit; "
                                  f"allowed: {range_text(-limit, limit, unit)}")
        fastest_m_s = max(abs(v) for v in self.wheel_speeds_m_s(twist))
        if fastest_m_s > cfg.max_wheel_m_s * (1 + 1e-9):
            raise ConfigError(
                f"vx {twist.vx_m_s:g} m/s, vy {twist.vy_m_s:g} m/s and wz "
                f"{math.degrees(twist.wz_rad_s):g} deg/s together need a wheel at "
                f"{fastest_m_s / cfg.wheel_circumference_m:.2f} rev/s; the wheels turn at most "
                f"{cfg.max_wheel_rev_s:g} rev/s (in this direction at most "
                f"{cfg.max_wheel_m_s / fastest_m_s:.0%} as fast)")

    def within_limits(self, twist: Twist, slack: float = 1e-9) -> bool:
        """Whether ``twist`` exceeds no body and no wheel limit."""
        cfg = self.config
        return (abs(twist.vx_m_s) <= cfg.max_speed_m_s * (1 + slack)
                and abs(twist.vy_m_s) <= cfg.max_speed_m_s * (1 + slack)
                and abs(twist.wz_rad_s) <= cfg.max_yaw_rate_rad_s * (1 + slack)
                and all(abs(v) <= cfg.max_wheel_m_s * (1 + slack)
                        for v in self.wheel_speeds_m_s(twist)))
