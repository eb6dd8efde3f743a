"""Building a map by exploring: drive to the nearest open frontier until none is left.

``build_map(robot)`` reads the Lidar scan after scan (busarm.apps.navigation.sensing), places
each where it fits what is mapped so far (busarm.nav.mapping.MapBuilder: the odometry's
drift stops at the map), and drives the base to the frontier (busarm.nav.frontiers) it
can reach soonest, on the inflated map (busarm.nav.costmap, planner, follower), checking
every scan that the next second of motion touches nothing (``blocked``). It stops when no
frontier is left, or at the time limit; the map's frame is where the base started.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from busarm.apps.navigation.sensing import ScanReader, SensedScan
from busarm.base.odometry import Pose2D
from busarm.lidar.scan import to_points
from busarm.nav.costmap import Costmap
from busarm.nav.follower import PASSING_MARGIN_M, FollowerSettings, PathFollower, blocked
from busarm.nav.frontiers import (
    PLAN_GAP_CELLS,
    SEEN_FREE_P,
    Frontier,
    find_frontiers,
    gaps_filled,
)
from busarm.nav.grid import GridSpec, OccupancyGrid, cropped
from busarm.nav.mapping import MapBuilder, compose, inverse
from busarm.nav.planner import NoPath, plan_path
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.units import check_range

__all__ = [
    "ARRIVED_M",
    "EXPLORE_FREE_P",
    "EXPLORE_SPEED_M_S",
    "EXPLORE_YAW_RATE_RAD_S",
    "EXTENT_M",
    "FRONTIER_MARGIN_M",
    "PROGRESS_S",
    "REPLAN_S",
    "RESOLUTION_M",
    "ROBOT_RADIUS_M",
    "Explorer",
    "MapRun",
    "build_map",
]


ROBOT_RADIUS_M = 0.2
"""The base's footprint as a disc (the JetAuto with its wheels is about 0.3 x 0.25 m)."""
EXTENT_M = 32.0
"""The canvas a map is built on (centred on the start), cropped to what was seen: a room
reaching 16 m from where the map was begun (the A1 sees 12 m); planning works on the part
seen so far."""
RESOLUTION_M = 0.025
REPLAN_S = 3.0
EXPLORE_SPEED_M_S = 0.2
EXPLORE_YAW_RATE_RAD_S = 0.6
"""Turning slower keeps scans sharp (de-skewing corrects the rest)."""
ARRIVED_M = 0.25
"""A frontier target this close to the base is reached (whatever remains of it cannot be
seen from here): it is not chosen again."""
PROGRESS_S = 10.0
"""A line of progress every this much of exploring."""
TARGET_SEARCH_M = 0.6
"""A frontier's target: a place the base can reach within this of it."""
FRONTIER_MARGIN_M = 0.5
"""Unknown floor kept round what is seen, where frontiers and plans are worked out."""
EXPLORE_FREE_P = SEEN_FREE_P


@dataclass
class MapRun:
    """A finished exploration: the map (cropped), where the base was, and why it stopped."""

    grid: OccupancyGrid
    poses: list[Pose2D] = field(default_factory=list)
    """The base's corrected pose at each scan (map frame)."""
    seconds: float = 0.0
    driven_m: float = 0.0
    scans: int = 0
    corrections: int = 0
    finished: str = ""
    """Why it stopped: explored, or the time limit."""
    unreachable: int = 0
    """Frontiers given up on (no route, or blocked)."""

    def summary(self, saved_to: object) -> str:
        """One line for a person: the map's size and the time it took, and where it is."""
        spec = self.grid.spec
        return (f"mapped {spec.width * spec.resolution_m:.1f} x "
                f"{spec.height * spec.resolution_m:.1f} m in {self.seconds:.0f} s "
                f"({saved_to})")


class Explorer:
    """One exploration of the place ``robot`` stands in."""

    def __init__(self, robot: Robot, *, time_limit_s: float = 300.0,
                 resolution_m: float = RESOLUTION_M, min_frontier_m: float = 0.3,
                 on_scan: Callable[[Explorer], None] | None = None,
                 progress: Progress = quiet) -> None:
        check_range("time_limit_s", time_limit_s, 1.0, 7200.0, "s")
        self.reader = ScanReader(robot)
        self.base = self.reader.base
        self.clock = robot.clock
        self.time_limit_s = time_limit_s
        self.min_frontier_m = min_frontier_m
        self.on_scan = on_scan
        self.progress = progress
        self._said_s = 0.0
        half = EXTENT_M / 2
        spec = GridSpec.covering(-half, half, -half, half, resolution_m)
        self.builder = MapBuilder(spec, self.base.config.lidar)
        self.settings = FollowerSettings(max_speed_m_s=EXPLORE_SPEED_M_S,
                                         max_yaw_rate_rad_s=EXPLORE_YAW_RATE_RAD_S,
                                         goal_tolerance_m=0.05).within(self.base.config)
        self.pose = Pose2D()
        self.follower: PathFollower | None = None
        self.goal: tuple[float, float] | None = None
        self.visited: list[tuple[float, float]] = []
        self.unreachable: list[tuple[float, float]] = []
        """Frontier targets given up on: no route, or the way there blocked."""
        self._planned_at_s = -math.inf
        self._began_s = self.clock.now()

    def run(self) -> MapRun:
        """Explore until done; the wheels are stopped whatever happens (on a stop, what
        was explored before it is ``so_far``)."""
        self._began_s = self.clock.now()
        try:
            finished = self._loop(self._began_s)
        finally:
            self.base.stop()
        return self.so_far(finished)

    def so_far(self, finished: str) -> MapRun:
        """The map and the path as they are now, ``finished`` saying why it stopped:
        ``run``'s result, or what a stop (Ctrl+C, a signal, an error) left."""
        run = MapRun(cropped(self.builder.grid), list(self.builder.poses))
        run.seconds = self.clock.now() - self._began_s
        run.driven_m = sum(math.dist((a.x_m, a.y_m), (b.x_m, b.y_m))
                           for a, b in zip(run.poses, run.poses[1:], strict=False))
        run.scans, run.corrections = self.reader.scans, self.builder.corrections
        run.finished, run.unreachable = finished, len(self.unreachable)
        return run

    def _loop(self, start_s: float) -> str:
        while self.clock.now() - start_s < self.time_limit_s:
            sensed = self.reader.read()
            self._place(sensed)
            if self.on_scan is not None:
                self.on_scan(self)
            self._say_how_far(start_s)
            if self._needs_plan() and not self._plan():
                return "explored: no frontier left that the base can reach"
            self._drive(sensed)
        return f"the time limit ({self.time_limit_s:g} s)"

    def _say_how_far(self, start_s: float) -> None:
        """Every ``PROGRESS_S`` of exploring: a line saying how far it has got."""
        explored_s = self.clock.now() - start_s
        if explored_s - self._said_s < PROGRESS_S:
            return
        self._said_s = explored_s
        free = self.builder.grid.probability < SEEN_FREE_P
        floor_m2 = float(np.count_nonzero(free)) * self.builder.grid.spec.resolution_m ** 2
        self.progress(f"explored {explored_s:.0f} s: {self.reader.scans} scans, "
                      f"{floor_m2:.1f} m^2 of floor seen")

    def _place(self, sensed: SensedScan) -> None:
        at_scan = self.builder.add(sensed.bearings_rad, sensed.ranges_m,
                                   sensed.odometry)
        since = compose(inverse(sensed.odometry), sensed.odometry_now)
        self.pose = compose(at_scan, since)

    def _needs_plan(self) -> bool:
        return (self.follower is None or self.follower.done
                or self.clock.now() - self._planned_at_s > REPLAN_S)

    def _plan(self) -> bool:
        """Plan to the best frontier; False when none is left."""
        self._planned_at_s = self.clock.now()
        here = (self.pose.x_m, self.pose.y_m)
        if self.goal is not None and math.dist(self.goal, here) < ARRIVED_M:
            self.visited.append(self.goal)
        seen = cropped(self.builder.grid, FRONTIER_MARGIN_M)
        costmap = Costmap.from_grid(gaps_filled(seen, PLAN_GAP_CELLS), ROBOT_RADIUS_M,
                                    free_below_p=EXPLORE_FREE_P)
        reach = costmap.reachable(*here)
        for frontier in self._candidates(costmap):
            target = _target(costmap, reach, frontier)
            if (target is None or self._given_up_near(target)
                    or math.dist(target, here) < ARRIVED_M):
                continue
            try:
                path = plan_path(costmap, here, target)
            except NoPath:
                self.unreachable.append(target)
                continue
            self.goal, self.follower = target, PathFollower(path, None, self.settings)
            return True
        self.follower = None
        return False

    def _candidates(self, costmap: Costmap) -> list[Frontier]:
        found = find_frontiers(cropped(self.builder.grid, FRONTIER_MARGIN_M),
                               self.min_frontier_m)

        def cost(f: Frontier) -> float:
            # Near ones first; a long frontier is worth a little more travel.
            return math.dist((f.x_m, f.y_m), (self.pose.x_m, self.pose.y_m)) - 0.3 * min(
                f.length_m, 2.0)

        return sorted(found, key=cost)

    def _given_up_near(self, target: tuple[float, float]) -> bool:
        return any(math.dist(target, g) < 0.3 for g in (*self.visited, *self.unreachable))

    def _drive(self, sensed: SensedScan) -> None:
        if self.follower is None:
            self.base.stop()
            return
        command = self.follower.command(self.pose)
        points = to_points(sensed.scan, self.base.config.lidar)
        if blocked(points, command, ROBOT_RADIUS_M, holonomic=True,
                   passing_margin_m=PASSING_MARGIN_M):
            self.base.stop()
            if self.goal is not None:
                self.unreachable.append(self.goal)
            self.follower = None
            return
        self.base.drive(command.vx_m_s, command.vy_m_s, command.wz_rad_s)


def _target(costmap: Costmap, reach: npt.NDArray[np.bool_], frontier: Frontier
            ) -> tuple[float, float] | None:
    """Where to drive to see past ``frontier``: of the cells the base can reach
    (``reach``) within ``TARGET_SEARCH_M`` of the frontier, the one nearest its middle
    (the middle of a room seen through a doorway lies far out in the unknown: the
    doorway is the way to it); None if none is that near."""
    from scipy.spatial import cKDTree

    rows, cols = np.nonzero(reach)
    if not len(rows):
        return None
    cells = costmap.spec.centres(rows, cols).reshape(-1, 2)
    gap, _ = cKDTree(frontier.points_m).query(cells, distance_upper_bound=TARGET_SEARCH_M)
    near = cells[np.isfinite(gap)]
    if not len(near):
        return None
    best = int(np.argmin(np.hypot(near[:, 0] - frontier.x_m, near[:, 1] - frontier.y_m)))
    return float(near[best, 0]), float(near[best, 1])


def build_map(robot: Robot, *, time_limit_s: float = 300.0,
              resolution_m: float = RESOLUTION_M,
              on_scan: Callable[[Explorer], None] | None = None) -> MapRun:
    """Explore the place ``robot`` stands in and return its map (see ``Explorer``)."""
    return Explorer(robot, time_limit_s=time_limit_s, resolution_m=resolution_m,
                    on_scan=on_scan).run()
