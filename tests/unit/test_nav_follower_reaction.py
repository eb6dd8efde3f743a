"""The follower's braking with a control period (``reaction_s``) and the straight run it
reports ahead (``to_stop_m``, what the navigator's guard looks along)."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.nav.follower import FollowerSettings, PathFollower

CHASSIS = load_chassis_config()
KINEMATICS = MecanumKinematics(CHASSIS)
Point = tuple[float, float]
SCAN_S = 0.1
"""The navigator's control period: one command a Lidar revolution."""
NAV = FollowerSettings(max_speed_m_s=1.0, slow_radius_m=0.05,
                       reaction_s=SCAN_S).within(CHASSIS)
"""As the navigator drives: at the chassis's limits, braking in time after a scan."""


def ramp(now: Twist, command: Twist, dt_s: float) -> Twist:
    """The twist ``Base.drive`` makes of ``command``: limited, then stepped toward it by
    the chassis's accelerations over ``dt_s``."""
    target = KINEMATICS.limit_twist(command)
    d = (target.vx_m_s - now.vx_m_s, target.vy_m_s - now.vy_m_s,
         target.wz_rad_s - now.wz_rad_s)
    worst = max(abs(d[0]) / (CHASSIS.max_accel_m_s2 * dt_s),
                abs(d[1]) / (CHASSIS.max_accel_m_s2 * dt_s),
                abs(d[2]) / (CHASSIS.max_yaw_accel_rad_s2 * dt_s), 1.0)
    return Twist(now.vx_m_s + d[0] / worst, now.vy_m_s + d[1] / worst,
                 now.wz_rad_s + d[2] / worst)


def drive_at_scan_rate(follower: PathFollower, pose: Pose2D, seconds: float = 30.0
                       ) -> tuple[Pose2D, float | None, float]:
    """One command a scan, held for the scan: (the final pose, when it was done, the
    fastest it went)."""
    twist, fastest = Twist(), 0.0
    for k in range(int(seconds / SCAN_S)):
        command = follower.command(pose)
        if follower.done:
            return pose, k * SCAN_S, fastest
        twist = ramp(twist, command, SCAN_S)
        fastest = max(fastest, math.hypot(twist.vx_m_s, twist.vy_m_s))
        for _ in range(10):
            pose = pose.moved_by(twist.vx_m_s * SCAN_S / 10, twist.vy_m_s * SCAN_S / 10,
                                 twist.wz_rad_s * SCAN_S / 10)
    return pose, None, fastest


@pytest.mark.parametrize(("path", "yaw"), [
    ([(0.0, 0.0), (2.0, 0.0)], 0.0),
    ([(0.0, 0.0), (1.2, 0.0), (1.2, 1.0)], math.pi / 2),
    ([(0.0, 0.0), (0.25, 0.0)], 0.0),
])
def test_at_one_command_a_scan_it_arrives_at_the_chassis_speed_without_a_crawl(
        path: list[Point], yaw: float) -> None:
    follower = PathFollower(path, yaw, NAV)
    final, done_at_s, fastest = drive_at_scan_rate(follower, Pose2D())
    assert done_at_s is not None
    assert math.dist((final.x_m, final.y_m), path[-1]) <= NAV.goal_tolerance_m
    assert abs(wrap_rad(final.yaw_rad - yaw)) <= NAV.yaw_tolerance_rad
    # The way at full speed, plus speeding up, braking and the corner: no slow tail.
    assert done_at_s < follower.length_m / CHASSIS.max_speed_m_s + 2.0
    if follower.length_m > 1.0:
        assert fastest > 0.9 * CHASSIS.max_speed_m_s


@settings(max_examples=200, deadline=None)
@given(st.floats(0.0, 0.3), st.floats(0.0, 3.0), st.floats(-0.05, 0.05),
       st.floats(0.2, 2.0), st.floats(-1.5, 1.5))
def test_it_never_asks_a_speed_it_cannot_brake_from_after_the_reaction_time(
        reaction_s: float, x_m: float, y_m: float, leg_m: float, turn: float) -> None:
    cfg = FollowerSettings(max_speed_m_s=0.4, reaction_s=reaction_s)
    corner = (1.5, 0.0)
    end = (corner[0] + leg_m * math.cos(turn), leg_m * math.sin(turn))
    follower = PathFollower([(0.0, 0.0), corner, end], None, cfg)
    pose = Pose2D(min(x_m, 1.5), y_m, 0.0)
    command = follower.command(pose)
    if follower.done:
        return
    v = math.hypot(command.vx_m_s, command.vy_m_s)
    a = cfg.max_accel_m_s2
    # On at v for the reaction time, then braking at a: it stops within the way left...
    assert v * reaction_s + v * v / (2 * a) <= follower.remaining_m(pose) + 1e-9
    # ... and comes to the corner no faster than the corner allows.
    s = follower.progress_m
    if s < corner[0]:
        turn_speed = min(0.4, math.sqrt(a * cfg.corner_cut_m) / max(math.sin(abs(turn) / 2),
                                                                     1e-12))
        assert v * reaction_s + (v * v - turn_speed**2) / (2 * a) <= corner[0] - s + 1e-9


def test_without_a_reaction_time_the_braking_is_as_it_was() -> None:
    path = [(0.0, 0.0), (1.0, 0.0)]
    for x in (0.0, 0.5, 0.9, 0.97):
        plain = PathFollower(path, 0.0).command(Pose2D(x, 0.0, 0.0))
        assert plain.vx_m_s == pytest.approx(min(0.25, math.sqrt(2 * 0.4 * (1.0 - x)),
                                                 max(0.25 * (1.0 - x) / 0.3, 0.02)))


def test_the_run_ahead_ends_at_the_next_sharp_corner_or_the_goal() -> None:
    follower = PathFollower([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], None)
    here = Pose2D(0.2, 0.0, 0.0)
    follower.command(here)
    assert follower.to_stop_m(here) == pytest.approx(0.8)
    # Off the path, the way back onto it counts too.
    assert follower.to_stop_m(Pose2D(0.2, 0.3, 0.0)) == pytest.approx(0.3 + 0.8)
    for x in (0.6, 0.99):  # (its progress is searched for near where it was)
        here = Pose2D(x, 0.0, 0.0)
        follower.command(here)
    # Within the corner cut the base turns onto the next leg: its run is to the goal.
    assert follower.to_stop_m(here) == pytest.approx(1.01)
    # A gentle bend (under CORNER_RAD) is driven through: no stop there.
    gentle = PathFollower([(0.0, 0.0), (1.0, 0.0), (2.0, 0.1)], None)
    gentle.command(Pose2D(0.5, 0.0, 0.0))
    assert gentle.to_stop_m(Pose2D(0.5, 0.0, 0.0)) == pytest.approx(gentle.length_m - 0.5)
    assert PathFollower([(0.3, 0.4)], 0.0).to_stop_m(Pose2D()) == pytest.approx(0.5)
