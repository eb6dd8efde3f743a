"""The physical constants of a simulated servo model (``ServoParams``): speeds, heat,
supply; and the two models on the arm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from busarm.errors import ConfigError
from busarm.protocol.lx_units import DEG_PER_PULSE

__all__ = [
    "FULL_TURN_PULSES",
    "PARAMS_20KG",
    "PARAMS_35KG",
    "ServoParams",
]


FULL_TURN_PULSES = round(360.0 / DEG_PER_PULSE)
"""One full turn of the horn in pulses (1500), the period of motor-mode readings."""


@dataclass(frozen=True)
class ServoParams:
    """Physical constants of one servo model. Defaults: the arm's 35 kg joints.

    Speeds are the vendor's nominal no-load figures at 11.1 V; the thermal figures are
    assumptions chosen so that a stalled servo trips in tens of seconds. Tests may
    shrink the times to run faster.
    """

    max_speed_s_per_60deg: float = 0.20
    """Fastest position-mode move: seconds per 60 deg (0.2 -> 300 deg/s = 1250 pulses/s)."""
    motor_deg_per_s_at_full_speed: float = 300.0
    """Motor mode: turning rate at speed 1000 (rate is proportional to speed)."""
    stall_time_s: float = 0.5
    """How long a loaded motor must be held short of its target before STALLED shows."""
    ambient_c: float = 25.0
    """Ambient temperature: power-on temperature and what an idle servo cools to."""
    thermal_time_constant_s: float = 40.0
    """Time constant of the first-order thermal model."""
    full_effort_rise_c: float = 100.0
    """Steady temperature rise above ambient at effort 1 (pushing a stop)."""
    effort_holding: float = 0.02
    """Effort (0..1) of a loaded servo holding still."""
    effort_moving: float = 0.15
    """Effort of a servo moving freely."""
    effort_stalled: float = 1.0
    """Effort of a servo pushing against an obstacle."""
    over_temp_hysteresis_c: float = 1.0
    """An over-temperature fault clears at temp_max - this (must be > 0)."""
    supply_mv: int = 11100
    """Supply voltage at power-on (a 3S pack); change it with ``SimServo.supply_mv``."""
    min_responsive_mv: int = 6000
    """Below this supply the servo stops answering and blinks (field notes)."""
    motor_wrap_min_pulses: float = -250.0
    """Lowest reading in motor mode; readings wrap into [this, this + 1500)."""
    answers_wait_read: bool = True
    """False: never answer MOVE_TIME_WAIT_READ (reported of some servos)."""

    def __post_init__(self) -> None:
        positive = (
            "max_speed_s_per_60deg", "motor_deg_per_s_at_full_speed",
            "thermal_time_constant_s", "over_temp_hysteresis_c",
        )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"ServoParams.{name} = {value!r} must be > 0")
        non_negative = ("stall_time_s", "full_effort_rise_c")
        for name in non_negative:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"ServoParams.{name} = {value!r} must be >= 0")
        for name in ("effort_holding", "effort_moving", "effort_stalled"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise ConfigError(f"ServoParams.{name} = {value!r} is out of range 0..1")
        if not math.isfinite(self.ambient_c):
            raise ConfigError(f"ServoParams.ambient_c = {self.ambient_c!r} must be finite")
        for name in ("supply_mv", "min_responsive_mv"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 65535:
                raise ConfigError(f"ServoParams.{name} = {value!r} is out of range 0..65535")
        # The wrapped turn must hold every position-mode angle, offsets included.
        lo = self.motor_wrap_min_pulses
        if not -375.0 <= lo <= -125.0:
            raise ConfigError(
                f"ServoParams.motor_wrap_min_pulses = {lo!r} is out of range -375..-125"
            )

    @property
    def max_speed_pulses_per_s(self) -> float:
        """Fastest position-mode speed in pulses per second."""
        return 60.0 / DEG_PER_PULSE / self.max_speed_s_per_60deg

    @property
    def motor_pulses_per_s_at_full_speed(self) -> float:
        """Motor-mode rate at speed 1000 in pulses per second."""
        return self.motor_deg_per_s_at_full_speed / DEG_PER_PULSE

    @classmethod
    def arm_35kg(cls) -> ServoParams:
        """The arm's 35 kg joint servos (the defaults)."""
        return cls()

    @classmethod
    def gripper(cls) -> ServoParams:
        """The 20 kg gripper servo: 0.18 s/60 deg nominal; smaller, so it heats faster."""
        return cls(
            max_speed_s_per_60deg=0.18,
            motor_deg_per_s_at_full_speed=60.0 / 0.18,
            thermal_time_constant_s=30.0,
        )


PARAMS_35KG = ServoParams()
"""The arm's 35 kg joint servos."""
PARAMS_20KG = ServoParams.gripper()
"""The 20 kg gripper servo."""
