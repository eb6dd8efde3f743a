"""Checks shared by the board's messages: one ConfigError naming the value and its range."""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

from busarm.errors import ConfigError

__all__ = [
    "FLOAT32_MAX",
    "check_range",
    "motor_floats",
    "pack_fields",
]


FLOAT32_MAX = 3.4028234663852886e38


def pack_fields(what: str, fmt: str, *values: int | float) -> bytes:
    """``struct.pack``, or a ConfigError saying which values do not fit the wire."""
    try:
        return struct.pack(fmt, *values)
    except struct.error as exc:
        raise ConfigError(f"{what}: {values} do not fit the board's fields ({exc})") from None


def check_range(name: str, value: int, lo: int, hi: int) -> int:
    """``value`` if it is an int in ``lo..hi``; else ConfigError naming it and the range."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ConfigError(f"{name} = {value!r}; allowed: {lo}..{hi}")
    return value


def motor_floats(sub: int, pairs: Sequence[tuple[int, float]], motors: int, what: str,
                 unit: str = "") -> bytes:
    """The data of a MOTOR sub-command that sets a float32 per motor: ``sub``, the count,
    then each (motor, 1-based on the API, 0-based on the wire) and its value; ConfigError
    naming a bad motor, count or value (``what``, in ``unit``)."""
    check_range("motor count", len(pairs), 1, motors)
    data = bytearray((sub, len(pairs)))
    for motor, value in pairs:
        check_range("motor", motor, 1, motors)
        if not math.isfinite(value) or abs(value) > FLOAT32_MAX:
            raise ConfigError(f"motor {motor} {what} = {value!r}{unit}; allowed: a finite "
                              f"number within +-{FLOAT32_MAX:.4g} (float32)")
        data += struct.pack("<Bf", motor - 1, value)
    return bytes(data)
