"""``Pose2D.interpolated`` as properties: the position moves along the straight line by
the fraction asked, the yaw turns the short way round (never more than half a turn, in
-pi..pi), and the two ends are the two poses. The angle arithmetic here is written out
(degrees, modulo 360) rather than taken from busarm's wrap_rad."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from busarm.base.odometry import Pose2D

COORD = st.floats(-50.0, 50.0, allow_nan=False)
YAW = st.floats(-math.pi, math.pi, allow_nan=False)
FRACTION = st.floats(0.0, 1.0, allow_nan=False)
POSES = st.builds(Pose2D, COORD, COORD, YAW)


def near(value: float) -> object:
    return pytest.approx(value, abs=1e-9)


def short_turn_deg(from_rad: float, to_rad: float) -> float:
    """The signed turn (degrees, -180..180) from one heading to another, the short way."""
    return (math.degrees(to_rad - from_rad) + 180.0) % 360.0 - 180.0


@given(POSES, POSES, FRACTION)
def test_the_position_moves_that_fraction_along_the_straight_line(
        a: Pose2D, b: Pose2D, f: float) -> None:
    p = a.interpolated(b, f)
    whole = math.hypot(b.x_m - a.x_m, b.y_m - a.y_m)
    assert math.hypot(p.x_m - a.x_m, p.y_m - a.y_m) == near(f * whole)
    assert math.hypot(b.x_m - p.x_m, b.y_m - p.y_m) == near((1 - f) * whole)


@given(POSES, POSES, FRACTION)
def test_the_yaw_turns_that_fraction_of_the_short_way_round(
        a: Pose2D, b: Pose2D, f: float) -> None:
    turn = short_turn_deg(a.yaw_rad, b.yaw_rad)
    assume(abs(abs(turn) - 180.0) > 1e-6)  # half a turn: either way is as short
    p = a.interpolated(b, f)
    assert -math.pi <= p.yaw_rad <= math.pi
    assert short_turn_deg(a.yaw_rad, p.yaw_rad) == near(f * turn)
    assert short_turn_deg(p.yaw_rad, b.yaw_rad) == near((1 - f) * turn)


@given(POSES, POSES)
def test_the_ends_are_the_two_poses(a: Pose2D, b: Pose2D) -> None:
    for pose, end in ((a.interpolated(b, 0.0), a), (a.interpolated(b, 1.0), b)):
        assert (pose.x_m, pose.y_m) == (near(end.x_m), near(end.y_m))
        assert short_turn_deg(pose.yaw_rad, end.yaw_rad) == near(0.0)


@given(POSES, POSES, FRACTION)
def test_from_either_end_it_is_the_same_pose(a: Pose2D, b: Pose2D, f: float) -> None:
    assume(abs(abs(short_turn_deg(a.yaw_rad, b.yaw_rad)) - 180.0) > 1e-6)
    there, back = a.interpolated(b, f), b.interpolated(a, 1 - f)
    assert (there.x_m, there.y_m) == (near(back.x_m), near(back.y_m))
    assert short_turn_deg(there.yaw_rad, back.yaw_rad) == near(0.0)


def test_across_the_back_the_yaw_turns_through_pi_not_through_zero() -> None:
    # From 170 degrees to -170 degrees is 20 degrees through 180, not 340 through 0.
    a = Pose2D(0.0, 0.0, math.radians(170.0))
    b = Pose2D(1.0, 2.0, math.radians(-170.0))
    mid = a.interpolated(b, 0.5)
    assert abs(mid.yaw_rad) == near(math.pi)
    assert (mid.x_m, mid.y_m) == (near(0.5), near(1.0))
    assert math.degrees(a.interpolated(b, 0.25).yaw_rad) == near(175.0)
