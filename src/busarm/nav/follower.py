"""Following a path with the mecanum base, and the guard that stops it short of anything.

``PathFollower.command(pose)`` is holonomic pure pursuit: it translates toward a point
``lookahead_m`` ahead, in the body frame (a mecanum base moves sideways as readily as
forward, so it need not face where it goes), while it turns toward the goal's yaw (or the
path's direction) at the same time. The look-ahead point lies on the tangent of the leg
followed, from the base's foot on it (a point further along a curve would have it run
inside the curve, by lookahead^2 / 2 r); it stops at each corner until the base is within
``corner_cut_m`` of it, so a corner is cut by no more than that. The speed falls before a
corner as the turn needs, and before the goal so as to stop there (``speed <= sqrt(2 a
d)``: never past it). Call it at a steady rate and send the twist to ``Base.drive``,
which keeps it within the chassis's limits.

``blocked(points, twist, ...)`` is the safety check to run on every scan: whether the
robot's disc, going on at ``twist``, would come within a margin of any Lidar return.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np
import numpy.typing as npt

from busarm.base.config import ChassisConfig
from busarm.base.kinematics import Twist
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.errors import ConfigError
from busarm.units import check_range

__all__ = [
    "CORNER_RAD",
    "PASSING_MARGIN_M",
    "YAW_GAIN_PER_S",
    "FloatArray",
    "FollowerSettings",
    "PathFollower",
    "Point",
    "blocked",
    "sweep_m",
]


FloatArray = npt.NDArray[np.float64]
Point = tuple[float, float]

CORNER_RAD = math.radians(20.0)
"""A vertex turning the path by more than this is a corner the look-ahead point stops at."""
YAW_GAIN_PER_S = 2.5
PASSING_MARGIN_M = 0.02
"""What ``blocked`` keeps between the base's disc (it holds the chassis, 0.30 x 0.26 m,
with a centimetre to spare) and a return it passes beside: a 0.6 m doorway leaves 10 cm
of play, more than the path follower needs."""
"""The turn rate asked per radian of heading error (before the rate limits)."""
_RANGES: dict[str, tuple[float, float, str]] = {
    "max_speed_m_s": (0.01, 2.0, "m/s"),
    "max_yaw_rate_rad_s": (0.05, 10.0, "rad/s"),
    "max_accel_m_s2": (0.01, 10.0, "m/s^2"),
    "max_yaw_accel_rad_s2": (0.05, 50.0, "rad/s^2"),
    "lookahead_m": (0.02, 3.0, "m"),
    "goal_tolerance_m": (0.001, 1.0, "m"),
    "yaw_tolerance_rad": (0.001, math.pi, "rad"),
    "slow_radius_m": (0.01, 5.0, "m"),
    "min_speed_m_s": (0.0, 0.5, "m/s"),
    "corner_cut_m": (0.001, 1.0, "m"),
    "reaction_s": (0.0, 1.0, "s"),
}


@dataclass(frozen=True)
class FollowerSettings:
    """How the follower drives: its limits (within the chassis's), its look-ahead and
    when it calls the goal reached."""

    max_speed_m_s: float = 0.25
    max_yaw_rate_rad_s: float = 1.2
    max_accel_m_s2: float = 0.4
    """The deceleration planned for before a corner or the goal (keep it below the
    chassis's own limit: the base's ramp must be able to follow it)."""
    max_yaw_accel_rad_s2: float = 2.0
    lookahead_m: float = 0.25
    goal_tolerance_m: float = 0.02
    yaw_tolerance_rad: float = 0.03
    slow_radius_m: float = 0.3
    """Within this of the goal the speed falls in proportion to the distance left."""
    min_speed_m_s: float = 0.02
    """...but no lower than this (where the deceleration allows it), lest the last
    millimetres take forever."""
    corner_cut_m: float = 0.02
    """How far before a corner the base may turn off toward the next leg."""
    reaction_s: float = 0.0
    """How long a command stands before the next one can change it (the control period:
    a Lidar revolution when it is given a scan at a time). The speed is held to one that
    still stops in time after this much more at it."""

    def __post_init__(self) -> None:
        for f in fields(self):
            lo, hi, unit = _RANGES[f.name]
            check_range(f.name, getattr(self, f.name), lo, hi, unit)
        if self.min_speed_m_s > self.max_speed_m_s:
            raise ConfigError(f"min_speed_m_s = {self.min_speed_m_s:g} m/s is above "
                              f"max_speed_m_s = {self.max_speed_m_s:g} m/s; allowed: "
                              f"0..{self.max_speed_m_s:g} m/s")

    def within(self, chassis: ChassisConfig) -> FollowerSettings:
        """These settings with each limit lowered to the chassis's where that is lower
        (the deceleration to half the chassis's: room for its ramp to follow)."""
        return replace(
            self, max_speed_m_s=min(self.max_speed_m_s, chassis.max_speed_m_s),
            max_yaw_rate_rad_s=min(self.max_yaw_rate_rad_s, chassis.max_yaw_rate_rad_s),
            max_accel_m_s2=min(self.max_accel_m_s2, chassis.max_accel_m_s2 / 2),
            max_yaw_accel_rad_s2=min(self.max_yaw_accel_rad_s2,
                                     chassis.max_yaw_accel_rad_s2 / 2),
            min_speed_m_s=min(self.min_speed_m_s, chassis.max_speed_m_s))


class PathFollower:
    """Drives the base along ``path`` (m, map frame; from a planner) to its last point,
    arriving at ``goal_yaw_rad`` (None: facing along the path's last leg)."""

    def __init__(self, path: list[Point], goal_yaw_rad: float | None = None,
                 settings: FollowerSettings | None = None) -> None:
        self.settings = settings or FollowerSettings()
        points = np.asarray(path, dtype=np.float64)
        if points.ndim != 2 or points.shape[1:] != (2,) or len(points) == 0 \
                or not np.isfinite(points).all():
            raise ConfigError(f"a path of shape {points.shape}: it must be one or more "
                              "finite (x, y) points in metres")
        if goal_yaw_rad is not None and not math.isfinite(goal_yaw_rad):
            raise ConfigError(f"goal_yaw_rad = {goal_yaw_rad!r}; it must be a finite angle "
                              "in radians, or None to face along the path")
        keep = np.concatenate([[True], np.hypot(*np.diff(points, axis=0).T) > 1e-9])
        self._points = points[keep]
        legs = np.diff(self._points, axis=0)
        self._leg_m = np.hypot(legs[:, 0], legs[:, 1])
        self._leg_dir = legs / self._leg_m[:, None] if len(legs) else legs
        self._s_at = np.concatenate([[0.0], np.cumsum(self._leg_m)])
        self.length_m = float(self._s_at[-1])
        """The path's length (m)."""
        self._vertex_s, self._vertex_speed, corner = self._vertices()
        self._stops = np.concatenate([corner, [True]])
        """Per leg: whether its end is a corner or the goal (the look-ahead stops there)."""
        self._goal_yaw = goal_yaw_rad
        self._s = 0.0
        self._done = False

    @property
    def done(self) -> bool:
        """Whether the goal has been reached (within both tolerances); from then on every
        command is to stand still."""
        return self._done

    @property
    def progress_m(self) -> float:
        """How far along the path (m) the base had come at the last command."""
        return self._s

    def remaining_m(self, pose: Pose2D) -> float:
        """The way left (m): from the base back onto the path, then along it to the end."""
        s = self._project(pose)
        x, y = self._at(s)
        return self.length_m - s + math.hypot(pose.x_m - x, pose.y_m - y)

    def to_stop_m(self, pose: Pose2D) -> float:
        """The run ahead (m) of the base at ``pose``, before the follower turns it or
        stops it: back onto the path, then along it to where the path next turns off
        sharply (a corner the look-ahead point stops at) or ends."""
        s = self._project(pose)
        x, y = self._at(s)
        off_m = math.hypot(pose.x_m - x, pose.y_m - y)
        if self.length_m == 0.0:
            return off_m
        ends = self._s_at[1:][self._stops]
        ahead = ends[ends > s + self.settings.corner_cut_m]
        return off_m + (float(ahead[0]) - s if len(ahead) else max(self.length_m - s, 0.0))

    def command(self, pose: Pose2D) -> Twist:
        """The twist (body frame) to drive now, with the base at ``pose`` (map frame)."""
        if self._done:
            return Twist()
        cfg = self.settings
        self._s = self._project(pose)
        gx, gy = self._points[-1]
        to_goal_m = math.hypot(gx - pose.x_m, gy - pose.y_m)
        leg = self._leg()
        target_yaw = self._target_yaw(leg)
        yaw_error = 0.0 if target_yaw is None else wrap_rad(target_yaw - pose.yaw_rad)
        if to_goal_m <= cfg.goal_tolerance_m and abs(yaw_error) <= cfg.yaw_tolerance_rad:
            self._done = True
            return Twist()
        speed = self._speed(pose)
        cx, cy = self._carrot(pose, leg)
        dx, dy = cx - pose.x_m, cy - pose.y_m
        norm = math.hypot(dx, dy)
        if norm > 1e-9:
            c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
            ux, uy = dx / norm, dy / norm
            vx, vy = speed * (c * ux + s * uy), speed * (-s * ux + c * uy)
        else:
            vx = vy = 0.0
        rate = min(cfg.max_yaw_rate_rad_s,
                   math.sqrt(2.0 * cfg.max_yaw_accel_rad_s2 * abs(yaw_error)),
                   YAW_GAIN_PER_S * abs(yaw_error))
        return Twist(vx, vy, math.copysign(rate, yaw_error))

    # ------------------------------------------------------------------ geometry

    def _vertices(self) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
        """Each inner vertex's place along the path (m), the speed (m/s) to pass it at,
        and whether it is a corner (the look-ahead point stops there)."""
        cfg = self.settings
        d = self._leg_dir
        if len(d) < 2:
            return np.zeros(0), np.zeros(0), np.zeros(0, dtype=bool)
        # Named, typed halves: one nested expression of slices costs mypy seconds.
        before: FloatArray = d[:-1]
        after: FloatArray = d[1:]
        cross: FloatArray = before[:, 0] * after[:, 1] - before[:, 1] * after[:, 0]
        turn = np.abs(np.arctan2(cross, np.sum(before * after, axis=1)))
        # Turning the velocity by theta at speed v takes 2 v sin(theta/2) / a; the base
        # strays about v^2 sin^2(theta/2) / a meanwhile: keep that within the corner cut.
        with np.errstate(divide="ignore"):
            speed = np.sqrt(cfg.max_accel_m_s2 * cfg.corner_cut_m) / np.sin(turn / 2.0)
        return self._s_at[1:-1], np.minimum(speed, cfg.max_speed_m_s), turn > CORNER_RAD

    def _project(self, pose: Pose2D) -> float:
        """The base's place along the path (m): the nearest point on the legs near where
        it was, never behind that."""
        if self.length_m == 0.0:
            return 0.0
        p = np.array([pose.x_m, pose.y_m])
        start = self._points[:-1]
        t = np.clip(np.sum((p - start) * self._leg_dir, axis=1), 0.0, self._leg_m)
        near = start + t[:, None] * self._leg_dir
        distance = np.hypot(near[:, 0] - p[0], near[:, 1] - p[1])
        s = self._s_at[:-1] + t
        reach = self._s + self.settings.lookahead_m + 0.5
        window = (self._s_at[1:] >= self._s - 1e-9) & (self._s_at[:-1] <= reach)
        distance = np.where(window, distance, np.inf)
        best = int(np.argmin(distance))
        return max(self._s, float(min(s[best], reach)))

    def _at(self, s: float) -> Point:
        """The path's point ``s`` metres along it."""
        if self.length_m == 0.0:
            return float(self._points[0, 0]), float(self._points[0, 1])
        s = min(max(s, 0.0), self.length_m)
        i = min(int(np.searchsorted(self._s_at, s, side="right")) - 1, len(self._leg_m) - 1)
        x, y = self._points[i] + (s - self._s_at[i]) * self._leg_dir[i]
        return float(x), float(y)

    def _leg(self) -> int:
        """The leg to follow: the one the base is on, or the next once it is within
        ``corner_cut_m`` of the corner between them."""
        if self.length_m == 0.0:
            return -1
        last = len(self._leg_m) - 1
        i = min(int(np.searchsorted(self._s_at, self._s, side="right")) - 1, last)
        if i < last and self._stops[i] and \
                self._s >= self._s_at[i + 1] - self.settings.corner_cut_m:
            i += 1
        return i

    def _carrot(self, pose: Pose2D, leg: int) -> Point:
        """The look-ahead point: ``lookahead_m`` on along the leg's line from the base's
        foot on it (along its tangent, so that a curve is not cut as a chord would), but
        never past the leg's end if that is a corner or the goal."""
        if leg < 0:
            return float(self._points[0, 0]), float(self._points[0, 1])
        a, d = self._points[leg], self._leg_dir[leg]
        along = float(np.dot([pose.x_m - a[0], pose.y_m - a[1]], d))
        reach = along + self.settings.lookahead_m
        if self._stops[leg]:  # past the end (an overshoot): back to it
            reach = min(reach, float(self._leg_m[leg]))
        x, y = a + reach * d
        return float(x), float(y)

    def _speed(self, pose: Pose2D) -> float:
        """The fastest the base may go now: to stop at the goal, to pass each vertex
        ahead no faster than it allows, and slower near the goal."""
        cfg = self.settings
        a, lag = cfg.max_accel_m_s2, cfg.max_accel_m_s2 * cfg.reaction_s
        left_m = self.remaining_m(pose)
        # v t + (v^2 - end^2) / 2a <= d: at v for the reaction time t, then braking at a.
        speed = min(cfg.max_speed_m_s, math.sqrt(lag * lag + 2.0 * a * left_m) - lag)
        ahead = self._vertex_s > self._s
        if ahead.any():
            to_go = self._vertex_s[ahead] - self._s
            speed = min(speed, float(np.min(np.sqrt(
                lag * lag + self._vertex_speed[ahead] ** 2 + 2.0 * a * to_go))) - lag)
        near = max(cfg.max_speed_m_s * left_m / cfg.slow_radius_m, cfg.min_speed_m_s)
        return min(speed, near)

    def _target_yaw(self, leg: int) -> float | None:
        """The goal's yaw, else the direction of the leg followed (None: no path)."""
        if self._goal_yaw is not None or leg < 0:
            return self._goal_yaw
        dx, dy = self._leg_dir[leg]
        return math.atan2(float(dy), float(dx))


def sweep_m(twist: Twist, horizon_s: float, step_m: float = 0.01) -> FloatArray:
    """Where the base's centre will be (its frame now, m) going on at ``twist``: shape
    (K, 2), at even times after now up to ``horizon_s``, consecutive ones at most
    ``step_m`` apart along the way (now itself left out)."""
    check_range("horizon_s", horizon_s, 0.0, 10.0, "s")
    check_range("step_m", step_m, 0.001, 1.0, "m")
    speed = math.hypot(twist.vx_m_s, twist.vy_m_s)
    count = max(1, math.ceil(speed * horizon_s / step_m))
    t = np.arange(1, count + 1) * (horizon_s / count)
    w, vx, vy = twist.wz_rad_s, twist.vx_m_s, twist.vy_m_s
    if abs(w) < 1e-9:
        return np.stack([vx * t, vy * t], axis=1)
    # The body's velocity turns with it: the exact integral of R(w t) (vx, vy).
    s, c = np.sin(w * t), np.cos(w * t)
    return np.stack([(vx * s + vy * (c - 1.0)) / w, (vx * (1.0 - c) + vy * s) / w], axis=1)


def blocked(points_base_m: npt.ArrayLike, twist: Twist, robot_radius_m: float,
            horizon_s: float = 1.0, margin_m: float = 0.05, *, holonomic: bool = False,
            passing_margin_m: float | None = None) -> bool:
    """Whether the robot's disc, going on at ``twist`` for ``horizon_s``, comes within
    ``margin_m`` of any return (shape (N, 2), base frame) at a place nearer to it than it
    is now (so a base already that close may still back away). ``passing_margin_m``
    (default ``margin_m``): the margin to a return the disc passes beside within the
    horizon (nearest to it before the horizon's end: a door's jamb, not a wall ahead).
    ``holonomic``: the translation is held in the world while the base turns (as
    ``PathFollower`` steers a mecanum base), so the disc goes straight; else the twist is
    held in the body and the disc follows its arc."""
    check_range("robot_radius_m", robot_radius_m, 0.01, 2.0, "m")
    check_range("margin_m", margin_m, 0.0, 1.0, "m")
    passing = margin_m if passing_margin_m is None else check_range(
        "passing_margin_m", passing_margin_m, 0.0, 1.0, "m")
    points = np.asarray(points_base_m, dtype=np.float64)
    if points.size == 0:
        return False
    if points.ndim != 2 or points.shape[1] != 2:
        raise ConfigError(f"scan points of shape {points.shape}; they must be (N, 2) in m")
    points = points[np.isfinite(points).all(axis=1)]
    if twist.vx_m_s == 0.0 and twist.vy_m_s == 0.0:
        return False  # turning in place: the disc stays where it is
    centres = sweep_m(Twist(twist.vx_m_s, twist.vy_m_s) if holonomic else twist, horizon_s)
    now_m = np.hypot(points[:, 0], points[:, 1])
    later_m = np.hypot(points[None, :, 0] - centres[:, None, 0],
                       points[None, :, 1] - centres[:, None, 1])
    nearest = np.argmin(later_m, axis=0)
    closest_m = later_m[nearest, np.arange(len(points))]
    reach_m = robot_radius_m + np.where(nearest < len(centres) - 1, passing, margin_m)
    return bool(np.any((closest_m < reach_m) & (closest_m < now_m)))
