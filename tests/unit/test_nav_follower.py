"""The path follower, driven in a small simulation of the base; and the safety guard."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.errors import ConfigError
from busarm.nav.costmap import Costmap
from busarm.nav.follower import FollowerSettings, PathFollower, blocked, sweep_m
from busarm.nav.grid import CLAMP_LOG_ODDS, GridSpec, OccupancyGrid
from busarm.nav.planner import plan_path

CHASSIS = load_chassis_config()
KINEMATICS = MecanumKinematics(CHASSIS)
RATE_HZ = 20.0
SPEED_ERROR = (1.03, 0.97, 1.03)
"""What the wheels really do per commanded vx, vy, wz (slip, a motor's gain)."""
Point = tuple[float, float]


@dataclass
class Run:
    poses: list[Pose2D] = field(default_factory=list)
    commands: list[Twist] = field(default_factory=list)
    done_at_s: float | None = None

    @property
    def final(self) -> Pose2D:
        return self.poses[-1]


class Chassis:
    """The base as Base.drive makes it move: the twist limited, ramped at the chassis's
    acceleration limits (the change scaled as a whole), then off by the speed error."""

    def __init__(self, pose: Pose2D) -> None:
        self.pose = pose
        self.twist = Twist()

    def step(self, command: Twist, dt_s: float) -> None:
        target = KINEMATICS.limit_twist(command)
        now = self.twist
        d = (target.vx_m_s - now.vx_m_s, target.vy_m_s - now.vy_m_s,
             target.wz_rad_s - now.wz_rad_s)
        worst = max(abs(d[0]) / (CHASSIS.max_accel_m_s2 * dt_s),
                    abs(d[1]) / (CHASSIS.max_accel_m_s2 * dt_s),
                    abs(d[2]) / (CHASSIS.max_yaw_accel_rad_s2 * dt_s), 1.0)
        self.twist = Twist(now.vx_m_s + d[0] / worst, now.vy_m_s + d[1] / worst,
                           now.wz_rad_s + d[2] / worst)
        ex, ey, ew = SPEED_ERROR
        for _ in range(10):  # integrated finer than the control rate
            t = dt_s / 10
            self.pose = self.pose.moved_by(self.twist.vx_m_s * ex * t,
                                           self.twist.vy_m_s * ey * t,
                                           self.twist.wz_rad_s * ew * t)


def drive(follower: PathFollower, start: Pose2D, seconds: float = 30.0,
          chassis: Chassis | None = None) -> Run:
    """Run the follower at RATE_HZ until it is done and the base stands (or time is up)."""
    chassis = chassis or Chassis(start)
    run = Run([chassis.pose])
    for k in range(int(seconds * RATE_HZ)):
        command = follower.command(chassis.pose)
        run.commands.append(command)
        if follower.done and run.done_at_s is None:
            run.done_at_s = k / RATE_HZ
        chassis.step(command, 1.0 / RATE_HZ)
        run.poses.append(chassis.pose)
        if follower.done and chassis.twist.is_zero:
            break
    return run


def distance_to_path(path: list[Point], x: float, y: float) -> float:
    best = math.inf
    for a, b in itertools.pairwise(path):
        d = np.subtract(b, a)
        t = np.clip(np.dot(np.subtract((x, y), a), d) / max(np.dot(d, d), 1e-18), 0.0, 1.0)
        best = min(best, math.dist((x, y), (a[0] + t * d[0], a[1] + t * d[1])))
    return best


def arc(radius_m: float, degrees: float, step_m: float = 0.05) -> list[Point]:
    n = math.ceil(math.radians(degrees) * radius_m / step_m)
    angles = np.linspace(0.0, math.radians(degrees), n + 1)
    return [(radius_m * math.sin(a), radius_m * (1 - math.cos(a))) for a in angles]


PATHS = {
    "straight": ([(0.0, 0.0), (2.0, 0.0)], 0.0),
    "straight, turning round on the way": ([(0.0, 0.0), (1.5, 0.0)], math.pi),
    "L-shaped": ([(0.0, 0.0), (1.2, 0.0), (1.2, 1.0)], None),
    "curved": (arc(0.8, 150.0), math.radians(150.0)),
    "sideways": ([(0.0, 0.0), (0.0, 0.8)], 0.0),
}


@pytest.mark.parametrize("name", list(PATHS))
def test_the_follower_reaches_the_goal_within_2_cm_and_2_degrees(name: str) -> None:
    path, goal_yaw = PATHS[name]
    follower = PathFollower(path, goal_yaw)
    run = drive(follower, Pose2D(0.0, 0.0, 0.0))
    assert follower.done and run.done_at_s is not None
    gx, gy = path[-1]
    assert math.hypot(run.final.x_m - gx, run.final.y_m - gy) <= 0.02
    last_leg = math.atan2(path[-1][1] - path[-2][1], path[-1][0] - path[-2][0])
    want_yaw = last_leg if goal_yaw is None else goal_yaw
    assert abs(math.degrees(wrap_rad(run.final.yaw_rad - want_yaw))) <= 2.0
    # No dawdling: the path at the speed limit, plus starting, stopping and the corners.
    length = sum(math.dist(a, b) for a, b in itertools.pairwise(path))
    assert run.done_at_s < length / 0.25 + 6.0
    # Within the corner cut of the path all the way (the corners' overshoot included).
    assert max(distance_to_path(path, p.x_m, p.y_m) for p in run.poses) <= 0.03


def test_on_a_straight_path_it_stays_within_5_cm_while_it_turns_round() -> None:
    path = [(0.0, 0.0), (2.0, 0.0)]
    run = drive(PathFollower(path, math.pi), Pose2D(0.0, 0.03, 0.0))
    assert max(abs(p.y_m) for p in run.poses) <= 0.05
    assert min(p.x_m for p in run.poses) >= -0.05 and max(p.x_m for p in run.poses) <= 2.02
    # It turned the whole way round while it went, not standing at the end.
    half_way = next(p for p in run.poses if p.x_m >= 1.0)
    assert abs(half_way.yaw_rad) > 1.5


def test_it_moves_sideways_without_turning_when_the_goal_yaw_says_so() -> None:
    run = drive(PathFollower([(0.0, 0.0), (0.0, 0.8)], 0.0), Pose2D())
    assert max(abs(p.yaw_rad) for p in run.poses) < math.radians(1.0)
    assert all(abs(c.vx_m_s) < 0.02 for c in run.commands)


def test_it_never_asks_to_go_faster_than_it_can_stop_in() -> None:
    cfg = FollowerSettings()
    follower = PathFollower([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0)], None, cfg)
    run = drive(follower, Pose2D())
    for pose, command in zip(run.poses, run.commands, strict=False):
        speed = math.hypot(command.vx_m_s, command.vy_m_s)
        left = math.hypot(1.0 - pose.x_m, 1.0 - pose.y_m)
        assert speed <= min(cfg.max_speed_m_s, math.sqrt(2 * cfg.max_accel_m_s2 * left)) + 1e-9
        assert abs(command.wz_rad_s) <= cfg.max_yaw_rate_rad_s + 1e-9
    assert max(math.hypot(c.vx_m_s, c.vy_m_s) for c in run.commands) > 0.24


def test_once_done_it_stays_stopped_and_reports_progress() -> None:
    follower = PathFollower([(0.0, 0.0), (1.0, 0.0)], 0.0)
    assert follower.length_m == 1.0
    assert follower.remaining_m(Pose2D(0.25, 0.1, 0.0)) == pytest.approx(0.75 + 0.1)
    assert follower.command(Pose2D(0.4, 0.0, 0.0)).vx_m_s > 0
    assert follower.progress_m == pytest.approx(0.4)
    assert follower.command(Pose2D(0.995, 0.005, 0.01)) == Twist()
    assert follower.done
    assert follower.command(Pose2D(0.5, 0.0, 0.0)) == Twist()
    assert follower.remaining_m(Pose2D(1.0, 0.0, 0.0)) == pytest.approx(0.0)


def test_past_the_goal_it_comes_back() -> None:
    follower = PathFollower([(0.0, 0.0), (1.0, 0.0)], math.pi / 2)
    command = follower.command(Pose2D(1.1, 0.02, math.pi / 2))
    # Facing the map's +y, the map's -x (back to the goal) is the body's +y (its left).
    assert command.vy_m_s > 0.0 and abs(command.vx_m_s) < 0.25 * command.vy_m_s
    run = drive(follower, Pose2D(1.1, 0.02, math.pi / 2))
    assert follower.done and math.hypot(run.final.x_m - 1.0, run.final.y_m) <= 0.02


def test_a_one_point_path_only_holds_the_position_and_the_yaw_asked() -> None:
    follower = PathFollower([(0.0, 0.0)], math.pi / 2)
    run = drive(follower, Pose2D(0.0, 0.0, 0.0))
    assert follower.done
    assert math.hypot(run.final.x_m, run.final.y_m) <= 0.02
    assert abs(wrap_rad(run.final.yaw_rad - math.pi / 2)) <= 0.035
    assert PathFollower([(0.0, 0.0)], None).command(Pose2D(0.0, 0.01, 2.0)) == Twist()


def walled_room() -> OccupancyGrid:
    """A 4 x 2 m room (5 cm cells), walled."""
    log_odds = np.full((40, 80), -CLAMP_LOG_ODDS)
    log_odds[[0, -1], :] = CLAMP_LOG_ODDS
    log_odds[:, [0, -1]] = CLAMP_LOG_ODDS
    return OccupancyGrid(GridSpec(0.0, 0.0, 0.05, 80, 40), log_odds)


def box_outline(lo: Point, hi: Point, step_m: float = 0.02) -> np.ndarray:
    """Lidar returns off the faces of a box lo..hi (map frame)."""
    xs = np.arange(lo[0], hi[0] + 1e-9, step_m)
    ys = np.arange(lo[1], hi[1] + 1e-9, step_m)
    return np.concatenate([np.stack([xs, np.full_like(xs, y)], 1) for y in (lo[1], hi[1])]
                          + [np.stack([np.full_like(ys, x), ys], 1) for x in (lo[0], hi[0])])


def to_base(points: np.ndarray, pose: Pose2D) -> np.ndarray:
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    d = points - [pose.x_m, pose.y_m]
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def test_a_box_that_appears_on_the_path_is_driven_round_without_touching_it() -> None:
    radius = 0.2
    static = Costmap.from_grid(walled_room(), radius)
    start, goal = (0.5, 1.0), (3.5, 1.0)
    path = plan_path(static, start, goal)
    assert len(path) == 2  # straight through the empty room
    lo, hi = (2.0, 0.85), (2.3, 1.15)
    chassis = Chassis(Pose2D(*start, 0.0))
    follower = PathFollower(path, 0.0)
    replanned = stopped_for = 0
    for _ in range(int(40 * RATE_HZ)):
        pose = chassis.pose
        command = follower.command(pose)
        if pose.x_m >= 1.0:  # the box is there from now on: seen in every scan
            returns = box_outline(lo, hi)
            if blocked(to_base(returns, pose), command, radius):
                stopped_for += 1
                command = Twist()
            live = static.with_obstacles(returns)
            if any(not live.cell_free(*p) for p in follower_path_ahead(path, pose)):
                path = plan_path(live, (pose.x_m, pose.y_m), goal)
                follower = PathFollower(path, 0.0)
                replanned += 1
                command = follower.command(pose)
        chassis.step(command, 1.0 / RATE_HZ)
        gap = math.hypot(max(lo[0] - chassis.pose.x_m, 0, chassis.pose.x_m - hi[0]),
                         max(lo[1] - chassis.pose.y_m, 0, chassis.pose.y_m - hi[1]))
        assert gap >= radius, f"the disc touched the box at {chassis.pose}"
        if follower.done and chassis.twist.is_zero:
            break
    assert replanned == 1 and stopped_for == 0  # round it in time, never up against it
    assert follower.done
    assert math.hypot(chassis.pose.x_m - goal[0], chassis.pose.y_m - goal[1]) <= 0.02


def follower_path_ahead(path: list[Point], pose: Pose2D, step_m: float = 0.02) -> list[Point]:
    """Points every 2 cm along the path (a re-plan is due when one is no longer free)."""
    out = []
    for a, b in itertools.pairwise(path):
        n = max(1, math.ceil(math.dist(a, b) / step_m))
        out += [(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
                for t in np.linspace(0, 1, n + 1)]
    return [p for p in out if math.dist(p, (pose.x_m, pose.y_m)) > 0.05]


# ---------------------------------------------------------------------- the guard

def test_a_return_straight_ahead_blocks_driving_forward_and_one_behind_does_not() -> None:
    forward = Twist(0.25, 0.0, 0.0)
    assert blocked(np.array([[0.4, 0.0]]), forward, 0.2)
    assert not blocked(np.array([[-0.3, 0.0]]), forward, 0.2)
    # In 1 s at 0.25 m/s the disc's front comes to 0.45 m, and the margin is 0.05 m.
    assert blocked(np.array([[0.48, 0.0]]), forward, 0.2)
    assert not blocked(np.array([[0.52, 0.0]]), forward, 0.2)
    assert blocked(np.array([[0.52, 0.0]]), forward, 0.2, margin_m=0.1)
    assert not blocked(np.array([[0.52, 0.0]]), forward, 0.2, horizon_s=0.5, margin_m=0.1)
    assert not blocked(np.array([[0.4, 0.0]]), Twist(0.0, 0.0, 1.0), 0.2)  # turning on the spot
    assert blocked(np.array([[0.0, 0.4]]), Twist(0.0, 0.25, 0.0), 0.2)  # sideways, to the left
    assert not blocked(np.zeros((0, 2)), forward, 0.2)


def test_a_base_already_close_may_still_back_away() -> None:
    wall = np.array([[0.22, y] for y in np.linspace(-0.3, 0.3, 31)])
    assert blocked(wall, Twist(0.05, 0.0, 0.0), 0.2)
    assert not blocked(wall, Twist(-0.1, 0.0, 0.0), 0.2)
    assert not blocked(wall, Twist(-0.1, 0.1, 0.5), 0.2)


def test_the_sweep_follows_the_twist_as_the_base_turns() -> None:
    twist = Twist(0.2, 0.1, 0.8)
    centres = sweep_m(twist, 1.5, step_m=0.01)
    pose = Pose2D()
    n = 3000
    for _ in range(n):
        pose = pose.moved_by(twist.vx_m_s * 1.5 / n, twist.vy_m_s * 1.5 / n,
                             twist.wz_rad_s * 1.5 / n)
    assert centres[-1] == pytest.approx([pose.x_m, pose.y_m], abs=1e-6)
    steps = np.hypot(*np.diff(np.vstack([[0.0, 0.0], centres]), axis=0).T)
    assert steps.max() <= 0.01 + 1e-12


coords = st.floats(-1.5, 1.5)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(coords, coords), min_size=1, max_size=20),
       st.tuples(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4), st.floats(-2.0, 2.0)),
       st.floats(0.1, 0.3), st.floats(0.1, 2.0), st.floats(0.0, 0.2))
def test_blocked_exactly_when_a_swept_disc_comes_within_the_margin_of_a_return(
        points: list[Point], velocity: tuple[float, float, float], radius: float,
        horizon: float, margin: float) -> None:
    twist = Twist(*velocity)
    centres = sweep_m(twist, horizon)
    moving = twist.vx_m_s != 0.0 or twist.vy_m_s != 0.0
    expected = moving and any(
        math.dist(c, q) < radius + margin and math.dist(c, q) < math.hypot(*q)
        for c in centres for q in points)
    assert blocked(np.array(points), twist, radius, horizon, margin) == expected


# ---------------------------------------------------------------------- settings

@pytest.mark.parametrize(("changes", "message"), [
    ({"max_speed_m_s": 0}, r"max_speed_m_s = 0 m/s is out of range 0\.01\.\.2 m/s"),
    ({"lookahead_m": 5}, r"lookahead_m = 5 m is out of range 0\.02\.\.3 m"),
    ({"goal_tolerance_m": math.nan}, r"goal_tolerance_m must be a number, got nan"),
    ({"yaw_tolerance_rad": -0.1}, r"yaw_tolerance_rad = -0\.1 rad is out of range"),
    ({"min_speed_m_s": 0.3}, r"min_speed_m_s = 0\.3 m/s is above max_speed_m_s = 0\.25 m/s"),
])
def test_bad_follower_settings_are_refused_by_name_and_range(
        changes: dict[str, float], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        FollowerSettings(**changes)


def test_settings_within_a_chassis_keep_to_its_limits() -> None:
    fast = FollowerSettings(max_speed_m_s=1.0, max_yaw_rate_rad_s=5.0, max_accel_m_s2=3.0)
    inside = fast.within(CHASSIS)
    assert inside.max_speed_m_s == CHASSIS.max_speed_m_s
    assert inside.max_yaw_rate_rad_s == CHASSIS.max_yaw_rate_rad_s
    assert inside.max_accel_m_s2 == CHASSIS.max_accel_m_s2 / 2
    assert FollowerSettings().within(CHASSIS) == FollowerSettings()


@pytest.mark.parametrize(("path", "yaw", "message"), [
    ([], 0.0, r"a path of shape \(0,\): it must be one or more finite \(x, y\) points"),
    ([(0.0, math.inf)], 0.0, r"a path of shape \(1, 2\)"),
    ([(0.0, 0.0)], math.nan, r"goal_yaw_rad = nan; it must be a finite angle"),
])
def test_a_bad_path_or_yaw_is_refused(path: list[Point], yaw: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        PathFollower(path, yaw)


def test_a_holonomic_base_turning_as_it_goes_down_a_narrow_corridor_is_not_blocked() -> None:
    # Walls 0.275 m each side, the base backing out at 0.25 m/s while it turns round: held
    # in the body that twist is an arc into a wall; a holonomic follower keeps it straight.
    along = np.arange(-1.0, 1.0, 0.01)
    walls = np.concatenate([np.column_stack([along, np.full_like(along, side)])
                            for side in (0.275, -0.275)])
    twist = Twist(-0.25, 0.0, 1.2)
    assert blocked(walls, twist, 0.2)
    assert not blocked(walls, twist, 0.2, holonomic=True)
    assert blocked(walls, Twist(0.0, 0.25, 1.2), 0.2, holonomic=True)  # sideways into one


def test_a_jamb_passed_beside_is_given_the_passing_margin_a_wall_ahead_the_full_one() -> None:
    ahead = Twist(0.2, 0.0, 0.0)  # 0.2 m in the next second
    jambs = np.array([[0.1, 0.24], [0.1, -0.24]])  # a door 0.48 m wide, passed through
    assert blocked(jambs, ahead, 0.2, holonomic=True)  # within 5 cm as it passes
    assert not blocked(jambs, ahead, 0.2, holonomic=True, passing_margin_m=0.02)
    wall = np.array([[0.44, 0.0]])  # 0.24 m past where the second ends: still coming on
    assert blocked(wall, ahead, 0.2, holonomic=True, passing_margin_m=0.02)
    farther = wall + np.array([0.02, 0.0])
    assert not blocked(farther, ahead, 0.2, holonomic=True, passing_margin_m=0.02)
    with pytest.raises(ConfigError, match="passing_margin_m"):
        blocked(jambs, ahead, 0.2, passing_margin_m=-0.01)
