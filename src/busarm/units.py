"""Unit conversions and the value checks and wording every layer shares.

Volts and millivolts; range checks (``check_range``, ``check_int_range``) and how a
value, a range or a list is written in a message. A servo family's own wire units
(the LX servos' pulses, 0.24 deg each) live with its protocol:
``busarm.protocol.lx_units``.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Iterable
from decimal import Decimal
from typing import Any

from busarm.errors import ConfigError

__all__ = [
    "changed_fields",
    "check_int_range",
    "check_range",
    "fixed_number",
    "listing",
    "mv_from_v",
    "parse_ids",
    "place_text",
    "plain_number",
    "range_text",
    "short_repr",
    "shown",
    "v_from_mv",
]


def check_range(
    name: str, value: object, lo: float, hi: float, unit: str = "", *,
    error: type[ConfigError] = ConfigError,
) -> float:
    """``value`` as a float if it is a finite number (not a bool) within lo..hi.

    The one numeric range check of busarm (``check_int_range`` for integers): else
    ``error`` naming ``name``, the bad value and the range, in ``unit`` if given:
    ``"speed = 2000 deg/s is out of range 0.1..1000 deg/s"``, or ``"speed must be a
    number, got 'fast'"`` for a value that is not a finite number.
    """
    # (A plain float first: the ABC check costs a microsecond, and this runs per blob.)
    if ((type(value) is not float
         and (isinstance(value, bool) or not isinstance(value, numbers.Real)))
            or not math.isfinite(value)):
        raise error(f"{name} must be a number, got {shown(value)}")
    number = float(value)
    if not lo <= number <= hi:
        u = f" {unit}" if unit else ""
        raise error(f"{name} = {shown(value)}{u} is out of range {range_text(lo, hi, unit)}")
    return number


def check_int_range(
    name: str, value: object, lo: int, hi: int, unit: str = "", *,
    error: type[ConfigError] = ConfigError,
) -> int:
    """``value`` as an int if it is an integer (not a bool) within lo..hi, else ``error``
    as ``check_range`` words it (``"ids must be an integer 0..253, got 1.5"``)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise error(f"{name} must be an integer {range_text(lo, hi, unit)}, got {shown(value)}")
    number = int(value)
    if not lo <= number <= hi:
        u = f" {unit}" if unit else ""
        raise error(f"{name} = {number}{u} is out of range {range_text(lo, hi, unit)}")
    return number


def range_text(lo: float, hi: float, unit: str = "") -> str:
    """``"lo..hi unit"`` as the messages show it: ``0..30 s``, not ``0.0..30.0 s``, and
    ``0..1000000000 px``, not ``0..1e+09 px``."""
    return f"{plain_number(lo)}..{plain_number(hi)}{f' {unit}' if unit else ''}"


def plain_number(x: float) -> str:
    """A number as a person writes it: every digit it has, no exponent, no ``.0`` on a
    whole number, no ``-0`` (``2.0`` -> ``2``, ``1e9`` -> ``1000000000``, ``1e-05`` ->
    ``0.00001``)."""
    if isinstance(x, bool) or not math.isfinite(x):
        return str(x)
    text = format(Decimal(repr(float(x))), "f")  # the shortest digits of this float
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def fixed_number(value: float, digits: int = 1) -> str:
    """``value`` with ``digits`` decimals as every printed measurement of busarm: never
    ``-0`` or ``-0.0`` (a value that rounds to zero has no sign), ``unknown`` for nan."""
    if math.isnan(value):
        return "unknown"
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def place_text(coordinates_mm: Iterable[float]) -> str:
    """``(172, -14) mm``: a place (x, y[, z]) as every message says it, whole millimetres
    (the survey knows it to about a millimetre), never ``-0``."""
    return f"({', '.join(fixed_number(float(c), 0) for c in coordinates_mm)}) mm"


def shown(value: object) -> str:
    """A value as a message quotes it to a person: a number as given (``2.5``, ``120.0``,
    ``1000000000.0``: no exponent), text in quotes, nothing as ``nothing``, true and false
    as TOML and JSON write them, a list or an object by its items (never Python's
    ``None``, ``True``, ``[...]`` or ``{...}``)."""
    if value is None:
        return "nothing"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        text = repr(float(value))
        return plain_number(float(value)) if "e" in text and math.isfinite(value) else text
    if isinstance(value, dict):
        return "an object with " + (f"keys {listing(value)}" if value else "no keys")
    if isinstance(value, list | tuple | set | frozenset):
        return f"a list of {len(value)}: {listing(value)}" if value else "an empty list"
    return repr(value)


def listing(items: Iterable[object]) -> str:
    """``a, b, c``: names or values as a message lists them (text as it is, the rest as
    ``shown``); not a Python list's brackets and quotes."""
    return ", ".join(i if isinstance(i, str) else shown(i) for i in items)


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
        if lo < 0 or hi > 253:
            # Said once for the whole part: "1-300" is one mistake, not 47 bad IDs.
            raise ConfigError(
                f"servo IDs {text!r}: {part!r} is outside the servo IDs 0-253 "
                "(254 is the broadcast ID)"
            )
        ids.extend(range(lo, hi + 1))
    if not ids:
        raise ConfigError(f"servo IDs {text!r}: no ID given")
    return ids


def changed_fields(obj: Any) -> list[tuple[str, Any]]:
    """(name, value) of a dataclass's fields whose values differ from their defaults (not
    ``label``: the user's own words for it), in their order."""
    out = []
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        default = (f.default if f.default is not dataclasses.MISSING else
                   f.default_factory() if f.default_factory is not dataclasses.MISSING
                   else dataclasses.MISSING)
        if f.name != "label" and value != default:
            out.append((f.name, value))
    return out


def short_repr(obj: Any) -> str:
    """``Name(key=value, ...)`` of a dataclass, with only the fields that differ from their
    defaults (``changed_fields``): a description's repr a person can read. A long value
    (a scene, an arm config) is shown by its name or kind; a part shown so, in full."""
    parts = []
    for name, value in changed_fields(obj):
        text = repr(value)
        if len(text) > 60 and getattr(type(value), "__repr__", None) is not short_repr:
            shown_as = getattr(value, "name", None) or getattr(value, "source", None)
            text = f"<{type(value).__name__}{f' {shown_as!r}' if shown_as else ''}>"
        parts.append(f"{name}={text}")
    return f"{type(obj).__name__}({', '.join(parts)})"
