"""Seeded arenas: a room, a taped loop with curves, tables along the walls, boxes, blocks.

``random_arena(seed)`` draws the same arena for the same seed. The loop is an oval with a
wobble (two or three bends a lap), no tighter than ``MIN_CURVE_RADIUS_M`` anywhere, and
the robot starts on it facing along it; boxes stand clear of the tape and of each other,
blocks stand on tables and on the floor beside the tape. Counts can be fixed (benchmarks
sweep them).
"""

from __future__ import annotations

import math
import random

import numpy as np

from busarm.errors import ConfigError
from busarm.twin.arena import (
    MAX_THINGS,
    ROBOT_RADIUS_M,
    Arena,
    ArenaBlock,
    FloorLine,
    Room,
    Solid,
    StartPose,
)
from busarm.twin.footprints import Footprint, overlaps
from busarm.twin.scene import COLORS
from busarm.units import check_int_range, listing

__all__ = [
    "LINE_STEP_M",
    "LOOP_MARGIN_M",
    "MIN_CURVE_RADIUS_M",
    "SOLID_TAPE_CLEAR_M",
    "TABLE_HEIGHT_M",
    "TAPE_CLEAR_M",
    "TRIES",
    "distance_to_line_m",
    "loop_points",
    "min_curve_radius_m",
    "random_arena",
]


MIN_CURVE_RADIUS_M = 0.35
LINE_STEP_M = 0.02
LOOP_MARGIN_M = 0.65
"""From the tape to the walls: room for the robot to follow the loop."""
TAPE_CLEAR_M = 0.12
"""A floor block lies at most this far from the tape."""
SOLID_TAPE_CLEAR_M = 0.2
"""A box or a table keeps this far from the tape's edge: the chassis (0.26 m wide, its
wheels included) passes it following the tape, with a few centimetres to spare."""
TRIES = 400
TABLE_HEIGHT_M = (0.21, 0.26)
"""Tables stand above the Lidar's plane (0.18 m on the JetAuto), as furniture does: a
stand lower than that is invisible to the Lidar, and a map cannot keep the base off it."""


def loop_points(centre: tuple[float, float], radii: tuple[float, float], bends: int,
                wobble: float, phase: float) -> list[tuple[float, float]]:
    """A closed wobbly oval, about LINE_STEP_M between points, counter-clockwise."""
    perimeter = math.pi * (3 * (radii[0] + radii[1]) - math.sqrt(
        (3 * radii[0] + radii[1]) * (radii[0] + 3 * radii[1])))
    n = max(24, round(perimeter / LINE_STEP_M))
    theta = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    scale = 1.0 + wobble * np.sin(bends * theta + phase)
    xs = centre[0] + radii[0] * scale * np.cos(theta)
    ys = centre[1] + radii[1] * scale * np.sin(theta)
    return [(round(float(x), 4), round(float(y), 4)) for x, y in zip(xs, ys, strict=True)]


def min_curve_radius_m(points: list[tuple[float, float]]) -> float:
    """The tightest turn of a closed polyline (circumradius of each three neighbours)."""
    p = np.asarray(points)
    a, b, c = np.roll(p, 1, axis=0), p, np.roll(p, -1, axis=0)
    ab, bc, ca = (np.linalg.norm(a - b, axis=1), np.linalg.norm(b - c, axis=1),
                  np.linalg.norm(c - a, axis=1))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    with np.errstate(divide="ignore"):
        radius = np.where(cross > 1e-12, ab * bc * ca / (2 * cross), np.inf)
    return float(radius.min())


def distance_to_line_m(line: FloorLine, x_m: float, y_m: float) -> float:
    """How far a point is from the tape's centre line."""
    best = math.inf
    for (ax, ay), (bx, by) in line.segments():
        dx, dy = bx - ax, by - ay
        t = max(0.0, min(1.0, ((x_m - ax) * dx + (y_m - ay) * dy) / (dx * dx + dy * dy)))
        best = min(best, math.hypot(x_m - ax - t * dx, y_m - ay - t * dy))
    return best


def _draw_loop(rng: random.Random, room: Room) -> FloorLine:
    cx, cy = (room.x_min_m + room.x_max_m) / 2, (room.y_min_m + room.y_max_m) / 2
    w, h = room.size_m
    radii = ((w / 2 - LOOP_MARGIN_M) / 1.15, (h / 2 - LOOP_MARGIN_M) / 1.15)
    for attempt in range(2 * TRIES):
        if attempt == TRIES:
            # A long narrow room: an oval filling it turns tighter than the robot can follow
            # at its ends (an ellipse's tightest radius is short**2 / long), so shorten it.
            short = min(radii)
            long_most = short * short / (1.3 * MIN_CURVE_RADIUS_M)
            radii = (min(radii[0], long_most), min(radii[1], long_most))
        pts = loop_points((cx, cy), radii, rng.choice((2, 3)), rng.uniform(0.05, 0.15),
                          rng.uniform(0, 2 * math.pi))
        if min_curve_radius_m(pts) >= MIN_CURVE_RADIUS_M:
            return FloorLine(tuple(pts), 0.03, closed=True)
    raise ConfigError("no loop with gentle enough curves fits this room")  # pragma: no cover


class _Placer:
    """Rejection sampling of footprints that touch nothing already placed."""

    def __init__(self, rng: random.Random, room: Room, line: FloorLine | None) -> None:
        self.rng, self.room, self.line = rng, room, line
        self.taken: list[Footprint] = []

    def free(self, fp: Footprint, margin_m: float = 0.0, within: Room | None = None) -> bool:
        """Whether ``fp`` grown by ``margin_m`` touches nothing taken and lies that far
        inside ``within`` (default the room)."""
        r = within or self.room
        points = [(fp.x_mm, fp.y_mm)] if fp.round else fp.corners()
        pad = (fp.radius_mm if fp.round else 0.0) / 1000 + margin_m
        if not all(r.x_min_m + pad <= x / 1000 <= r.x_max_m - pad
                   and r.y_min_m + pad <= y / 1000 <= r.y_max_m - pad for x, y in points):
            return False
        grown = Footprint(fp.x_mm, fp.y_mm, fp.half_x_mm + margin_m * 1000,
                          fp.half_y_mm + margin_m * 1000, fp.yaw_deg, fp.round)
        return not any(overlaps(grown, other) for other in self.taken)

    def point(self, within: Room | None = None) -> tuple[float, float]:
        r = within or self.room
        return self.rng.uniform(r.x_min_m, r.x_max_m), self.rng.uniform(r.y_min_m, r.y_max_m)


def random_arena(seed: int, *, boxes: int | None = None, floor_blocks: int | None = None,
                 tables: int = 2, colors: tuple[str, ...] = ("red", "green", "blue")) -> Arena:
    """The seeded arena ``seed`` (see the module docstring); counts default to the seed's."""
    check_int_range("tables", tables, 0, 3)  # one against each wall but the start's
    for what, count in (("boxes", boxes), ("floor_blocks", floor_blocks)):
        if count is not None:
            check_int_range(what, count, 0, MAX_THINGS)
    if not colors or not set(colors) <= set(COLORS):
        raise ConfigError(f"colors {listing(colors) or '(none)'}: give one or more of "
                          f"{listing(COLORS)}")
    rng = random.Random(seed)
    room = Room(-1.0, round(rng.uniform(3.2, 4.2), 2), round(-rng.uniform(1.5, 1.8), 2),
                round(rng.uniform(1.5, 1.8), 2))
    line = _draw_loop(rng, room)
    place = _Placer(rng, room, line)
    start_x, start_y = line.points_m[len(line.points_m) // 2]  # the loop's far-left side
    (ax, ay), (bx, by) = line.points_m[len(line.points_m) // 2 - 1], line.points_m[
        len(line.points_m) // 2 + 1]
    start = StartPose(start_x, start_y, round(math.degrees(math.atan2(by - ay, bx - ax)), 3))
    place.taken.append(Footprint.disc(start_x * 1000, start_y * 1000,
                                      (ROBOT_RADIUS_M + 0.15) * 2000))
    table_list = _place_tables(place, tables)
    n_boxes = rng.randint(2, 4) if boxes is None else boxes
    box_list = [_place_box(place) for _ in range(n_boxes)]
    blocks = [_table_block(place, table_list, t, rng.choice(colors))
              for t in range(len(table_list)) for _ in range(rng.randint(1, 2))]
    n_floor = rng.randint(1, 3) if floor_blocks is None else floor_blocks
    blocks += [_floor_block(place, rng.choice(colors)) for _ in range(n_floor)]
    return Arena(room, tuple(table_list), tuple(box_list), tuple(blocks), (line,), start,
                 name=f"seeded arena {seed}", seed=seed, source=f"arena seed {seed}")


def _place_tables(place: _Placer, count: int) -> list[Solid]:
    rng, room, out = place.rng, place.room, []
    walls = [("x", room.y_max_m), ("x", room.y_min_m), ("y", room.x_max_m)]
    rng.shuffle(walls)
    for along, wall in walls[:count]:
        for _ in range(TRIES):
            long, deep = rng.uniform(0.5, 0.7), rng.uniform(0.3, 0.4)
            if along == "x":
                x, y = rng.uniform(room.x_min_m + 0.5, room.x_max_m - 0.5), wall - math.copysign(
                    deep / 2 + 0.02, wall)
                solid = Solid(round(x, 3), round(y, 3), round(long, 3), round(deep, 3),
                              round(rng.uniform(*TABLE_HEIGHT_M), 3))
            else:
                x, y = wall - deep / 2 - 0.02, rng.uniform(room.y_min_m + 0.5, room.y_max_m - 0.5)
                solid = Solid(round(x, 3), round(y, 3), round(deep, 3), round(long, 3),
                              round(rng.uniform(*TABLE_HEIGHT_M), 3))
            fp = solid.footprint()
            if place.free(fp, 0.0) and _clear_of_line(place, fp, SOLID_TAPE_CLEAR_M):
                place.taken.append(fp)
                out.append(solid)
                break
        else:  # pragma: no cover - every seed tried has room for three tables
            raise ConfigError(f"no room for a table along a wall of {place.room}")
    return out


def _clear_of_line(place: _Placer, fp: Footprint, clear_m: float) -> bool:
    """Whether the footprint keeps ``clear_m`` from the tape's edge (the tape's points are
    LINE_STEP_M apart, so this holds to about a centimetre)."""
    assert place.line is not None, "an arena with its tape drawn"
    edge_mm = (clear_m + place.line.width_m / 2) * 1000
    return all(fp.distance_from_mm(x * 1000, y * 1000) >= edge_mm
               for x, y in place.line.points_m)


def _place_box(place: _Placer) -> Solid:
    rng = place.rng
    for _ in range(TRIES):
        x, y = place.point()
        solid = Solid(round(x, 3), round(y, 3), round(rng.uniform(0.15, 0.3), 3),
                      round(rng.uniform(0.15, 0.3), 3), round(rng.uniform(0.2, 0.4), 3),
                      round(rng.uniform(-45, 45), 1))
        fp = solid.footprint()
        if place.free(fp, 0.05) and _clear_of_line(place, fp, SOLID_TAPE_CLEAR_M):
            place.taken.append(fp)
            return solid
    raise ConfigError(f"no room for another box in {place.room}")


def _table_block(place: _Placer, tables: list[Solid], t: int, color: str) -> ArenaBlock:
    rng, table = place.rng, tables[t]
    top = table.footprint()
    for _ in range(TRIES):
        x = table.x_m + rng.uniform(-0.35, 0.35) * table.size_x_m
        y = table.y_m + rng.uniform(-0.35, 0.35) * table.size_y_m
        block = ArenaBlock(color, round(x, 4), round(y, 4), round(rng.uniform(-45, 45), 1),
                           on=t)
        fp = block.footprint()
        if all(top.distance_from_mm(cx, cy) == 0 for cx, cy in fp.corners()) and not any(
                overlaps(fp, other) for other in place.taken if other != top):
            place.taken.append(fp)
            return block
    raise ConfigError(f"no room for a block on table {t}")  # pragma: no cover


def _floor_block(place: _Placer, color: str) -> ArenaBlock:
    rng, line = place.rng, place.line
    assert line is not None, "an arena with its tape drawn"
    for _ in range(TRIES):
        ax, ay = rng.choice(line.points_m)
        x, y = ax + rng.uniform(-0.1, 0.1), ay + rng.uniform(-0.1, 0.1)
        block = ArenaBlock(color, round(x, 4), round(y, 4), round(rng.uniform(-45, 45), 1))
        if place.free(block.footprint(), 0.08) and distance_to_line_m(line, x, y) <= TAPE_CLEAR_M:
            place.taken.append(block.footprint())
            return block
    raise ConfigError("no room for a block on the floor")  # pragma: no cover

