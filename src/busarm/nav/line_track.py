"""Following a floor line: where the line runs under the base, and how to steer onto it.

The camera sees the line from some way ahead of the base, never under it. Rather than
extrapolating each picture back (a small error in the line's angle becomes a large one
under the base), ``LineTracker`` remembers the line's points in the odometry's frame as
they were seen and reads the line under the base from them once the base has driven up
to them: a weighted least-squares quadratic through the points around the base (in the
frame of their main direction, so any heading works) gives the line's offset from the
base's centre, its direction and its curvature there. Until the line has been seen
under the base (just started, or just found again), ``nearest`` is the point to head
for. Odometry over the few tens of centimetres between seeing a point and reaching it
drifts by well under a millimetre.

``LineController`` steers a holonomic (mecanum) base: it slides sideways onto the line
(no turn needed to correct an offset), turns to the line's direction with the line's
curvature as feed-forward, and slows where the line bends.

``obstacle_ahead`` is the vendor's stop rule (anything within +-45 deg ahead and closer
than 0.4 m) narrowed to what is in the base's way: a return beside the path (a table
along the line) does not stop it.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.base.kinematics import Twist
from busarm.base.odometry import Pose2D
from busarm.nav.mapping import transform_points
from busarm.units import check_range

__all__ = [
    "FIT_RADIUS_M",
    "MEMORY_M",
    "MIN_POINTS",
    "NEW_M",
    "UNDER_M",
    "WEIGHT_M",
    "FloatArray",
    "LineController",
    "LineTracker",
    "LineUnderBase",
    "in_stop_range",
    "obstacle_ahead",
]


FloatArray = npt.NDArray[np.float64]
MEMORY_M = 1.0
"""Line points farther than this from the base are forgotten."""
FIT_RADIUS_M = 0.2
"""The line is fitted through the points this close to the base's centre..."""
WEIGHT_M = 0.1
"""... each weighted by its distance (a Gaussian of this sigma): a bend farther off does
not pull the fit under the base."""
UNDER_M = 0.06
"""The line is known under the base when a point this close to its centre was seen."""
MIN_POINTS = 6
NEW_M = 0.05
"""A sighting's point this far from every remembered one is the line seen anew."""


@dataclass(frozen=True)
class LineUnderBase:
    lateral_m: float
    """The line's offset from the base's centre, + to the left."""
    heading_rad: float
    """The line's direction relative to the base's x axis (+ counter-clockwise)."""
    curvature_1_m: float
    """+ bending to the left."""
    points: int
    """How many line points the fit used."""


def _from_frame(points: FloatArray, pose: Pose2D) -> FloatArray:
    """Points in the outer frame, seen from ``pose``."""
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    d = points - np.array([pose.x_m, pose.y_m])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


class LineTracker:
    """The line's points seen so far (odometry frame), and the line under the base."""

    def __init__(self) -> None:
        self._seen: deque[FloatArray] = deque(maxlen=200)
        self._last: tuple[Pose2D, FloatArray] | None = None
        """``points``' answer for the odometry it was last asked at (a step asks several
        times at one pose; ``add`` and ``forget`` drop it)."""

    def add(self, points_base_m: npt.ArrayLike, odometry: Pose2D) -> None:
        """Remember a sighting's line points (base frame, taken at ``odometry``)."""
        p = np.asarray(points_base_m, dtype=np.float64).reshape(-1, 2)
        if len(p):
            self._seen.append(transform_points(odometry, p))
            self._last = None

    def forget(self) -> None:
        self._seen.clear()
        self._last = None

    def points(self, odometry: Pose2D) -> FloatArray:
        """The remembered line points within MEMORY_M, in the base's frame now (older ones
        are forgotten); read-only."""
        if self._last is not None and self._last[0] == odometry:
            return self._last[1]
        out: FloatArray = np.zeros((0, 2))
        if self._seen:
            here = np.array([odometry.x_m, odometry.y_m])
            every = np.concatenate(list(self._seen))
            near = np.hypot(*(every - here).T) <= MEMORY_M
            ends = np.cumsum([len(p) for p in self._seen])[:-1]
            kept = (p[k] for p, k in zip(self._seen, np.split(near, ends), strict=True))
            self._seen = deque((p for p in kept if len(p)), maxlen=self._seen.maxlen)
            if self._seen:
                out = _from_frame(np.concatenate(list(self._seen)), odometry)
        out.flags.writeable = False
        self._last = (odometry, out)
        return out

    def under(self, odometry: Pose2D) -> LineUnderBase | None:
        """The line at the base's centre now, or None when it has not been seen there
        (nothing within UNDER_M of the centre: steer to ``nearest`` first)."""
        local = self.points(odometry)
        distance = np.hypot(local[:, 0], local[:, 1])
        near = local[distance <= FIT_RADIUS_M]
        if len(near) < MIN_POINTS or distance.min() > UNDER_M:
            return None
        return _fit(near, np.exp(-0.5 * np.square(distance[distance <= FIT_RADIUS_M] / WEIGHT_M)))

    def unseen(self, points_base_m: npt.ArrayLike, odometry: Pose2D, *,
               beyond_m: float = NEW_M) -> int:
        """How many of a sighting's points (base frame, taken at ``odometry``) lie farther
        than ``beyond_m`` from every line point remembered: the line seen anew, not the
        part already followed."""
        p = np.asarray(points_base_m, dtype=np.float64).reshape(-1, 2)
        if not self._seen or not len(p):
            return len(p)
        known = np.concatenate(list(self._seen))
        seen = transform_points(odometry, p)
        gaps = np.hypot(seen[:, None, 0] - known[None, :, 0], seen[:, None, 1] - known[None, :, 1])
        return int(np.count_nonzero(gaps.min(axis=1) > beyond_m))

    def nearest(self, odometry: Pose2D) -> tuple[float, float] | None:
        """The nearest remembered line point (base frame), to steer to before the line
        is known under the base."""
        local = self.points(odometry)
        if not len(local):
            return None
        k = int(np.argmin(np.hypot(local[:, 0], local[:, 1])))
        return float(local[k, 0]), float(local[k, 1])


def _fit(points: FloatArray, weights: FloatArray) -> LineUnderBase | None:
    """A quadratic through the points in the frame of their main direction (any heading
    works); its point nearest the origin, direction and curvature there."""
    centre = np.average(points, axis=0, weights=weights)
    d = points - centre
    cov = (d * weights[:, None]).T @ d
    direction = np.linalg.eigh(cov)[1][:, -1]
    if direction[0] < 0:
        direction = -direction  # along the line the way the base faces
    normal = np.array([-direction[1], direction[0]])
    u, v = d @ direction, d @ normal
    if np.ptp(u) < 0.03:
        return None
    degree = 2 if np.ptp(u) >= 0.1 else 1
    poly = np.poly1d(np.polyfit(u, v, degree, w=np.sqrt(weights)))
    slope_of = poly.deriv(1)
    # The curve's point nearest the base's centre (origin): Newton on (p(u) - o) . p'(u).
    o = -centre
    o_u, o_v = float(o @ direction), float(o @ normal)
    t = o_u
    for _ in range(5):
        f = (t - o_u) + (poly(t) - o_v) * slope_of(t)
        df = 1 + slope_of(t) ** 2 + (poly(t) - o_v) * (poly.deriv(2)(t) if degree == 2 else 0.0)
        t -= f / df if abs(df) > 1e-9 else 0.0
    foot = centre + t * direction + float(poly(t)) * normal
    tangent = direction + float(slope_of(t)) * normal
    tangent /= np.linalg.norm(tangent)
    left = np.array([-tangent[1], tangent[0]])
    bend = float(poly.deriv(2)(t)) if degree == 2 else 0.0
    curvature = bend / (1 + float(slope_of(t)) ** 2) ** 1.5
    return LineUnderBase(float(foot @ left), math.atan2(tangent[1], tangent[0]), curvature,
                         len(points))


@dataclass(frozen=True)
class LineController:
    """Steering onto the line for a holonomic base."""

    speed_m_s: float = 0.15
    lateral_gain_1_s: float = 2.5
    heading_gain_1_s: float = 3.0
    max_sideways_m_s: float = 0.12
    max_yaw_rate_rad_s: float = 1.5
    slow_curvature_1_m: float = 3.0
    """At this curvature (a 0.33 m radius) the speed is halved."""

    def __post_init__(self) -> None:
        check_range("speed_m_s", self.speed_m_s, 0.01, 0.5, "m/s")
        check_range("lateral_gain_1_s", self.lateral_gain_1_s, 0.0, 20.0, "1/s")
        check_range("heading_gain_1_s", self.heading_gain_1_s, 0.0, 20.0, "1/s")

    def command(self, line: LineUnderBase) -> Twist:
        slow = 1.0 / (1.0 + abs(line.curvature_1_m) / self.slow_curvature_1_m)
        slow *= max(0.2, math.cos(line.heading_rad)) * max(0.3, 1.0 - abs(line.lateral_m) / 0.1)
        vx = self.speed_m_s * slow
        vy = float(np.clip(self.lateral_gain_1_s * line.lateral_m, -self.max_sideways_m_s,
                           self.max_sideways_m_s))
        wz = self.heading_gain_1_s * line.heading_rad + vx * line.curvature_1_m
        wz = float(np.clip(wz, -self.max_yaw_rate_rad_s, self.max_yaw_rate_rad_s))
        return Twist(vx, vy, wz)

    def toward(self, point_m: tuple[float, float]) -> Twist:
        """Slowly to a line point (base frame) before the line is known under the base."""
        x, y = point_m
        distance = math.hypot(x, y)
        if distance < 1e-6:
            return Twist()
        speed = min(self.speed_m_s / 2, distance)
        return Twist(speed * x / distance, speed * y / distance, 0.0)


def in_stop_range(points_base_m: FloatArray, *, range_m: float = 0.4,
                  front_m: float = 0.15) -> npt.NDArray[np.bool_]:
    """Which returns (base frame, (N, 2)) are near enough to stop for (``obstacle_ahead``'s
    reach: ``range_m`` past the base's front, ``front_m`` ahead of its centre)."""
    p = points_base_m
    return np.asarray(np.hypot(p[:, 0], p[:, 1]) <= range_m + front_m)


def obstacle_ahead(points_base_m: npt.ArrayLike, *, range_m: float = 0.4,
                   half_angle_deg: float = 45.0, corridor_half_m: float = 0.2,
                   front_m: float = 0.15) -> tuple[float, float] | None:
    """The nearest return (base frame) within ``half_angle_deg`` of straight ahead, closer
    than ``range_m`` to the base's front (``front_m`` ahead of its centre), and inside
    the corridor the base sweeps (``corridor_half_m`` each side); None if there is none."""
    p = np.asarray(points_base_m, dtype=np.float64).reshape(-1, 2)
    if not len(p):
        return None
    ahead = p[:, 0] > 0
    angle_ok = np.abs(np.degrees(np.arctan2(p[:, 1], p[:, 0]))) <= half_angle_deg
    close = in_stop_range(p, range_m=range_m, front_m=front_m)
    inside = np.abs(p[:, 1]) <= corridor_half_m
    hits = p[ahead & angle_ok & close & inside]
    if not len(hits):
        return None
    nearest = hits[int(np.argmin(hits[:, 0]))]
    return float(nearest[0]), float(nearest[1])
