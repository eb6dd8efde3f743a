"""Checks shared by the board's messages: one ConfigError naming the value and its range."""

from __future__ import annotations

import struct

from busarm.errors import ConfigError

__all__ = [
    "check_range",
    "pack_fields",
]


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
