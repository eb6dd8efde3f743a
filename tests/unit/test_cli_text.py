"""The command line's one formatting of measured values (busarm.cli.text)."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from busarm.cli import text


@given(st.floats(-1e4, 1e4), st.integers(0, 3))
def test_numbers_read_back_and_are_never_minus_zero(value: float, digits: int) -> None:
    shown = text.number(value, digits)
    assert abs(float(shown) - value) <= 0.5 * 10 ** -digits + 1e-9
    assert not (shown.startswith("-") and float(shown) == 0.0)


def test_every_line_carries_its_units() -> None:
    assert text.joints(["base_yaw", "shoulder_pitch"], [-0.001, -43.71]) == (
        "base_yaw 0.0  shoulder_pitch -43.7 deg")
    assert text.pose(200.0, -0.04, 40.0, -90.0, 0.0) == (
        "x 200.0  y 0.0  z 40.0 mm  pitch -90.0  roll 0.0 deg")
    assert text.place((171.8238837475933, 14.308332440597791)) == "(172, 14) mm"
    assert text.quantity(7.4, "V", 2) == "7.40 V"
    assert text.number(math.nan) == "unknown"


def test_the_gripper_says_what_it_does() -> None:
    from busarm.arm.config import load_arm_config
    from busarm.arm.gripper import gripper_state

    g = load_arm_config().gripper
    opened = g.pulses_for_gap_mm(29.0)
    assert text.gripper(gripper_state(g, opened, g.open_pulses, True)) == (
        f"open {g.gap_mm_at(opened):.1f} mm ({opened} pulses)")
    assert text.gripper(gripper_state(g, g.closed_pulses, g.closed_pulses, False)) == (
        f"closed 0.0 mm ({g.closed_pulses} pulses, torque off)")
    held = text.gripper(gripper_state(g, opened, g.closed_pulses, True))
    assert held.startswith(f"holding something {g.gap_mm_at(opened):.1f} mm wide (")
    assert f"told {g.closed_pulses}, stopped {abs(g.closed_pulses - opened)} short" in held
