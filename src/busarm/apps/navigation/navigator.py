"""Going to a pose on a saved map: localise, plan, follow, and never touch anything.

``Navigator(robot, grid)`` reads the Lidar scan after scan (busarm.apps.navigation.sensing), keeps
a particle filter (busarm.nav.localize) on the map, and drives the base along a path
planned on the inflated map with the scan's returns added (busarm.nav.costmap, planner),
followed holonomically (busarm.nav.follower). Every scan it checks that the next second
of the commanded motion keeps clear of every return (``blocked``): if not, the wheels
stop; it re-plans around the obstacle, or waits for it to go (a person steps away), and
gives up with a clear reason after ``obstacle_wait_s``. Where the scans fit the map
less (``PoseEstimate.matched_share``) it drives slower; where they stop fitting it stands
and finds itself again near where it believed it was, before driving on (``_confident``).
The Lidar going silent, the localisation lost for good or the time running out stop the
base with a NavigationError.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from busarm.apps.navigation.sensing import ScanReader, SensedScan
from busarm.base.kinematics import Twist
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError, NavigationError
from busarm.lidar.scan import to_points
from busarm.nav.costmap import Costmap
from busarm.nav.follower import PASSING_MARGIN_M, FollowerSettings, PathFollower, blocked
from busarm.nav.frontiers import PLAN_GAP_CELLS, SEEN_FREE_P, gaps_filled
from busarm.nav.grid import OccupancyGrid
from busarm.nav.localize import ParticleFilter, PoseEstimate
from busarm.nav.mapping import compose, inverse, transform_points
from busarm.nav.planner import NoPath, plan_path
from busarm.robot import Robot
from busarm.units import check_range

__all__ = [
    "GUARD_MARGIN_M",
    "SETTLE_MAX_M",
    "FloatArray",
    "NavSettings",
    "Navigator",
    "Point",
    "ScanHook",
    "Trip",
]


Point = tuple[float, float]
FloatArray = npt.NDArray[np.float64]
GUARD_MARGIN_M = 0.05
"""The guard keeps the base's disc this far from every return..."""
GUARD_HORIZON_S = 1.0
"""... over this much of the commanded motion ahead (but not past the goal)..."""
NEAR_GOAL_M, NEAR_GOAL_MARGIN_M = 0.3, 0.02
"""... but in the last NEAR_GOAL_M before a goal by a table or a wall, this far (the disc
already holds the chassis, 0.30 x 0.26 m, with a centimetre to spare: goals are taught
where the base stood)."""
SETTLE_MAX_M = 0.1
"""``settle`` closes at most this much by odometry alone (no Lidar check of the path)."""
SLOW_MATCH, SLOW_SHARE = 0.8, 0.5
"""Below this share of a scan's returns on the map, drive at SLOW_SHARE of the speed..."""
LOST_MATCH, LOST_SCANS = 0.5, 3
"""... and below this share for LOST_SCANS scans running, stop and find the pose again."""
RELOCALISE_SIGMA_M, RELOCALISE_SIGMA_RAD, RELOCALISE_S = 0.2, 0.2, 6.0
"""Finding it again: the cloud spread this much about the pose believed, for at most
RELOCALISE_S standing still."""
CONTROL_S = 0.1
"""One command a scan (the A1's revolution): the follower brakes in time after it."""
GOAL_SLOW_M = 0.05
"""The speed falls in proportion to the way left only over this last bit (before it the
braking curve alone: a trip's end was a slow crawl over the last 30 cm)."""
ON_APPROACH_M = 0.05
"""The base within this of the straight way in (across it, and short of its start) is on
it (``go_to``'s ``approach_m``)."""


@dataclass(frozen=True)
class NavSettings:
    robot_radius_m: float = 0.2
    """The base's footprint as a disc."""
    inflation_m: float = 0.3
    max_speed_m_s: float = 0.4
    """At most the chassis's own limit (it is lowered to that), forward or sideways."""
    goal_tolerance_m: float = 0.02
    replan_s: float = 2.0
    obstacle_wait_s: float = 8.0
    """How long an obstacle in the way is waited for before the trip gives up."""
    trip_limit_s: float = 180.0
    localize_limit_s: float = 30.0
    """Global localisation: the longest it may drive about before giving up."""
    wander_speed_m_s: float = 0.15

    def __post_init__(self) -> None:
        check_range("robot_radius_m", self.robot_radius_m, 0.05, 1.0, "m")
        check_range("inflation_m", self.inflation_m, 0.0, 2.0, "m")
        check_range("max_speed_m_s", self.max_speed_m_s, 0.02, 1.0, "m/s")
        check_range("obstacle_wait_s", self.obstacle_wait_s, 0.0, 600.0, "s")
        check_range("trip_limit_s", self.trip_limit_s, 1.0, 3600.0, "s")
        check_range("localize_limit_s", self.localize_limit_s, 1.0, 600.0, "s")


@dataclass
class Trip:
    """One ``go_to``: where it went, how, and whether it arrived."""

    goal: Pose2D
    ok: bool = False
    why: str = ""
    seconds: float = 0.0
    path: list[Pose2D] = field(default_factory=list)
    """The estimated pose at each scan (map frame)."""
    plans: list[list[Point]] = field(default_factory=list)
    plan_cpu_s: list[float] = field(default_factory=list)
    """The CPU time (s, of the planning thread) the planner took for each of ``plans``."""
    obstacle_stops: int = 0
    waited_s: float = 0.0
    relocalised: int = 0
    """How often the scans stopped fitting the map and the pose was found again."""
    via: Pose2D | None = None
    """The pose behind the goal from which the last stretch is driven straight in (None:
    planned to the goal all the way)."""
    on_approach: bool = False
    """Whether the base came onto that straight last stretch."""

    @property
    def driven_m(self) -> float:
        return sum(math.dist((a.x_m, a.y_m), (b.x_m, b.y_m))
                   for a, b in zip(self.path, self.path[1:], strict=False))

    def __repr__(self) -> str:
        outcome = "arrived" if self.ok else f"not arrived ({self.why})" if self.why else "under way"
        return (f"Trip(to {self.goal!r}, {outcome}, {self.seconds:.1f} s, "
                f"{self.driven_m:.2f} m, {len(self.plans)} plan(s), "
                f"{self.obstacle_stops} obstacle stop(s))")


ScanHook = Callable[["Navigator", SensedScan], None]


class Navigator:
    """Localisation, planning and following on ``grid`` for ``robot``'s base and Lidar."""

    def __init__(self, robot: Robot, grid: OccupancyGrid, *,
                 settings: NavSettings | None = None, seed: int = 0,
                 on_scan: ScanHook | None = None) -> None:
        self.settings = settings or NavSettings()
        self.reader = ScanReader(robot)
        self.base = self.reader.base
        self.clock = robot.clock
        self.grid = grid
        self.filter = ParticleFilter(grid, self.base.config.lidar, seed=seed)
        # Unseen gaps between diverging beams are floor, not walls; on a map made now,
        # floor a beam crossed is floor (a file's cells are free, occupied or unknown).
        self.static = Costmap.from_grid(gaps_filled(grid, PLAN_GAP_CELLS),
                                        self.settings.robot_radius_m,
                                        self.settings.inflation_m, free_below_p=SEEN_FREE_P)
        self.on_scan = on_scan
        self.estimate: PoseEstimate | None = None
        self.guess = False
        """The pose is one of several places alike, taken until something else (the
        camera) tells: the filter's, but not claimed known (set by the job that guesses)."""
        self.pose = Pose2D()
        """The base's pose now (map frame): the filter's, carried on by the odometry."""
        self.last_scan: SensedScan | None = None
        self.trips: list[Trip] = []
        self._filter_odometry: Pose2D | None = None
        self._keep_out: FloatArray = np.zeros((0, 2))
        self._approach_keep_out: FloatArray = np.zeros((0, 2))

    # ------------------------------------------------------------------ sensing
    def sense(self) -> SensedScan:
        """Read the next scan and update the pose estimate with it."""
        sensed = self.reader.read()
        if self._filter_odometry is not None:
            self.filter.predict(self._filter_odometry, sensed.odometry)
        self._filter_odometry = sensed.odometry
        self.estimate = self.filter.update(sensed.bearings_rad, sensed.ranges_m)
        since = compose(inverse(sensed.odometry), sensed.odometry_now)
        self.pose = compose(self.estimate.pose, since)
        self.last_scan = sensed
        if self.on_scan is not None:
            self.on_scan(self, sensed)
        return sensed

    def returns_m(self, sensed: SensedScan) -> tuple[FloatArray, FloatArray]:
        """The scan's returns in the base frame and in the map frame (now)."""
        local = to_points(sensed.scan, self.base.config.lidar)
        return local, transform_points(self.pose, local)

    # ------------------------------------------------------------------ localising
    def path_driven(self) -> list[Point]:
        """Where every trip so far went (m, the map's frame): what a person is shown."""
        return [(p.x_m, p.y_m) for trip in self.trips for p in trip.path]

    def latest_plan(self) -> list[Point]:
        """The plan the last trip follows now (m, the map's frame; empty before one)."""
        return list(self.trips[-1].plans[-1]) if self.trips and self.trips[-1].plans else []

    def localize(self, start: Pose2D | None = None, *, wander: bool = True,
                 alike_ok: bool = False) -> PoseEstimate:
        """Find where the base is: near ``start`` if given, else anywhere on the map
        (driving about slowly, clear of everything, until the filter has converged;
        standing still if not ``wander``). ``alike_ok``: a room that looks the same from
        several places returns its estimate (``rivals``, ``alike``: the caller tells
        them apart, as by what the camera sees) instead of a NavigationError."""
        if start is not None:
            self.filter.start_at(start)
        else:
            self.filter.start_anywhere()
        self._filter_odometry = None
        began = self.clock.now()
        settled = 0
        try:
            while True:
                sensed = self.sense()
                assert self.estimate is not None
                settled = settled + 1 if self.estimate.converged else 0
                if settled >= 3:
                    self.base.stop()
                    return self.estimate
                if self.clock.now() - began > self.settings.localize_limit_s:
                    rivals = self.estimate.rivals
                    if rivals and alike_ok:
                        return self.estimate
                    why = (f"the room looks the same from {rivals + 1} places on the map "
                           "(give it a hint: where it stands)" if rivals else
                           "is it the map of this place?")
                    raise NavigationError(
                        f"could not tell where the base is on the map after "
                        f"{self.settings.localize_limit_s:g} s of looking ({why}): the base "
                        "is stopped")
                if start is None and wander:
                    self._wander(sensed)
        finally:
            self.base.stop()

    def _wander(self, sensed: SensedScan) -> None:
        """Drive toward the most open direction, turning slowly (new views for the filter)."""
        local, _ = self.returns_m(sensed)
        bearings = np.arctan2(local[:, 1], local[:, 0])
        ranges = np.hypot(local[:, 0], local[:, 1])
        if not len(ranges):
            return
        best = float(bearings[int(np.argmax(ranges))])
        speed = self.settings.wander_speed_m_s
        twist = Twist(speed * math.cos(best), speed * math.sin(best), 0.4)
        if blocked(local, twist, self.settings.robot_radius_m, holonomic=True):
            twist = Twist(0.0, 0.0, 0.4)
        self.base.drive(twist.vx_m_s, twist.vy_m_s, twist.wz_rad_s)

    # ------------------------------------------------------------------ going
    def go_to(self, goal: Pose2D, *, keep_yaw: bool = True,
              keep_out: Sequence[tuple[float, float, float]] = (), approach_m: float = 0.0,
              approach_keep_out: Sequence[tuple[float, float, float]] | None = None) -> Trip:
        """Drive to ``goal`` (map frame; its heading too if ``keep_yaw``), never over the
        ``keep_out`` discs (x, y, radius in m: where blocks are, which the Lidar does not
        see). ``approach_m``: the last this much is driven straight in along the goal's
        heading, without stopping before it: the way is planned to the pose that far
        behind the goal and on straight; once the base is on that stretch (``Trip.
        on_approach``) the plans are to the goal itself, over ``approach_keep_out``
        (default ``keep_out``). Returns the trip; raises NavigationError (the base
        stopped) if it cannot get there."""
        if not isinstance(goal, Pose2D):
            raise ConfigError(f"go_to: goal = {goal!r}; give a Pose2D(x_m, y_m, yaw_rad) in "
                              "the map's frame")
        check_range("approach_m", approach_m, 0.0, 2.0, "m")
        if self.estimate is None:
            raise NavigationError("the base has not been localised on the map: localize() "
                                  "first")
        trip = Trip(goal)
        if approach_m > 0.0:
            trip.via = compose(goal, Pose2D(-approach_m, 0.0, 0.0))
            self._approach_keep_out = _disc_points(keep_out if approach_keep_out is None
                                                   else approach_keep_out)
        self.trips.append(trip)
        self._keep_out = _disc_points(keep_out)
        began = self.clock.now()
        try:
            self._trip(trip, keep_yaw, began)
        finally:
            self.base.stop()
            trip.seconds = self.clock.now() - began
        return trip

    def _trip(self, trip: Trip, keep_yaw: bool, began: float) -> None:
        s = self.settings
        goal_yaw = trip.goal.yaw_rad if keep_yaw else None
        follower_settings = FollowerSettings(
            max_speed_m_s=s.max_speed_m_s, goal_tolerance_m=s.goal_tolerance_m,
            slow_radius_m=GOAL_SLOW_M, reaction_s=CONTROL_S).within(self.base.config)
        follower: PathFollower | None = None
        planned_at = -math.inf
        blocked_since: float | None = None
        unsure = 0
        while True:
            sensed = self.sense()
            trip.path.append(self.pose)
            relocalised = trip.relocalised
            unsure = self._confident(trip, unsure)
            if trip.relocalised != relocalised:
                planned_at = -math.inf  # found again: a new plan from where it is
            now = self.clock.now()
            if now - began > s.trip_limit_s:
                raise NavigationError(self._where(trip) + f": not there after "
                                      f"{s.trip_limit_s:g} s; the base is stopped")
            local, world = self.returns_m(sensed)
            if follower is None or now - planned_at > s.replan_s:
                self._onto_approach(trip)
                path = self._plan(trip, world)
                if path is not None:
                    follower = PathFollower(path, goal_yaw, follower_settings)
                    planned_at = now
            if follower is None:
                blocked_since = self._wait(trip, blocked_since, now, "no free route")
                continue
            if follower.done:
                trip.ok, trip.why = True, "arrived"
                return
            command = follower.command(self.pose)
            if self._in_the_way(local, command, follower.remaining_m(self.pose),
                                follower.to_stop_m(self.pose)):
                if blocked_since is None:
                    trip.obstacle_stops += 1
                blocked_since = self._wait(trip, blocked_since, now, "something in the way")
                planned_at = -math.inf  # re-plan around it next scan
                continue
            if blocked_since is not None:
                trip.waited_s += now - blocked_since
                blocked_since = None
            assert self.estimate is not None
            k = SLOW_SHARE if self.estimate.matched_share < SLOW_MATCH else 1.0
            self.base.drive(k * command.vx_m_s, k * command.vy_m_s, k * command.wz_rad_s)

    def _in_the_way(self, local: FloatArray, command: Twist, left_m: float,
                    straight_m: float) -> bool:
        """The guard: whether the next ``GUARD_HORIZON_S`` of ``command`` brings the disc
        within the margin of a return (base frame) nearer than it is. It looks no
        farther than the ``straight_m`` ahead before the follower stops at the goal
        (``left_m`` away), or turns off at a corner but never less than the base needs
        to stop from its speed there (past a shallow corner it keeps its speed): a
        wall just past a corner or a goal is no obstacle (the next leg is looked along
        as the base turns onto it; what the disc comes nearest to where it turns or
        stops is passed beside, not driven into)."""
        margin = NEAR_GOAL_MARGIN_M if left_m < NEAR_GOAL_M else GUARD_MARGIN_M
        passing = min(margin, PASSING_MARGIN_M)
        speed = math.hypot(command.vx_m_s, command.vy_m_s)
        horizon = GUARD_HORIZON_S
        # Never less than the base needs to stop from this speed (a command's period, then
        # the chassis's braking): past a shallow corner the follower keeps its speed.
        stop_m = speed * CONTROL_S + speed**2 / (2 * self.base.config.max_accel_m_s2)
        straight_m = max(straight_m, stop_m) if left_m > straight_m else straight_m
        if speed * horizon > straight_m:
            horizon, margin = straight_m / speed, passing
        return blocked(local, command, self.settings.robot_radius_m, horizon_s=horizon,
                       margin_m=margin, holonomic=True, passing_margin_m=passing)

    def _confident(self, trip: Trip, unsure: int) -> int:
        """Count the scans running that fit the map too little; at LOST_SCANS, stop and
        find the pose again near the one believed (NavigationError if it is not found)."""
        assert self.estimate is not None
        if self.estimate.matched_share >= LOST_MATCH:
            return 0
        if unsure + 1 < LOST_SCANS:
            return unsure + 1
        self.base.stop()
        trip.relocalised += 1
        believed = self.pose
        self.filter.start_at(believed, RELOCALISE_SIGMA_M, RELOCALISE_SIGMA_RAD)
        self._filter_odometry = None
        began = self.clock.now()
        while self.clock.now() - began < RELOCALISE_S:
            self.sense()
            if self.estimate.converged and self.estimate.matched_share >= SLOW_MATCH:
                return 0
        raise NavigationError(f"{self._where(trip)}: the scans no longer fit the map near "
                              f"where the base believed it was (at most "
                              f"{self.estimate.matched_share:.0%} of the returns on it for "
                              f"{RELOCALISE_S:g} s standing): the base is stopped")

    def settle(self, goal: Pose2D, tolerance_m: float = 0.01, tolerance_deg: float = 1.0,
               scans: int = 4, tries: int = 2) -> Pose2D:
        """Stand at ``goal`` exactly: standing still, the estimate is refined over
        ``scans`` scans, and what is left is closed by ``move_by`` (the odometry is exact
        over a few centimetres); returns what is left of the error (in the base frame)."""
        left = Pose2D()
        for _ in range(tries + 1):
            self.base.stop()
            for _ in range(scans):
                self.sense()
            left = compose(inverse(self.pose), goal)
            if (math.hypot(left.x_m, left.y_m) <= tolerance_m
                    and abs(left.yaw_deg) <= tolerance_deg):
                break
            if math.hypot(left.x_m, left.y_m) > SETTLE_MAX_M:
                raise NavigationError(
                    f"{self._where(Trip(goal))}: standing {math.hypot(left.x_m, left.y_m):.2f}"
                    f" m off the goal after arriving (more than {SETTLE_MAX_M:g} m, which "
                    "is not closed blind); the base is stopped")
            self.base.move_by(left.x_m, left.y_m, left.yaw_rad)
        return left

    def _onto_approach(self, trip: Trip) -> None:
        """Mark the trip on its straight last stretch once the base has come onto it:
        from then on it is planned to the goal itself, over the approach's keep-outs."""
        if trip.via is None or trip.on_approach:
            return
        rel = self.pose.relative_to(trip.via)
        stretch_m = math.dist((trip.via.x_m, trip.via.y_m), (trip.goal.x_m, trip.goal.y_m))
        if -ON_APPROACH_M <= rel.x_m <= stretch_m and abs(rel.y_m) <= ON_APPROACH_M:
            trip.on_approach = True
            self._keep_out = self._approach_keep_out

    def _plan(self, trip: Trip, world: FloatArray) -> list[Point] | None:
        extra = np.concatenate([world.reshape(-1, 2), self._keep_out])
        costmap = self.static.with_obstacles(extra) if len(extra) else self.static
        here = (self.pose.x_m, self.pose.y_m)
        via = None if trip.on_approach else trip.via
        target = trip.goal if via is None else via
        goal = (target.x_m, target.y_m)
        near = goal
        if not costmap.cell_free(*goal):
            # A goal by a wall, a table or a keep-out spot (a point's own spot is at the
            # disc's edge) may be a shade inside what the map calls free: plan to the
            # nearest free point, then straight on to the goal, the guard watching. Ending
            # at that point instead could leave more than ``settle`` closes blind.
            near = costmap.nearest_free(*goal, SETTLE_MAX_M) or goal
        began = time.thread_time()
        try:
            path = plan_path(costmap, here, near)
        except NoPath:
            return None
        trip.plan_cpu_s.append(time.thread_time() - began)
        if near != goal:
            path.append(goal)
        if via is not None:  # and on, straight in (the follower does not stop there)
            path.append((trip.goal.x_m, trip.goal.y_m))
        trip.plans.append(path)
        return path

    def _wait(self, trip: Trip, since: float | None, now: float, why: str) -> float:
        self.base.stop()
        since = now if since is None else since
        if now - since > self.settings.obstacle_wait_s:
            raise NavigationError(f"{self._where(trip)}: {why} for "
                                  f"{self.settings.obstacle_wait_s:g} s; the base is stopped")
        return since

    def _where(self, trip: Trip) -> str:
        g, p = trip.goal, self.pose
        return (f"going from ({p.x_m:.2f}, {p.y_m:.2f}) m to ({g.x_m:.2f}, {g.y_m:.2f}) m, "
                f"{g.yaw_deg:.0f} deg")


def _disc_points(discs: Sequence[tuple[float, float, float]]) -> FloatArray:
    """Points filling each disc's edge and centre (a costmap inflates them)."""
    out: list[FloatArray] = [np.zeros((0, 2))]
    for x, y, r in discs:
        a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
        out.append(np.column_stack([x + r * np.cos(a), y + r * np.sin(a)]))
        out.append(np.array([[x, y]]))
    return np.concatenate(out)
