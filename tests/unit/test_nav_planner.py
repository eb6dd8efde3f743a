"""The costmap and the planner: free cells, clearance, paths that keep the disc clear."""

from __future__ import annotations

import itertools
import math
from collections import deque

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from busarm.errors import ConfigError
from busarm.nav.costmap import Costmap
from busarm.nav.grid import CLAMP_LOG_ODDS, GridSpec, OccupancyGrid
from busarm.nav.planner import NoPath, path_length_m, plan_path, segment_cells

RES_M = 0.05
OCCUPIED, FREE, UNKNOWN = CLAMP_LOG_ODDS, -CLAMP_LOG_ODDS, 0.0
Rect = tuple[int, int, int, int]


def room(width: int, height: int, rects: list[Rect] = (), value: float = OCCUPIED,
         walls: bool = True) -> OccupancyGrid:
    """A floor of ``width`` x ``height`` cells (RES_M), walled, with rectangles (row,
    col, rows, cols) of ``value`` on it."""
    log_odds = np.full((height, width), FREE)
    if walls:
        log_odds[[0, -1], :] = OCCUPIED
        log_odds[:, [0, -1]] = OCCUPIED
    for r, c, h, w in rects:
        log_odds[r:r + h, c:c + w] = value
    return OccupancyGrid(GridSpec(0.0, 0.0, RES_M, width, height), log_odds)


def brute_obstacle(grid: OccupancyGrid) -> npt.NDArray[np.bool_]:
    return grid.log_odds >= 0.0  # occupied or unknown


def brute_clearance(grid: OccupancyGrid, x_m: float, y_m: float) -> float:
    """Distance from a point to the nearest obstacle square or the grid's edge, by hand."""
    s = grid.spec
    edge = min(x_m, s.width * RES_M - x_m, y_m, s.height * RES_M - y_m)
    rows, cols = np.nonzero(brute_obstacle(grid))
    if len(rows) == 0:
        return max(edge, 0.0)
    gx = np.maximum(np.abs(x_m - (cols + 0.5) * RES_M) - RES_M / 2, 0.0)
    gy = np.maximum(np.abs(y_m - (rows + 0.5) * RES_M) - RES_M / 2, 0.0)
    return max(min(float(np.hypot(gx, gy).min()), edge), 0.0)


def brute_free(grid: OccupancyGrid, radius_m: float) -> npt.NDArray[np.bool_]:
    """Cells every point of which is at least the radius from every obstacle square and
    from the grid's edge: square-to-square distances, cell by cell."""
    h, w = grid.log_odds.shape
    rows, cols = np.mgrid[0:h, 0:w]
    orows, ocols = np.nonzero(brute_obstacle(grid))
    edge = RES_M * np.minimum(np.minimum(rows, h - 1 - rows), np.minimum(cols, w - 1 - cols))
    nearest = edge.astype(np.float64)
    if len(orows):
        dr = np.maximum(np.abs(rows[..., None] - orows) - 1, 0)
        dc = np.maximum(np.abs(cols[..., None] - ocols) - 1, 0)
        nearest = np.minimum(nearest, RES_M * np.hypot(dr, dc).min(axis=-1))
    return nearest >= radius_m - 1e-9


def reachable(free: npt.NDArray[np.bool_], a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Breadth-first search over free cells, 8-connected."""
    seen = {a}
    todo = deque([a])
    while todo:
        r, c = todo.popleft()
        if (r, c) == b:
            return True
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                n = (r + dr, c + dc)
                if (0 <= n[0] < free.shape[0] and 0 <= n[1] < free.shape[1] and free[n]
                        and n not in seen):
                    seen.add(n)
                    todo.append(n)
    return False


def path_clearances(grid: OccupancyGrid, path: list[tuple[float, float]]) -> list[float]:
    """The clearance at points every 5 mm along the path (every vertex included)."""
    out = []
    for a, b in itertools.pairwise(path):
        n = max(1, math.ceil(math.dist(a, b) / 0.005))
        for t in np.linspace(0.0, 1.0, n + 1):
            out.append(brute_clearance(grid, a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])))
    return out


blocks = st.tuples(st.integers(0, 23), st.integers(0, 23), st.integers(1, 8), st.integers(1, 8))
walls = st.one_of(st.tuples(st.integers(0, 23), st.integers(0, 23), st.integers(1, 2),
                            st.integers(6, 24)),
                  st.tuples(st.integers(0, 23), st.integers(0, 23), st.integers(6, 24),
                            st.integers(1, 2)))
# A wall right across the room with a doorway (0..8 cells wide) in it, or none.
partitions = st.one_of(st.none(), st.tuples(st.booleans(), st.integers(4, 19),
                                            st.integers(0, 23), st.integers(0, 8)))
rects = st.lists(st.one_of(blocks, walls), max_size=6)
kinds = st.lists(st.sampled_from([OCCUPIED, UNKNOWN]), min_size=6, max_size=6)


def random_room(boxes: list[Rect], values: list[float],
                partition: tuple[bool, int, int, int] | None = None) -> OccupancyGrid:
    grid = room(24, 24, walls=False)
    for (r, c, h, w), value in zip(boxes, values, strict=False):
        grid.log_odds[r:r + h, c:c + w] = value
    if partition is not None:
        across, at, door, door_width = partition
        line = np.full(24, OCCUPIED)
        line[door:door + door_width] = FREE
        if across:
            grid.log_odds[at, :] = line
        else:
            grid.log_odds[:, at] = line
    return grid


@settings(max_examples=60, deadline=None)
@given(rects, kinds, st.sampled_from([0.06, 0.1, 0.15]))
def test_free_cells_are_those_where_the_disc_fits_anywhere_in_them(
        boxes: list[Rect], values: list[float], radius_m: float) -> None:
    grid = random_room(boxes, values)
    costmap = Costmap.from_grid(grid, radius_m)
    assert (costmap.free == brute_free(grid, radius_m)).all()
    assert np.isinf(costmap.cost[~costmap.free]).all()
    assert (costmap.cost[costmap.free] >= 0).all()


@settings(max_examples=60, deadline=None)
@given(rects, kinds, st.floats(-0.1, 1.3), st.floats(-0.1, 1.3))
def test_clearance_is_the_distance_to_the_nearest_obstacle_square(
        boxes: list[Rect], values: list[float], x_m: float, y_m: float) -> None:
    grid = random_room(boxes, values)
    costmap = Costmap.from_grid(grid, 0.1)
    assert costmap.clearance_m(x_m, y_m) == pytest.approx(brute_clearance(grid, x_m, y_m),
                                                          abs=1e-9)
    assert costmap.is_free(x_m, y_m) == (brute_clearance(grid, x_m, y_m) >= 0.1)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(rects, kinds, partitions, st.sampled_from([0.06, 0.1, 0.15]), st.integers(0, 10_000),
       st.integers(0, 10_000), st.tuples(st.floats(0.01, 0.99), st.floats(0.01, 0.99)),
       st.tuples(st.floats(0.01, 0.99), st.floats(0.01, 0.99)))
def test_a_path_keeps_the_disc_clear_and_exists_exactly_when_a_route_does(
        boxes: list[Rect], values: list[float], partition: tuple[bool, int, int, int] | None,
        radius_m: float, i: int, j: int, start_in: tuple[float, float],
        goal_in: tuple[float, float]) -> None:
    grid = random_room(boxes, values, partition)
    free = brute_free(grid, radius_m)
    cells = np.argwhere(free)
    if len(cells) == 0:
        with pytest.raises(NoPath, match="the goal is"):
            plan_path(Costmap.from_grid(grid, radius_m), (0.6, 0.6), (0.6, 0.6))
        return
    (sr, sc), (gr, gc) = cells[i % len(cells)], cells[j % len(cells)]
    start = ((sc + start_in[0]) * RES_M, (sr + start_in[1]) * RES_M)
    goal = ((gc + goal_in[0]) * RES_M, (gr + goal_in[1]) * RES_M)
    costmap = Costmap.from_grid(grid, radius_m)
    if not reachable(free, (int(sr), int(sc)), (int(gr), int(gc))):
        event("no route")
        with pytest.raises(NoPath, match="no route") as caught:
            plan_path(costmap, start, goal)
        assert caught.value.reason == "no_route"
        return
    event("a route")
    path = plan_path(costmap, start, goal)
    assert path[0] == start and path[-1] == goal
    assert min(path_clearances(grid, path)) >= radius_m - 1e-9


@settings(max_examples=40, deadline=None)
@given(rects, kinds, partitions, st.sampled_from([0.06, 0.1]), st.integers(0, 10_000),
       st.integers(0, 10_000))
def test_reachable_cells_are_those_a_breadth_first_search_reaches(
        boxes: list[Rect], values: list[float], partition: tuple[bool, int, int, int] | None,
        radius_m: float, i: int, j: int) -> None:
    grid = random_room(boxes, values, partition)
    costmap = Costmap.from_grid(grid, radius_m)
    cells = np.argwhere(costmap.free)
    if len(cells) == 0:
        assert not costmap.reachable(0.6, 0.6).any()
        return
    (sr, sc), (gr, gc) = cells[i % len(cells)], cells[j % len(cells)]
    reach = costmap.reachable((sc + 0.5) * RES_M, (sr + 0.5) * RES_M)
    assert reach[sr, sc] and not (reach & ~costmap.free).any()
    assert reach[gr, gc] == reachable(costmap.free, (int(sr), int(sc)), (int(gr), int(gc)))


def test_the_path_keeps_away_from_walls_where_there_is_room_and_has_few_waypoints() -> None:
    # A 3 x 2 m room with a pillar in the middle of the way.
    grid = room(60, 40, [(14, 27, 12, 6)])
    costmap = Costmap.from_grid(grid, 0.2, inflation_m=0.3)
    path = plan_path(costmap, (0.4, 1.0), (2.6, 1.0))
    assert 3 <= len(path) <= 8  # of some 50 cells: it bends along the gap's middle
    # Around the pillar with room to spare: the gaps beside it are 0.65 m, the disc 0.2 m.
    assert min(path_clearances(grid, path)) >= 0.28
    assert path_length_m(path) < 2.2 + 0.5


def test_a_start_too_near_a_wall_first_leaves_it() -> None:
    grid = room(60, 40)
    costmap = Costmap.from_grid(grid, 0.2)
    start, goal = (0.17, 0.6), (0.5, 1.7)  # 0.12 m from the wall's face: the disc overlaps it
    assert not costmap.is_free(*start) and not costmap.cell_free(*start)
    path = plan_path(costmap, start, goal)
    assert path[0] == start and path[-1] == goal
    clear = path_clearances(grid, path)
    # Away from the wall until the disc is clear of it, and clear of it from then on.
    out = next(i for i, c in enumerate(clear) if c >= 0.2 - 1e-9)
    assert all(b >= a - 1e-9 for a, b in itertools.pairwise(clear[:out + 1]))
    assert min(clear[out:]) >= 0.2 - 1e-9
    assert out * 0.005 < 0.15  # it leaves the shortest way, not along the wall


def test_no_path_says_which_end_is_wrong_and_why() -> None:
    grid = room(60, 40, [(0, 30, 40, 2)])  # a wall across the room: two halves
    costmap = Costmap.from_grid(grid, 0.2)
    with pytest.raises(NoPath) as caught:
        plan_path(costmap, (0.5, 1.0), (2.5, 1.0))
    assert caught.value.reason == "no_route"
    assert str(caught.value) == ("no path from (0.500, 1.000) m to (2.500, 1.000) m: no route "
                                 "between them keeps the robot's disc (radius 0.2 m) clear of "
                                 "obstacles")
    with pytest.raises(NoPath) as caught:
        plan_path(costmap, (0.5, 1.0), (1.52, 1.01))
    assert caught.value.reason == "goal_blocked"
    assert str(caught.value) == ("no path from (0.500, 1.000) m to (1.520, 1.010) m: the goal "
                                 "is in an obstacle; the robot's disc (radius 0.2 m) does not "
                                 "fit there (the nearest place with room for it is (1.275, "
                                 "1.025) m)")
    with pytest.raises(NoPath, match=r"the goal is 0\.100 m from an obstacle.*nearest place "
                                     r"with room for it is \(0\.275, 1\.025\) m"):
        plan_path(costmap, (0.5, 1.0), (0.15, 1.01))
    with pytest.raises(NoPath, match=r"the goal is outside the map \(x 0\.\.3 m, y 0\.\.2 m\)"):
        plan_path(costmap, (0.5, 1.0), (3.5, 1.0))
    with pytest.raises(NoPath, match="the start is outside the map") as caught:
        plan_path(costmap, (-0.5, 1.0), (0.5, 1.0))
    assert caught.value.reason == "start_outside"


def test_a_start_boxed_in_is_told_apart_from_no_route() -> None:
    # A pen of 0.35 m inside: the disc (0.4 m across) fits nowhere in it.
    grid = room(60, 40, [(10, 10, 1, 9), (18, 10, 1, 9), (10, 10, 9, 1), (10, 18, 9, 1)])
    costmap = Costmap.from_grid(grid, 0.2)
    with pytest.raises(NoPath, match="the start is boxed in") as caught:
        plan_path(costmap, (0.725, 0.725), (2.5, 1.0))
    assert caught.value.reason == "start_boxed_in"


def test_live_obstacles_make_a_new_costmap_and_leave_the_static_one() -> None:
    grid = room(60, 40)
    static = Costmap.from_grid(grid, 0.2)
    live = static.with_obstacles(np.array([[1.52, 1.01], [9.0, 9.0]]))  # one beyond the map
    assert static.is_free(1.5, 1.0) and not live.is_free(1.5, 1.0)
    assert live.clearance_m(1.5, 1.25) == pytest.approx(0.2)
    assert static.obstacle.sum() + 1 == live.obstacle.sum()
    path = plan_path(live, (0.5, 1.0), (2.5, 1.0))
    assert min(brute_clearance_to(path, (1.5, 1.0), (1.55, 1.05))) >= 0.2 - 1e-9


def brute_clearance_to(path: list[tuple[float, float]], lo: tuple[float, float],
                       hi: tuple[float, float]) -> list[float]:
    """Distances from points every 5 mm along the path to the rectangle lo..hi."""
    out = []
    for a, b in itertools.pairwise(path):
        for t in np.linspace(0, 1, max(2, math.ceil(math.dist(a, b) / 0.005))):
            x, y = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
            out.append(math.hypot(max(lo[0] - x, 0, x - hi[0]), max(lo[1] - y, 0, y - hi[1])))
    return out


def test_nearest_free_is_the_point_itself_or_the_nearest_free_cell_within_reach() -> None:
    costmap = Costmap.from_grid(room(60, 40), 0.2)
    assert costmap.nearest_free(1.0, 1.0) == (1.0, 1.0)
    assert costmap.nearest_free(0.1, 1.01) == pytest.approx((0.275, 1.025))
    assert costmap.nearest_free(0.1, 1.01, max_m=0.1) is None
    with pytest.raises(ConfigError, match=r"max_m = -1 m is out of range 0\.\.100 m"):
        costmap.nearest_free(0.1, 1.0, max_m=-1)


def test_segment_cells_are_every_cell_the_segment_crosses() -> None:
    costmap = Costmap.from_grid(room(20, 20, walls=False), 0.06)
    rows, cols, lengths = segment_cells(costmap, (0.01, 0.01), (0.09, 0.04))
    assert list(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 0), (0, 1)]
    assert lengths.sum() == pytest.approx(math.hypot(0.08, 0.03))
    # Through a corner exactly: the two cells it only touches are not claimed.
    rows, cols, _ = segment_cells(costmap, (0.025, 0.025), (0.075, 0.075))
    assert list(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 0), (1, 1)]


@pytest.mark.parametrize(("radius", "inflation", "message"), [
    (0, 0.3, r"robot_radius_m = 0 m is out of range 0\.01\.\.2 m"),
    (0.2, -0.1, r"inflation_m = -0\.1 m is out of range 0\.\.5 m"),
    (math.nan, 0.3, r"robot_radius_m must be a number, got nan"),
])
def test_bad_costmap_settings_are_refused(radius: float, inflation: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        Costmap.from_grid(room(10, 10), radius, inflation)


def test_a_start_or_goal_that_is_not_a_point_is_refused() -> None:
    costmap = Costmap.from_grid(room(60, 40), 0.2)
    with pytest.raises(ConfigError, match=r"goal = \(nan, 1\.0\); it must be \(x, y\) in metres"):
        plan_path(costmap, (0.5, 1.0), (math.nan, 1.0))
