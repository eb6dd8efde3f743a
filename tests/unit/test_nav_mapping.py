"""Scan matching against a map, and a map built while the odometry drifts."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from nav_world import BEARINGS, mapped, scan_from

from busarm.base.config import Mount
from busarm.base.odometry import Pose2D
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.mapping import MapBuilder, compose, inverse
from busarm.nav.scan_match import LikelihoodField, match_scan

# The L-shaped room (no symmetry to fool the matcher) and its scans: nav_world.

FIELD = LikelihoodField(mapped(Pose2D(-1.2, 0.8, 0.0), Pose2D(1.2, -0.8, 1.0)))


@settings(max_examples=25, deadline=None)
@given(st.floats(-0.12, 0.12), st.floats(-0.12, 0.12), st.floats(-5.0, 5.0),
       st.sampled_from([Pose2D(0.0, -0.8, 0.4), Pose2D(-1.0, 0.9, -2.0), Pose2D(1.3, -0.4, 2.5)]))
def test_the_matcher_finds_the_true_pose_from_a_guess_within_its_window(
        dx: float, dy: float, dyaw_deg: float, truth: Pose2D) -> None:
    guess = Pose2D(truth.x_m + dx, truth.y_m + dy, truth.yaw_rad + math.radians(dyaw_deg))
    found = match_scan(FIELD, BEARINGS, scan_from(truth), guess)
    assert math.hypot(found.pose.x_m - truth.x_m, found.pose.y_m - truth.y_m) < 0.03
    assert abs(math.degrees(found.pose.yaw_rad - truth.yaw_rad)) < 1.0
    assert found.matched_share > 0.8


def test_a_scan_of_somewhere_unmapped_is_not_trusted() -> None:
    empty = LikelihoodField(OccupancyGrid(GridSpec.covering(-2.5, 2.5, -2.0, 2.0, 0.05)))
    found = match_scan(empty, BEARINGS, scan_from(Pose2D()), Pose2D(0.1, 0.0, 0.0))
    assert found.matched_share == 0.0
    builder = MapBuilder(GridSpec.covering(-2.5, 2.5, -2.0, 2.0, 0.05), Mount(0, 0, 0.2, 0))
    builder.add(BEARINGS, np.full(len(BEARINGS), np.nan), Pose2D())
    assert builder.add(BEARINGS, scan_from(Pose2D(0.3, 0, 0)), Pose2D(0.3, 0, 0)) == Pose2D(
        0.3, 0, 0) and builder.corrections == 0


def test_the_map_stops_the_odometrys_drift() -> None:
    """The base drives a loop; its odometry reads 4 % long and turns 1 deg too far at each
    step; the builder's poses stay on the true path, the odometry's do not."""
    mount = Mount(0.06, 0.0, 0.18, 0.0)
    builder = MapBuilder(GridSpec.covering(-2.5, 2.5, -2.0, 2.0, 0.025), mount,
                         start=Pose2D(-1.2, -0.9, 0.0))
    truth = Pose2D(-1.2, -0.9, 0.0)
    odom = Pose2D()
    steps = [(0.15, 0.0, 0.0)] * 14 + [(0.0, 0.0, 30.0)] * 3 + [(0.15, 0.0, 0.0)] * 10
    builder.add(BEARINGS, scan_from(compose(truth, Pose2D(0.06, 0, 0))), odom)
    for dx, dy, dyaw in steps:
        truth = compose(truth, Pose2D(dx, dy, math.radians(dyaw)))
        odom = compose(odom, Pose2D(dx * 1.04, dy, math.radians(dyaw * 1.0 + 1.0)))
        pose = builder.add(BEARINGS, scan_from(compose(truth, Pose2D(0.06, 0, 0))), odom)
    believed = compose(Pose2D(-1.2, -0.9, 0.0), odom)
    assert math.hypot(believed.x_m - truth.x_m, believed.y_m - truth.y_m) > 0.25  # drifted
    assert math.hypot(pose.x_m - truth.x_m, pose.y_m - truth.y_m) < 0.03
    assert abs(math.degrees(pose.yaw_rad - truth.yaw_rad)) < 1.0
    assert builder.corrections == len(steps)


def test_compose_and_inverse_undo_each_other() -> None:
    a, b = Pose2D(0.3, -1.2, 2.0), Pose2D(-0.5, 0.7, -2.9)
    back = compose(compose(a, b), inverse(b))
    assert math.isclose(back.x_m, a.x_m) and math.isclose(back.y_m, a.y_m)
    assert math.isclose(back.yaw_rad, a.yaw_rad)
