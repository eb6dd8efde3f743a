"""A path for the base across a costmap: minimum cost over free cells, then straightened.

The search is Dijkstra's over the grid's free cells, 8-connected (a diagonal step through
a shared corner is safe: both cells' closures keep the disc clear), in scipy's compiled
csgraph rather than a Python A*: a whole room's grid is searched in milliseconds. A step
costs its length times (1 + the mean inflation cost of its two cells), so the path keeps
away from walls where there is room. The cell path is then shortcut greedily: a straight
segment replaces steps when every cell it crosses (found exactly, not sampled) is free
and it costs no more than the steps it replaces. A start whose cell is not free (the
base drifted near a wall) may first leave through the cells under its own disc, which are
evidently empty since the robot stands there.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import numpy.typing as npt

from busarm.errors import BusArmError, ConfigError
from busarm.nav.costmap import Costmap, FloatArray

__all__ = [
    "ESCAPE_COST",
    "NoPath",
    "Point",
    "path_length_m",
    "plan_path",
    "segment_cells",
    "segment_cost",
    "shortcut",
]


Point = tuple[float, float]

ESCAPE_COST = 10.0
"""The extra cost per metre of a step through a non-free cell under the start's disc (ten
times that through an obstacle cell there: unknown, as under a robot that has not seen
its own footprint): a start that is not free leaves by the shortest way out."""
_STEPS = ((0, 1), (1, 0), (1, 1), (1, -1))
"""Half the 8-neighbourhood: the graph is undirected."""


class NoPath(BusArmError):
    """No way for the base from the start to the goal; the message names both and why.

    ``reason``: ``"start_outside"``, ``"goal_outside"``, ``"goal_blocked"`` (the goal is
    too near an obstacle for the robot's disc), ``"start_boxed_in"`` (no free cell can be
    reached from the start) or ``"no_route"``.
    """

    def __init__(self, message: str, reason: str) -> None:
        super().__init__(message)
        self.reason = reason


def plan_path(costmap: Costmap, start: Point, goal: Point) -> list[Point]:
    """Waypoints (m, map frame) from ``start`` to ``goal``, both included, along which the
    robot's disc stays clear of every obstacle (after first leaving the start's cell if
    that is not free); NoPath if there is none."""
    for name, point in (("start", start), ("goal", goal)):
        if len(point) != 2 or not all(math.isfinite(v) for v in point):
            raise ConfigError(f"{name} = {point!r}; it must be (x, y) in metres, finite")
    spec = costmap.spec
    (sr, gr), (sc, gc) = spec.cells([start, goal])
    inside = spec.inside(np.array([sr, gr]), np.array([sc, gc]))
    where = _where(start, goal)
    extent = (f"x {spec.origin_x_m:g}..{spec.origin_x_m + spec.width * spec.resolution_m:g} m, "
              f"y {spec.origin_y_m:g}..{spec.origin_y_m + spec.height * spec.resolution_m:g} m")
    if not inside[0]:
        raise NoPath(f"{where}: the start is outside the map ({extent})", "start_outside")
    if not inside[1]:
        raise NoPath(f"{where}: the goal is outside the map ({extent})", "goal_outside")
    if not costmap.free[gr, gc]:
        raise NoPath(f"{where}: {_goal_blocked(costmap, goal)}", "goal_blocked")
    cost = costmap.cost.copy()
    if not costmap.free[sr, sc]:
        escape = _escape_cells(costmap, start)
        cost[escape] = np.where(costmap.obstacle[escape], 10.0 * ESCAPE_COST, ESCAPE_COST)
    cells = _cheapest_cells(cost, spec.resolution_m, (int(sr), int(sc)), (int(gr), int(gc)))
    if cells is None:
        if not costmap.free[sr, sc] and not _reaches_free(costmap, cost, (int(sr), int(sc))):
            raise NoPath(f"{where}: the start is boxed in (no free cell, where the robot's "
                         f"disc of radius {costmap.robot_radius_m:g} m fits, can be reached "
                         "from it)", "start_boxed_in")
        raise NoPath(f"{where}: no route between them keeps the robot's disc (radius "
                     f"{costmap.robot_radius_m:g} m) clear of obstacles", "no_route")
    centres = spec.centres(cells[:, 0], cells[:, 1])
    points = [start, *((float(x), float(y)) for x, y in centres), goal]
    return shortcut(costmap, cost, _deduplicated(points))


def path_length_m(path: list[Point]) -> float:
    """The length (m) of a polyline."""
    return sum(math.dist(a, b) for a, b in itertools.pairwise(path))


def segment_cells(costmap: Costmap, a: Point, b: Point
                  ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64], FloatArray]:
    """The cells (rows, cols) the segment a-b passes through, exactly (every boundary
    it crosses), with the length (m) of it inside each."""
    s = costmap.spec
    ua = np.array([(a[0] - s.origin_x_m) / s.resolution_m, (a[1] - s.origin_y_m) / s.resolution_m])
    ub = np.array([(b[0] - s.origin_x_m) / s.resolution_m, (b[1] - s.origin_y_m) / s.resolution_m])
    d = ub - ua
    ts = [np.array([0.0, 1.0])]
    for axis in (0, 1):
        if d[axis] != 0.0:
            lo, hi = sorted((ua[axis], ub[axis]))
            lines = np.arange(math.floor(lo) + 1, math.ceil(hi))
            ts.append((lines - ua[axis]) / d[axis])
    t = np.unique(np.clip(np.concatenate(ts), 0.0, 1.0))
    # One crossing, not two, where the line meets a cell corner (rounding splits it, and
    # a sliver between would claim a cell the line only touches).
    t = t[np.concatenate([[True], np.diff(t) > 1e-9])]
    if len(t) < 2:  # a point: its own cell
        t = np.array([0.0, 1.0])
    t[-1] = 1.0
    mid = (t[:-1] + t[1:]) / 2.0
    u = ua[None, :] + mid[:, None] * d[None, :]
    lengths = np.diff(t) * math.dist(a, b)
    return (np.floor(u[:, 1]).astype(np.int64), np.floor(u[:, 0]).astype(np.int64), lengths)


def segment_cost(costmap: Costmap, cost: FloatArray, a: Point, b: Point) -> float:
    """The cost of the straight segment a-b: each piece's length times (1 + its cell's
    cost); inf if it crosses a cell of infinite cost or leaves the grid."""
    rows, cols, lengths = segment_cells(costmap, a, b)
    if not costmap.spec.inside(rows, cols).all():
        return math.inf
    return float(np.sum(lengths * (1.0 + cost[rows, cols])))


def shortcut(costmap: Costmap, cost: FloatArray, points: list[Point]) -> list[Point]:
    """``points`` with steps replaced by straight segments wherever one crosses only
    cells of finite cost and costs no more than the steps it replaces."""
    if len(points) <= 2:
        return list(points)
    steps = [segment_cost(costmap, cost, a, b) for a, b in itertools.pairwise(points)]
    total = np.concatenate([[0.0], np.cumsum(steps)])
    out = [points[0]]
    i = 0
    while i < len(points) - 1:
        j = i + 1
        for k in range(i + 2, len(points)):
            along = total[k] - total[i]
            if segment_cost(costmap, cost, points[i], points[k]) > along * (1 + 1e-9):
                break  # blocked or dearer: the farther ones seldom come back
            j = k
        out.append(points[j])
        i = j
    return out


def _where(start: Point, goal: Point) -> str:
    return (f"no path from ({start[0]:.3f}, {start[1]:.3f}) m to "
            f"({goal[0]:.3f}, {goal[1]:.3f}) m")


def _goal_blocked(costmap: Costmap, goal: Point) -> str:
    clearance = costmap.clearance_m(*goal)
    near = costmap.nearest_free(*goal)
    hint = ("no place within 0.5 m has room for it" if near is None else
            f"the nearest place with room for it is ({near[0]:.3f}, {near[1]:.3f}) m")
    what = "in an obstacle" if clearance <= 0.0 else f"{clearance:.3f} m from an obstacle"
    return (f"the goal is {what}; the robot's disc (radius {costmap.robot_radius_m:g} m) "
            f"does not fit there ({hint})")


def _escape_cells(costmap: Costmap, start: Point) -> npt.NDArray[np.bool_]:
    """Cells that are not free under the robot's disc at ``start`` (their centres within
its radius and a cell's diagonal: the zone always borders the cells around it)."""
    s = costmap.spec
    h, w = s.height, s.width
    rows, cols = np.mgrid[0:h, 0:w]
    centres = s.centres(rows, cols)
    under = np.hypot(centres[..., 0] - start[0],
                     centres[..., 1] - start[1]) <= (costmap.robot_radius_m
                                                     + s.resolution_m * math.sqrt(2.0))
    out: npt.NDArray[np.bool_] = under & ~costmap.free
    return out


def _graph(cost: FloatArray, resolution_m: float) -> object:
    """The undirected 8-connected graph of the cells of finite cost (a sparse matrix)."""
    from scipy.sparse import coo_matrix

    h, w = cost.shape
    index = np.arange(h * w).reshape(h, w)
    heads, tails, weights = [], [], []
    for dr, dc in _STEPS:
        a = (slice(0, h - dr), slice(max(0, -dc), w - max(0, dc)))
        b = (slice(dr, h), slice(max(0, dc), w - max(0, -dc)))
        ok = np.isfinite(cost[a]) & np.isfinite(cost[b])
        heads.append(index[a][ok])
        tails.append(index[b][ok])
        length_m = resolution_m * math.hypot(dr, dc)
        weights.append(length_m * (1.0 + (cost[a][ok] + cost[b][ok]) / 2.0))
    return coo_matrix((np.concatenate(weights), (np.concatenate(heads), np.concatenate(tails))),
                      shape=(h * w, h * w)).tocsr()


def _search(cost: FloatArray, resolution_m: float, start: tuple[int, int]
            ) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    from scipy.sparse.csgraph import dijkstra

    w = cost.shape[1]
    dist, pred = dijkstra(_graph(cost, resolution_m), directed=False,
                          indices=start[0] * w + start[1], return_predecessors=True)
    return np.asarray(dist, dtype=np.float64), np.asarray(pred, dtype=np.int64)


def _cheapest_cells(cost: FloatArray, resolution_m: float, start: tuple[int, int],
                    goal: tuple[int, int]) -> npt.NDArray[np.int64] | None:
    """The cells (rows, cols), start to goal, of the cheapest way; None if none."""
    w = cost.shape[1]
    if start == goal:
        return np.array([start], dtype=np.int64)
    _, pred = _search(cost, resolution_m, start)
    at = goal[0] * w + goal[1]
    if pred[at] < 0:
        return None
    chain = [at]
    while chain[-1] != start[0] * w + start[1]:
        chain.append(int(pred[chain[-1]]))
    flat = np.array(chain[::-1], dtype=np.int64)
    return np.stack([flat // w, flat % w], axis=1)


def _reaches_free(costmap: Costmap, cost: FloatArray, start: tuple[int, int]) -> bool:
    dist, _ = _search(cost, costmap.spec.resolution_m, start)
    return bool((np.isfinite(dist.reshape(costmap.free.shape)) & costmap.free).any())


def _deduplicated(points: list[Point]) -> list[Point]:
    out = [points[0]]
    for p in points[1:]:
        if math.dist(p, out[-1]) > 1e-9:
            out.append(p)
    if len(out) == 1:  # start and goal at one point: still a path of two
        out.append(points[-1])
    return out
