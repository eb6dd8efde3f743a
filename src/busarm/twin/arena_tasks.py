"""Mobile jobs set up in a twin's arena, as a person would set them up in a room.

For navigation transport a person writes a points file: where to stand to pick (in front
of the block) and where to put it. Here those points come from the arena (which the code
under test never reads): ``transport_points`` picks a floor block and a clear spot, and
gives both stands in the map's frame (the frame of the pose the map was started from).
"""

from __future__ import annotations

import math
import random
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.nav.grid import OccupancyGrid
from busarm.nav.mapping import compose, inverse, transform_points
from busarm.nav.points import WORK_AHEAD_M, NamedPoint, NamedPoints
from busarm.nav.scan_match import OCCUPIED_P
from busarm.twin.arena import ROBOT_RADIUS_M, Arena, Room
from busarm.twin.arena_gen import random_arena
from busarm.twin.footprints import Footprint

if TYPE_CHECKING:
    from busarm.base.base import Base
    from busarm.twin.twin import Twin

__all__ = [
    "CLEAR_M",
    "DIRECTIONS",
    "MIN_TRIP_M",
    "STANDOFF_M",
    "WALL_CLEAR_M",
    "FloatArray",
    "free_pose",
    "map_in_arena",
    "start_pose",
    "transport_arena",
    "transport_points",
    "true_map_surfaces",
    "twin_map_origin",
    "twin_transport_points",
]


FloatArray = npt.NDArray[np.float64]
STANDOFF_M = WORK_AHEAD_M
"""A pick or place stand is this far behind the block's spot (the arm reaches ahead)."""
CLEAR_M = 0.08
"""A stand keeps the base's disc this far from everything the arena has."""
MIN_TRIP_M = 1.0
WALL_CLEAR_M = 0.5
"""A place spot keeps this far from inner walls (a person does not put things down in a
doorway's or a corridor's way: the base keeps off a spot, blocks lie there)."""
DIRECTIONS = 24
FIT_CELLS, FIT_CLIP_M = 600, 0.3
"""``map_in_arena``: the cells fitted (evenly taken), and the farthest a cell counts."""


def transport_arena(seed: int) -> Arena:
    """A seeded arena for transport: its tables, boxes and tape, and one block on the
    floor to fetch (the others stand on the tables)."""
    return random_arena(seed, floor_blocks=1)


def start_pose(arena: Arena) -> Pose2D:
    s = arena.start
    return Pose2D(s.x_m, s.y_m, math.radians(s.yaw_deg))


def _footprints(arena: Arena, skip_block: int | None) -> list[Footprint]:
    out = [s.footprint() for s in (*arena.fixed, *arena.boxes)]
    out += [b.footprint() for i, b in enumerate(arena.blocks) if b.on is None and i != skip_block]
    return out


def _clear(arena: Arena, things: list[Footprint], x_m: float, y_m: float, radius_m: float
           ) -> bool:
    r = arena.room
    if not (r.x_min_m + radius_m <= x_m <= r.x_max_m - radius_m
            and r.y_min_m + radius_m <= y_m <= r.y_max_m - radius_m):
        return False
    return all(f.distance_from_mm(x_m * 1000, y_m * 1000) >= radius_m * 1000 for f in things)


def _stand(arena: Arena, things: list[Footprint], spot: tuple[float, float],
           rng: random.Random) -> Pose2D | None:
    """A pose STANDOFF_M behind ``spot``, facing it, with the base's disc clear."""
    first = rng.uniform(0, 2 * math.pi)
    for k in range(DIRECTIONS):
        a = first + 2 * math.pi * k / DIRECTIONS
        x, y = spot[0] - STANDOFF_M * math.cos(a), spot[1] - STANDOFF_M * math.sin(a)
        if _clear(arena, things, x, y, ROBOT_RADIUS_M + CLEAR_M):
            return Pose2D(x, y, a)
    return None


def transport_points(arena: Arena, map_origin: Pose2D | None = None, seed: int = 0, *,
                     place_within: Room | None = None, min_trip_m: float = MIN_TRIP_M
                     ) -> tuple[NamedPoints, int, tuple[float, float]]:
    """Points ``pick`` (facing the first floor block) and ``place`` (facing a clear spot
    in ``place_within``, default anywhere, at least ``min_trip_m`` away) in the map's
    frame (``map_origin``: the arena pose the map's origin is at; default the arena's
    start); also the block's index and the place spot (arena frame), for checking the
    outcome."""
    rng = random.Random(seed)
    floor = [i for i, b in enumerate(arena.blocks) if b.on is None]
    if not floor:
        raise ConfigError(f"{arena.name}: no block on the floor to fetch")
    index = floor[0]
    block = arena.blocks[index]
    things = _footprints(arena, index)
    pick = _stand(arena, things, (block.x_m, block.y_m), rng)
    if pick is None:
        raise ConfigError(f"{arena.name}: no room to stand in front of block {index}")
    things_and_block = [*things, block.footprint(),
                        Footprint.disc(pick.x_m * 1000, pick.y_m * 1000, 2000 * ROBOT_RADIUS_M)]
    area = place_within or arena.room
    for _ in range(2000):
        x = rng.uniform(area.x_min_m, area.x_max_m)
        y = rng.uniform(area.y_min_m, area.y_max_m)
        if math.dist((x, y), (block.x_m, block.y_m)) < min_trip_m or not _clear(
                arena, things_and_block, x, y, 0.06) or any(
                w.footprint().distance_from_mm(x * 1000, y * 1000) < WALL_CLEAR_M * 1000
                for w in arena.walls):
            continue
        place = _stand(arena, things_and_block, (x, y), rng)
        if place is not None:
            break
    else:
        raise ConfigError(f"{arena.name}: no clear spot to put the block")
    origin = map_origin if map_origin is not None else start_pose(arena)
    to_map = inverse(origin)
    points = NamedPoints(f"transport in {arena.name}", {
        "pick": NamedPoint("pick", compose(to_map, pick)),
        "place": NamedPoint("place", compose(to_map, place))}, source=f"{arena.name} points")
    return points, index, (x, y)


def twin_map_origin(twin: Twin, base: Base) -> Pose2D:
    """Where (arena frame) the origin of a map ``base`` builds from now on is: a map's
    frame is the odometry's (busarm.nav.mapping.MapBuilder), so its origin is the base's
    true pose less its odometry pose. (The arena's start only while the odometry has
    counted nothing: not after a job has driven, nor quite after the twin has settled.)"""
    assert twin.mobile is not None, "a twin with a mobile base"
    with twin.lock:
        here = twin.mobile.pose(twin.data)
    return compose(here, inverse(base.odometry().pose))


def twin_transport_points(twin: Twin, base: Base) -> NamedPoints:
    """The transport points a person would write for the twin's arena
    (``transport_points``), in the frame of a map ``base`` builds from now on: take them
    before exploring."""
    if twin.arena is None:
        raise ConfigError("the twin stands in no arena: transport's points come from one")
    return transport_points(twin.arena, twin_map_origin(twin, base))[0]


def free_pose(arena: Arena, rng: random.Random, clear_m: float = 0.35,
              away_from: tuple[float, float] | None = None, away_m: float = 1.0) -> Pose2D:
    """A pose (arena frame) where the base's disc keeps ``clear_m`` from everything, at
    least ``away_m`` from ``away_from``: where a person puts the robot down."""
    things = _footprints(arena, None)
    for _ in range(5000):
        x = rng.uniform(arena.room.x_min_m, arena.room.x_max_m)
        y = rng.uniform(arena.room.y_min_m, arena.room.y_max_m)
        if away_from is not None and math.dist((x, y), away_from) < away_m:
            continue
        if _clear(arena, things, x, y, clear_m):
            return Pose2D(x, y, rng.uniform(-math.pi, math.pi))
    raise ConfigError(f"{arena.name}: no free place for the robot")


def true_map_surfaces(arena: Arena, origin: Pose2D, points_m: npt.ArrayLike) -> FloatArray:
    """For points in the map frame (the map's origin at arena pose ``origin``): the distance
    (m) to the nearest surface the Lidar sees (walls, tables, boxes): a map's accuracy."""
    x, y = transform_points(origin, points_m).T
    r = arena.room
    out = np.minimum.reduce([np.abs(x - r.x_min_m), np.abs(x - r.x_max_m),
                             np.abs(y - r.y_min_m), np.abs(y - r.y_max_m)])
    for solid in (*arena.fixed, *arena.boxes):
        f = solid.footprint()
        d = np.array([f.distance_from_mm(a * 1000, b * 1000) for a, b in zip(x, y, strict=True)])
        out = np.minimum(out, d / 1000)
    return np.asarray(out, dtype=np.float64)


def map_in_arena(arena: Arena, grid: OccupancyGrid, origin: Pose2D) -> Pose2D:
    """Where (arena frame) a map's origin truly is: ``origin`` (the pose it was begun
    from) corrected by the rigid shift and turn that lay its occupied cells best on the
    true surfaces. A map is its own frame: one built with a degree's turn in it is still
    right for a robot localised and taught on it, so its localisation is judged there."""
    from scipy.optimize import minimize

    rows, cols = np.nonzero(grid.probability >= OCCUPIED_P)
    if len(rows) == 0:
        return origin
    cells = grid.spec.centres(rows, cols)
    cells = cells[:: max(1, len(cells) // FIT_CELLS)]

    def misfit(v: FloatArray) -> float:
        at = compose(origin, Pose2D(float(v[0]), float(v[1]), float(v[2])))
        return float(np.mean(np.minimum(true_map_surfaces(arena, at, cells), FIT_CLIP_M)))

    start = np.array([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [0.0, 0.05, 0.0], [0.0, 0.0, 0.02]])
    best = minimize(misfit, np.zeros(3), method="Nelder-Mead",
                    options={"xatol": 1e-4, "fatol": 1e-7, "initial_simplex": start})
    return compose(origin, Pose2D(float(best.x[0]), float(best.x[1]), float(best.x[2])))
