"""How the command line writes what it measures: one formatting of numbers with units,
joint angles, tool poses, places on the table and the gripper, for every command.

Every number carries its unit; no ``-0.0``; a place on the table is whole millimetres
(the survey knows it to about a millimetre), angles and poses one decimal.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

from busarm.arm.gripper import GripperState
from busarm.units import fixed_number, place_text

__all__ = [
    "gripper",
    "joints",
    "number",
    "place",
    "pose",
    "quantity",
]


def number(value: float, digits: int = 1) -> str:
    """``value`` with ``digits`` decimals, never ``-0.0`` (nor ``nan`` as a number): the
    one formatting of busarm's printed numbers (``busarm.units.fixed_number``)."""
    return fixed_number(value, digits)


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
    """``(172, 14) mm``: a place on the table (``busarm.units.place_text``)."""
    return place_text(xy_mm[:2])


def gripper(state: GripperState) -> str:
    """The gripper as a person sees it (``busarm.arm.gripper``): ``open 29.2 mm (544
    pulses)``, ``closed 0.0 mm (700 pulses)``, ``holding something 30.8 mm wide (536
    pulses; told 700, stopped 164 short)``; the torque when it is off."""
    torque = ", torque off" if state.torque_on is False else ""
    gap = quantity(state.gap_mm, "mm")
    if state.is_holding:
        return (f"holding something {gap} wide ({state.position_pulses} pulses; told "
                f"{state.target_pulses}, stopped {state.short_of_target_pulses} short{torque})")
    return f"{state.state} {gap} ({state.position_pulses} pulses{torque})"
