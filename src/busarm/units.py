"""Conversions between the servo's wire units and the user's units.

Wire: positions in pulses (0..1000 over 0..240 deg, 500 = mid-point), offsets in
pulses too (-125..125 = -30..30 deg), times in ms, voltages in mV.
User: degrees from the mid-point, seconds, volts, deg C.
"""

from __future__ import annotations

import math

from busarm.errors import ConfigError

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


def check_range(name: str, value: float, lo: float, hi: float, unit: str = "") -> None:
    """Raise ConfigError naming ``name``, the bad value and the allowed range."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value) or value < lo or value > hi:
        u = f" {unit}" if unit else ""
        raise ConfigError(f"{name} = {value!r}{u} is out of range {lo}..{hi}{u}")


def check_int_range(name: str, value: object, lo: int, hi: int) -> int:
    """Return ``value`` as int if it is an integer within lo..hi, else raise ConfigError."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{name} must be an integer {lo}..{hi}, got {value!r}")
    if value < lo or value > hi:
        raise ConfigError(f"{name} = {value} is out of range {lo}..{hi}")
    return value


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


def v_from_mv(vin_mv: int) -> float:
    return vin_mv / 1000.0


def mv_from_v(vin_v: float) -> int:
    return round(vin_v * 1000.0)


def parse_ids(text: str) -> list[int]:
    """Servo IDs from ``"1,2,3"`` or ``"1-5,10"``, each 0..253, in the order given.

    Duplicates are kept (the simulator uses them for two servos on one ID); a reversed
    range such as ``5-1`` is an error rather than nothing.
    """
    ids: list[int] = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            lo, hi = (int(x) for x in part.split("-", 1)) if "-" in part else (int(part),) * 2
        except ValueError:
            raise ConfigError(f"servo IDs {text!r}: {part!r} is not an ID or a range") from None
        if lo > hi:
            raise ConfigError(f"servo IDs {text!r}: range {part!r} is reversed")
        ids.extend(range(lo, hi + 1))
    for sid in ids:
        if not 0 <= sid <= 253:
            raise ConfigError(f"servo ID {sid} is out of range 0..253")
    if not ids:
        raise ConfigError(f"servo IDs {text!r}: no ID given")
    return ids
