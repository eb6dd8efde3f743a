"""How the command line writes what it measures: one formatting of numbers with units,
joint angles, tool poses, places on the table and the gripper, for every command.

Every number carries its unit; no ``-0.0``; a place on the table is whole millimetres
(the survey knows it to about a millimetre), angles and poses one decimal.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence


def number(value: float, digits: int = 1) -> str:
    """``value`` with ``digits`` decimals, never ``-0.0`` (nor ``nan`` as a number)."""
    if math.isnan(value):
        return "unknown"
    text = f"{value:.{digits}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text


def quantity(value: float, unit: str, digits: int = 1) -> str:
    """``12.5 mm``, ``-30.0 deg``, ``7.40 V``."""
    return f"{number(value, digits)} {unit}"


def joints(names: Iterable[str], angles_deg: Iterable[float], digits: int = 1) -> str:
    """``base_yaw 0.0  shoulder_pitch -43.7  ... deg``: each joint's angle, the unit once."""
    parts = [f"{name} {number(a, digits)}" for name, a in zip(names, angles_deg, strict=True)]
    return "  ".join(parts) + " deg"


def pose(x_mm: float, y_mm: float, z_mm: float, pitch_deg: float, roll_deg: float) -> str:
    """``x 200.0  y 0.0  z 40.0 mm  pitch -90.0  roll 0.0 deg``: the tool's pose."""
    return (f"x {number(x_mm)}  y {number(y_mm)}  z {number(z_mm)} mm  "
            f"pitch {number(pitch_deg)}  roll {number(roll_deg)} deg")


def place(xy_mm: Sequence[float]) -> str:
    """``(172, 14) mm``: a place on the table."""
    return f"({number(xy_mm[0], 0)}, {number(xy_mm[1], 0)}) mm"


def gripper(gap_mm: float | None, *, holding: bool | None = None) -> str:
    """The gripper as a person sees it: ``open 29.0 mm``, ``holding a block (30.5 mm)``,
    ``closed``; ``unknown`` if it could not be read."""
    if gap_mm is None or math.isnan(gap_mm):
        return "unknown (no reply)"
    if holding:
        return f"holding a block ({quantity(gap_mm, 'mm')} apart)"
    if gap_mm < 0.5:
        return "closed"
    return f"open {quantity(gap_mm, 'mm')}"
