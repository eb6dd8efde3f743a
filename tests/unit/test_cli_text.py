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
    assert text.gripper(29.04) == "open 29.0 mm"
    assert text.gripper(30.5, holding=True) == "holding a block (30.5 mm apart)"
    assert text.gripper(0.2) == "closed"
    assert text.gripper(None) == "unknown (no reply)"
