"""The LX wire's units and their conversions to degrees and seconds.

Wire: positions in pulses (0..1000 over 0..240 deg, 500 = mid-point), offsets in pulses
too (-125..125 = -30..30 deg), move times in ms (at most 30 s), motor speed as a duty
value -1000..1000. User: degrees from the mid-point, seconds. These are the LX servo
family's numbers: another family has its own (``busarm.bus.servo_port.ServoModel``),
which is why they live with the LX protocol and not in ``busarm.units``.
"""

from __future__ import annotations

from busarm.units import check_range

__all__ = [
    "CENTER_PULSES",
    "DEG_PER_PULSE",
    "MOTOR_SPEED_MAX",
    "MOVE_TIME_MAX_MS",
    "OFFSET_MAX_PULSES",
    "OFFSET_MIN_PULSES",
    "POSITION_MAX_DEG",
    "POSITION_MAX_PULSES",
    "POSITION_MIN_DEG",
    "POSITION_MIN_PULSES",
    "deg_from_pulses",
    "ms_from_s",
    "offset_deg_from_pulses",
    "offset_pulses_from_deg",
    "pulses_from_deg",
]


DEG_PER_PULSE = 0.24
"""One position pulse is 0.24 deg (1000 pulses = 240 deg)."""
CENTER_PULSES = 500
"""The servo's mid-point, which busarm calls 0 deg."""
POSITION_MIN_PULSES = 0
POSITION_MAX_PULSES = 1000
POSITION_MIN_DEG = (POSITION_MIN_PULSES - CENTER_PULSES) * DEG_PER_PULSE  # -120
POSITION_MAX_DEG = (POSITION_MAX_PULSES - CENTER_PULSES) * DEG_PER_PULSE  # +120
OFFSET_MIN_PULSES = -125
OFFSET_MAX_PULSES = 125
MOVE_TIME_MAX_MS = 30000
MOTOR_SPEED_MAX = 1000
"""Motor-mode speed is a unitless duty value, -1000..1000, as on the wire."""


def deg_from_pulses(position_pulses: float) -> float:
    """Degrees from the mid-point for a position in pulses (500 -> 0.0)."""
    return (position_pulses - CENTER_PULSES) * DEG_PER_PULSE


def pulses_from_deg(angle_deg: float) -> int:
    """Nearest position in pulses for an angle in degrees from the mid-point.

    Raises ConfigError if the angle is outside the servo's -120..120 deg.
    """
    check_range("angle_deg", angle_deg, POSITION_MIN_DEG, POSITION_MAX_DEG, "deg")
    return round(angle_deg / DEG_PER_PULSE) + CENTER_PULSES


def offset_deg_from_pulses(offset_pulses: int) -> float:
    """Degrees for an angle offset in pulses (125 -> 30 deg)."""
    return offset_pulses * DEG_PER_PULSE


def offset_pulses_from_deg(offset_deg: float) -> int:
    """Nearest offset in pulses for degrees, within the servo's -30..30 deg."""
    check_range(
        "offset_deg", offset_deg, OFFSET_MIN_PULSES * DEG_PER_PULSE,
        OFFSET_MAX_PULSES * DEG_PER_PULSE, "deg",
    )
    return round(offset_deg / DEG_PER_PULSE)


def ms_from_s(duration_s: float) -> int:
    """Whole milliseconds for seconds, within the wire's 0..30 s."""
    check_range("duration_s", duration_s, 0.0, MOVE_TIME_MAX_MS / 1000.0, "s")
    return round(duration_s * 1000.0)
