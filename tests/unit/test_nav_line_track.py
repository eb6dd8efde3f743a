"""The line under the base from remembered sightings; steering onto it; the stop rule."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.odometry import Pose2D
from busarm.nav.line_track import LineController, LineTracker, obstacle_ahead
from busarm.nav.mapping import compose, transform_points


def arc(radius_m: float, bend: int, length_m: float = 6.0) -> np.ndarray:
    """A line along x from (-1, 0): straight (bend 0) or a circle bending left (+1) or
    right (-1) of ``radius_m``; points 5 mm apart."""
    s = np.arange(0.0, length_m, 0.005)
    if bend == 0:
        return np.column_stack([s - 1.0, np.zeros_like(s)])
    a = s / radius_m
    return np.column_stack([radius_m * np.sin(a) - 1.0, bend * radius_m * (1 - np.cos(a))])


def seen_from(line: np.ndarray, pose: Pose2D) -> np.ndarray:
    """The line's points the camera sees from ``pose``: 0.15..0.6 m ahead, +-0.25 m."""
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    d = line - np.array([pose.x_m, pose.y_m])
    local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
    keep = (local[:, 0] >= 0.15) & (local[:, 0] <= 0.6) & (np.abs(local[:, 1]) <= 0.25)
    return local[keep][::4]


def truth(line: np.ndarray, pose: Pose2D) -> tuple[float, float]:
    """The line's signed distance from the base's centre (+: the line is to the left of
    its direction) and its direction relative to the base, at its point nearest the base."""
    i = int(np.argmin(np.hypot(*(line - [pose.x_m, pose.y_m]).T)))
    i = min(i, len(line) - 2)
    tangent = math.atan2(line[i + 1, 1] - line[i, 1], line[i + 1, 0] - line[i, 0])
    rel = math.atan2(math.sin(tangent - pose.yaw_rad), math.cos(tangent - pose.yaw_rad))
    d = line[i] - [pose.x_m, pose.y_m]
    return float(-math.sin(tangent) * d[0] + math.cos(tangent) * d[1]), rel


def drive(line: np.ndarray, start: Pose2D, seconds: float, *, speed_error: float = 0.0,
          dt: float = 0.1) -> list[float]:
    """Closed loop at 10 Hz: sightings, the tracker, the controller; the base moves by
    the command (off by ``speed_error``); returns the true offsets along the way."""
    tracker, control = LineTracker(), LineController()
    pose, odometry, offsets = start, Pose2D(), []
    for _ in range(round(seconds / dt)):
        tracker.add(seen_from(line, pose), odometry)
        under = tracker.under(odometry)
        nearest = tracker.nearest(odometry)
        if under is not None:
            twist = control.command(under)
        elif nearest is not None:
            twist = control.toward(nearest)
        else:
            break
        step = Pose2D(twist.vx_m_s * dt, twist.vy_m_s * dt, twist.wz_rad_s * dt)
        odometry = compose(odometry, step)
        pose = compose(pose, Pose2D(step.x_m * (1 + speed_error), step.y_m * (1 + speed_error),
                                    step.yaw_rad))
        offsets.append(abs(truth(line, pose)[0]))
    return offsets


def along(line: np.ndarray, s_m: float, offset_m: float, yaw_deg: float) -> Pose2D:
    """The pose ``s_m`` along the line, ``offset_m`` to the right of it (the line is at
    +offset to its left), turned ``yaw_deg`` from its direction."""
    i = min(round(s_m / 0.005), len(line) - 2)
    t = math.atan2(line[i + 1, 1] - line[i, 1], line[i + 1, 0] - line[i, 0])
    return Pose2D(line[i, 0] + offset_m * math.sin(t), line[i, 1] - offset_m * math.cos(t),
                  t + math.radians(yaw_deg))


@settings(max_examples=30, deadline=None)
@given(st.sampled_from([0, 1, -1]), st.floats(0.35, 2.0), st.floats(-0.05, 0.05),
       st.floats(-15, 15))
def test_the_line_under_the_base_is_read_from_what_was_seen_ahead(
        bend: int, radius_m: float, offset_m: float, yaw_deg: float) -> None:
    line = arc(radius_m, bend)
    tracker = LineTracker()
    first = along(line, 0.0, offset_m, yaw_deg)
    # The base drives 0.6 m along the line, seeing ahead every 5 cm; the odometry is
    # exact here (its own frame: where the base started).
    for k in range(13):
        pose = along(line, 0.05 * k, offset_m, yaw_deg)
        tracker.add(seen_from(line, pose), compose(_inverse(first), pose))
    under = tracker.under(compose(_inverse(first), pose))
    assert under is not None
    lateral, heading = truth(line, pose)
    assert abs(under.lateral_m - lateral) < 0.002
    assert abs(math.degrees(under.heading_rad - heading)) < 1.5


def _inverse(p: Pose2D) -> Pose2D:
    from busarm.nav.mapping import inverse

    return inverse(p)


def test_nothing_seen_is_no_line() -> None:
    tracker = LineTracker()
    assert tracker.under(Pose2D()) is None
    tracker.add(np.zeros((0, 2)), Pose2D())
    assert tracker.under(Pose2D()) is None
    tracker.add([[0.3, 0.0], [0.4, 0.0], [0.5, 0.0]] * 3, Pose2D())
    assert tracker.under(Pose2D(5.0, 0.0, 0.0)) is None  # all of it forgotten, far behind


@settings(max_examples=15, deadline=None)
@given(st.sampled_from([0, 1, -1]), st.floats(0.35, 1.5), st.floats(-0.03, 0.03),
       st.floats(-10, 10), st.floats(-0.05, 0.05))
def test_the_controller_brings_the_base_onto_the_line_and_keeps_it_there(
        bend: int, radius_m: float, offset_m: float, yaw_deg: float, speed_error: float) -> None:
    line = arc(radius_m, bend, length_m=2.0 * math.pi * 0.35 + 2)
    offsets = drive(line, Pose2D(-1.0, offset_m, math.radians(yaw_deg)), 12.0,
                    speed_error=speed_error)
    assert len(offsets) == 120
    settled = offsets[20:]
    assert max(settled) < 0.01 and float(np.median(settled)) < 0.006


def test_the_stop_rule_sees_what_is_in_the_way_not_beside_it() -> None:
    assert obstacle_ahead(np.zeros((0, 2))) is None
    in_way = obstacle_ahead([[0.45, 0.05], [0.8, 0.0], [-0.3, 0.0]])
    assert in_way == (0.45, 0.05)
    assert obstacle_ahead([[0.35, 0.3]]) is None  # a table edge beside the path
    assert obstacle_ahead([[0.6, 0.0]]) is None   # 0.45 m ahead of the front: not yet
    assert obstacle_ahead([[0.3, 0.25]], corridor_half_m=0.3) == (0.3, 0.25)
    assert obstacle_ahead([[0.2, 0.19]]) == (0.2, 0.19)
    assert obstacle_ahead([[0.1, 0.19]]) is None  # beyond 45 degrees


@settings(max_examples=30, deadline=None)
@given(st.floats(0.5, 2.0), st.sampled_from([-1, 0, 1]), st.floats(-0.5, 2.0))
def test_only_line_not_seen_before_counts_as_unseen(radius_m: float, bend: int,
                                                    along_m: float) -> None:
    line = arc(radius_m, bend)
    tracker = LineTracker()
    pose = Pose2D(-1.0, 0.0, 0.0)
    i = int(np.argmin(np.abs(np.cumsum(np.r_[0, np.hypot(*np.diff(line, axis=0).T)])
                             - (along_m + 1.0))))
    k = min(i, len(line) - 2)
    pose = Pose2D(float(line[k, 0]), float(line[k, 1]),
                  math.atan2(line[k + 1, 1] - line[k, 1], line[k + 1, 0] - line[k, 0]))
    seen = seen_from(line, pose)
    assert tracker.unseen(seen, pose) == len(seen)  # nothing remembered yet
    tracker.add(seen, pose)
    assert tracker.unseen(seen, pose) == 0  # the same line again
    back = compose(pose, Pose2D(-0.1, 0.0, 0.0))  # the part seen, from 10 cm back
    again = seen_from(line, back)
    world = transform_points(back, again)
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    d = world - np.array([pose.x_m, pose.y_m])
    ahead, side = c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]
    was_in_view = (ahead >= 0.17) & (ahead <= 0.58) & (np.abs(side) <= 0.23)
    assert tracker.unseen(again[was_in_view], back) == 0
    beside = seen + np.array([0.0, 0.2])  # a second line 20 cm to the side
    assert tracker.unseen(beside, pose) == len(beside)


def test_floor_seen_at_or_behind_a_wall_is_told() -> None:
    from busarm.base.config import Mount
    from busarm.lidar.scan import LaserScan, at_returns

    angles = np.radians(np.arange(0.0, 360.0, 1.0))
    # A wall 1 m ahead of the Lidar (x = 1.06 m on the base, the Lidar 6 cm forward).
    ahead = np.abs(np.cos(angles)) > 0.3
    ranges = np.where(ahead & (np.cos(angles) > 0), 1.0 / np.cos(angles), np.nan)
    scan = LaserScan(angles, ranges, np.where(np.isnan(ranges), 0.0, 40.0), 0.0, 0.15, 12.0)
    mount = Mount(0.06, 0.0, 0.18, 0.0)
    points = np.array([[0.5, 0.0], [1.0, 0.0], [1.05, 0.1], [1.2, -0.2], [-0.5, 0.0]])
    assert at_returns(points, scan, mount).tolist() == [False, False, True, True, False]
    assert not at_returns(np.zeros((0, 2)), scan, mount).any()
