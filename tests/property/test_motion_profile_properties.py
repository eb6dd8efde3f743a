"""The ``time_optimal`` line profile (Ruckig's jerk-limited move of the path parameter):
from 0 to 1, never back, within the speed and acceleration it was given."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.arm.line_plan import MAX_TURN_SPEED_DEG_S
from busarm.arm.motion import (
    LINE_ACCEL_MM_S2,
    TIME_OPTIMAL,
    TURN_ACCEL_DEG_S2,
    check_profile,
    duration_for_speed,
    line_profile,
)
from busarm.errors import ConfigError

STEPS = 400


@settings(max_examples=150, deadline=None)
@given(length_mm=st.floats(0.5, 800.0), turn_deg=st.floats(0.0, 200.0),
       speed_mm_s=st.floats(10.0, 1000.0))
def test_time_optimal_goes_once_from_start_to_end_within_its_limits(
        length_mm: float, turn_deg: float, speed_mm_s: float) -> None:
    fn, duration_s = line_profile(TIME_OPTIMAL, length_mm, turn_deg, speed_mm_s,
                                  MAX_TURN_SPEED_DEG_S)
    assert fn(0.0) == 0.0 and fn(1.0) == 1.0
    s = [fn(k / STEPS) for k in range(STEPS + 1)]
    assert all(b >= a - 1e-12 for a, b in itertools.pairwise(s))
    dt = duration_s / STEPS
    speed = [(b - a) / dt for a, b in itertools.pairwise(s)]
    accel = [(b - a) / dt for a, b in itertools.pairwise(speed)]
    # Averages over a step never exceed the limits the profile keeps at every instant.
    assert max(speed) * length_mm <= speed_mm_s * 1.001
    assert max(speed) * turn_deg <= MAX_TURN_SPEED_DEG_S * 1.001
    assert max(abs(a) for a in accel) * length_mm <= LINE_ACCEL_MM_S2 * 1.01
    assert max(abs(a) for a in accel) * turn_deg <= TURN_ACCEL_DEG_S2 * 1.01
    # It cannot beat cruising at the speed limit all the way.
    assert duration_s >= length_mm / speed_mm_s * 0.999


@given(length_mm=st.floats(100.0, 800.0), speed_mm_s=st.floats(10.0, 300.0))
def test_time_optimal_is_faster_than_min_jerk_at_the_same_peak_speed_on_long_lines(
        length_mm: float, speed_mm_s: float) -> None:
    _, fast_s = line_profile(TIME_OPTIMAL, length_mm, 0.0, speed_mm_s, 90.0)
    assert fast_s < duration_for_speed("min_jerk", length_mm, speed_mm_s)


def test_a_line_that_neither_moves_nor_turns_takes_no_time() -> None:
    fn, duration_s = line_profile(TIME_OPTIMAL, 0.0, 0.0, 100.0, 90.0)
    assert duration_s == 0.0 and fn(1.0) == 1.0


def test_time_optimal_has_no_fixed_shape_and_unknown_profiles_are_named() -> None:
    with pytest.raises(ConfigError, match="'time_optimal' has no fixed shape"):
        check_profile(TIME_OPTIMAL)
    with pytest.raises(ConfigError, match="'fast' is unknown; choose one of min_jerk, "
                                          "trapezoidal, linear, time_optimal"):
        line_profile("fast", 10.0, 0.0, 100.0, 90.0)
