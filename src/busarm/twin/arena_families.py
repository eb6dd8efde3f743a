"""Families of seeded rooms for the mobile jobs: the rooms people's robots meet.

``transport_task(family, seed)`` draws the same room for the same family and seed, with
one block on the floor to fetch and where its place may be (``TransportTask``):

- ``standard``: the line benchmark's arena (``random_arena``): a room of about 4 x 3.3 m
  with a taped loop, tables and boxes; the place anywhere at least 1 m off.
- ``doorway``: two rooms through a door 0.6-0.7 m wide; the block in one, its place in
  the other.
- ``corridor``: two rooms joined by a corridor 0.8-1.2 m wide and 1.5-3 m long.
- ``corner``: the block 0.15-0.35 m from both walls of a corner, its place in another.
- ``big``: a big, sparse room (7-10 x 5-8 m, one or two things in it besides the walls:
  a bare rectangle looks the same from two poses, and is refused as such).
- ``symmetric``: tables and boxes in pairs, each the other turned half a turn about the
  room's middle, and one thing without a twin: a robot set down anywhere sees the same
  room from two poses until that one thing is in view.
- ``long``: a room 11-13 m long with walls jutting in from its sides; the carry is over
  8 m.

Every room keeps a way 0.5 m wide between things (the robot's disc is 0.4 m) and its
door or corridor clear; ``arena.start`` is where a map is begun.
"""

from __future__ import annotations

import random
from collections.abc import Callable
from dataclasses import dataclass

from busarm.errors import ConfigError
from busarm.twin.arena import (
    ROBOT_RADIUS_M,
    WALL_HEIGHT_M,
    Arena,
    ArenaBlock,
    Room,
    Solid,
    StartPose,
)
from busarm.twin.arena_gen import TABLE_HEIGHT_M, TRIES, _Placer, random_arena
from busarm.twin.footprints import Footprint, overlaps
from busarm.units import listing

__all__ = [
    "FAMILIES",
    "INNER_WALL_M",
    "PASSAGE_M",
    "TransportTask",
    "transport_task",
]


INNER_WALL_M = 0.1
"""An inner wall's thickness."""
PASSAGE_M = 0.5
"""Things keep this far apart (and from the walls, where they are not against one)."""
MIN_TRIP_M = 1.0
STAND_CLEAR_M = 0.55
"""Nothing is put this near the block to fetch: the base stands 0.2 m behind it."""
_COLOURS = ("red", "green", "blue")


@dataclass(frozen=True)
class TransportTask:
    """A room for transport: the block to fetch is its first on the floor; its place is
    drawn inside ``place_within`` (the room if None) at least ``min_trip_m`` from it."""

    arena: Arena
    family: str
    place_within: Room | None = None
    min_trip_m: float = MIN_TRIP_M


class _Room(_Placer):
    """Drawing a room: rejection sampling of things that touch nothing already there."""

    def __init__(self, rng: random.Random, room: Room) -> None:
        super().__init__(rng, room, None)
        self.walls: list[Solid] = []
        self.tables: list[Solid] = []
        self.boxes: list[Solid] = []
        self.blocks: list[ArenaBlock] = []

    def wall(self, x0: float, x1: float, y0: float, y1: float) -> None:
        """An inner wall over the rectangle x0..x1, y0..y1 (m)."""
        x0, x1, y0, y1 = (round(v, 4) for v in (x0, x1, y0, y1))
        if x1 - x0 > 1e-3 and y1 - y0 > 1e-3:  # its ends where they were drawn, not rounded
            solid = Solid((x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0, WALL_HEIGHT_M)
            self.walls.append(solid)
            self.taken.append(solid.footprint())

    def keep_clear(self, x: float, y: float, radius_m: float) -> None:
        """Nothing is put within ``radius_m`` of (x, y): a door's way, a start."""
        self.taken.append(Footprint.disc(x * 1000, y * 1000, radius_m * 2000))

    def table(self, within: Room | None = None) -> Solid | None:
        """A table against one of ``within``'s sides that is an outer wall."""
        rng, r, room = self.rng, within or self.room, self.room
        sides = [s for s, at, wall in (("n", r.y_max_m, room.y_max_m),
                                       ("s", r.y_min_m, room.y_min_m),
                                       ("e", r.x_max_m, room.x_max_m),
                                       ("w", r.x_min_m, room.x_min_m)) if abs(at - wall) < 1e-6]
        for _ in range(TRIES):
            side = rng.choice(sides)
            long, deep = rng.uniform(0.5, 0.8), rng.uniform(0.3, 0.45)
            height = round(rng.uniform(*TABLE_HEIGHT_M), 3)
            if side in "ns":
                x = rng.uniform(r.x_min_m + long / 2, r.x_max_m - long / 2)
                y = r.y_max_m - deep / 2 if side == "n" else r.y_min_m + deep / 2
                solid = Solid(round(x, 3), round(y, 3), round(long, 3), round(deep, 3), height)
            else:
                y = rng.uniform(r.y_min_m + long / 2, r.y_max_m - long / 2)
                x = r.x_max_m - deep / 2 if side == "e" else r.x_min_m + deep / 2
                solid = Solid(round(x, 3), round(y, 3), round(deep, 3), round(long, 3), height)
            if self._free_against_wall(solid.footprint()):
                self.taken.append(solid.footprint())
                self.tables.append(solid)
                return solid
        return None

    def _free_against_wall(self, fp: Footprint) -> bool:
        r = self.room
        if not all(r.x_min_m - 1e-6 <= x / 1000 <= r.x_max_m + 1e-6
                   and r.y_min_m - 1e-6 <= y / 1000 <= r.y_max_m + 1e-6 for x, y in fp.corners()):
            return False
        grown = Footprint(fp.x_mm, fp.y_mm, fp.half_x_mm + PASSAGE_M * 1000,
                          fp.half_y_mm + PASSAGE_M * 1000, fp.yaw_deg)
        return not any(overlaps(grown, other) for other in self.taken)

    def box(self, within: Room | None = None) -> Solid | None:
        rng = self.rng
        for _ in range(TRIES):
            x, y = self.point(within)
            solid = Solid(round(x, 3), round(y, 3), round(rng.uniform(0.15, 0.35), 3),
                          round(rng.uniform(0.15, 0.35), 3), round(rng.uniform(0.2, 0.4), 3),
                          round(rng.uniform(-45, 45), 1))
            if self.free(solid.footprint(), PASSAGE_M, within):
                self.taken.append(solid.footprint())
                self.boxes.append(solid)
                return solid
        return None

    def floor_block(self, within: Room | None = None, margin_m: float = 0.45) -> ArenaBlock:
        """The block to fetch: room to stand in front of it (``margin_m`` all round)."""
        rng = self.rng
        for _ in range(TRIES):
            x, y = self.point(within)
            block = ArenaBlock(rng.choice(_COLOURS), round(x, 4), round(y, 4),
                               round(rng.uniform(-45, 45), 1))
            if self.free(block.footprint(), margin_m, within):
                self.keep_clear(x, y, STAND_CLEAR_M)  # a stand in front of it stays free
                return self.add_block(block)
        raise ConfigError(f"no room for the block in {within or self.room}")

    def add_block(self, block: ArenaBlock) -> ArenaBlock:
        self.taken.append(block.footprint())
        self.blocks.append(block)
        return block

    def start(self, within: Room | None = None) -> StartPose:
        rng = self.rng
        for _ in range(TRIES):
            x, y = self.point(within)
            if self.free(Footprint.disc(x * 1000, y * 1000, 2000 * ROBOT_RADIUS_M), 0.3, within):
                self.keep_clear(x, y, ROBOT_RADIUS_M + 0.15)
                return StartPose(round(x, 3), round(y, 3), round(rng.uniform(-180, 180), 1))
        raise ConfigError(f"no room to start in {within or self.room}")

    def arena(self, family: str, seed: int, start: StartPose) -> Arena:
        return Arena(self.room, tuple(self.tables), tuple(self.boxes), tuple(self.blocks), (),
                     start, name=f"{family} room {seed}", seed=seed,
                     source=f"{family} room {seed}", walls=tuple(self.walls))


def _room(rng: random.Random, width: tuple[float, float], depth: tuple[float, float]) -> Room:
    w, h = round(rng.uniform(*width), 2), round(rng.uniform(*depth), 2)
    return Room(-1.0, round(w - 1.0, 2), round(-h / 2, 2), round(h / 2, 2))


def _split_x(room: Room, x0: float, x1: float) -> tuple[Room, Room]:
    """The parts of ``room`` left of x0 and right of x1."""
    return (Room(room.x_min_m, x0, room.y_min_m, room.y_max_m),
            Room(x1, room.x_max_m, room.y_min_m, room.y_max_m))


def _furnish(r: _Room, part: Room | None, tables: int, boxes: int) -> None:
    for _ in range(tables):
        r.table(part)
    for _ in range(boxes):
        r.box(part)


def _two_rooms(r: _Room, a: Room, b: Room, family: str, seed: int) -> TransportTask:
    rng = r.rng
    start = r.start(a if rng.random() < 0.5 else b)
    fetch, put = (a, b) if rng.random() < 0.5 else (b, a)
    r.floor_block(fetch)
    for part in (a, b):
        _furnish(r, part, rng.randint(0, 1), rng.randint(1, 2))
    return TransportTask(r.arena(family, seed, start), family, put)


def _doorway(seed: int) -> TransportTask:
    rng = random.Random(seed)
    room = _room(rng, (5.0, 6.5), (3.0, 4.0))
    r = _Room(rng, room)
    x = round(room.x_min_m + rng.uniform(0.42, 0.58) * room.size_m[0], 3)
    gap = round(rng.uniform(0.6, 0.7), 3)
    y = round(rng.uniform(room.y_min_m + 0.4 + gap / 2, room.y_max_m - 0.4 - gap / 2), 3)
    x0, x1 = x - INNER_WALL_M / 2, x + INNER_WALL_M / 2
    r.wall(x0, x1, room.y_min_m, y - gap / 2)
    r.wall(x0, x1, y + gap / 2, room.y_max_m)
    for side in (-1, 1):
        r.keep_clear(x + side * 0.5, y, 0.5)
    return _two_rooms(r, *_split_x(room, x0, x1), "doorway", seed)


def _corridor(seed: int) -> TransportTask:
    rng = random.Random(seed)
    ends, length = rng.uniform(2.2, 3.0), rng.uniform(1.5, 3.0)
    width = 2 * ends + length
    room = _room(rng, (width, width), (2.6, 3.6))
    r = _Room(rng, room)
    x0 = round(room.x_min_m + ends, 3)
    x1 = round(x0 + length, 3)
    wide = round(rng.uniform(0.8, 1.2), 3)
    y = round(rng.uniform(room.y_min_m + wide / 2 + 0.3, room.y_max_m - wide / 2 - 0.3), 3)
    r.wall(x0, x1, room.y_min_m, y - wide / 2)
    r.wall(x0, x1, y + wide / 2, room.y_max_m)
    for x in (x0 - 0.5, x1 + 0.5):
        r.keep_clear(x, y, 0.5)
    return _two_rooms(r, *_split_x(room, x0, x1), "corridor", seed)


def _corner_block(r: _Room, corner: tuple[int, int]) -> Room:
    """A block 0.15-0.35 m from both walls of the room's ``corner`` (signs of x, y);
    the corner's square of 0.8 m, for drawing a place there too."""
    room, rng = r.room, r.rng
    cx = room.x_max_m if corner[0] > 0 else room.x_min_m
    cy = room.y_max_m if corner[1] > 0 else room.y_min_m
    dx, dy = rng.uniform(0.15, 0.35), rng.uniform(0.15, 0.35)
    r.add_block(ArenaBlock(rng.choice(_COLOURS), round(cx - corner[0] * dx, 4),
                           round(cy - corner[1] * dy, 4), round(rng.uniform(-45, 45), 1)))
    r.keep_clear(cx - corner[0] * 0.45, cy - corner[1] * 0.45, 0.45)
    return Room(min(cx, cx - corner[0] * 0.8), max(cx, cx - corner[0] * 0.8),
                min(cy, cy - corner[1] * 0.8), max(cy, cy - corner[1] * 0.8))


def _corner(seed: int) -> TransportTask:
    rng = random.Random(seed)
    room = _room(rng, (3.8, 5.0), (3.0, 3.6))
    r = _Room(rng, room)
    corners = [(1, 1), (1, -1), (-1, 1), (-1, -1)]
    rng.shuffle(corners)
    _corner_block(r, corners[0])
    cx = room.x_max_m if corners[1][0] > 0 else room.x_min_m
    cy = room.y_max_m if corners[1][1] > 0 else room.y_min_m
    put = Room(min(cx, cx - corners[1][0] * 0.6), max(cx, cx - corners[1][0] * 0.6),
               min(cy, cy - corners[1][1] * 0.6), max(cy, cy - corners[1][1] * 0.6))
    r.keep_clear(cx - corners[1][0] * 0.5, cy - corners[1][1] * 0.5, 0.55)
    start = r.start()
    _furnish(r, None, rng.randint(1, 2), rng.randint(1, 3))
    return TransportTask(r.arena("corner", seed, start), "corner", put)


def _big(seed: int) -> TransportTask:
    rng = random.Random(seed)
    room = _room(rng, (7.0, 10.0), (5.0, 8.0))
    r = _Room(rng, room)
    start = r.start()
    things = rng.randint(1, 2)  # a bare rectangle looks the same turned half round
    tables = rng.randint(0, things)
    _furnish(r, None, tables, things - tables)
    r.floor_block()
    return TransportTask(r.arena("big", seed, start), "big", None, 3.0)


def _turned(solid: Solid, cx: float, cy: float) -> Solid:
    return Solid(round(2 * cx - solid.x_m, 4), round(2 * cy - solid.y_m, 4), solid.size_x_m,
                 solid.size_y_m, solid.height_m, solid.yaw_deg)


def _symmetric(seed: int) -> TransportTask:
    rng = random.Random(seed)
    room = _room(rng, (4.0, 6.0), (3.0, 4.5))
    r = _Room(rng, room)
    cx, cy = (room.x_min_m + room.x_max_m) / 2, (room.y_min_m + room.y_max_m) / 2
    r.keep_clear(cx, cy, 0.6)  # the middle: a pair's halves would meet there
    if r.box() is None:  # the one thing without a twin, first: there is room for it
        raise ConfigError(f"no room for a box in {room}")  # pragma: no cover
    start = r.start()
    r.floor_block()
    for kind in ["table"] * rng.randint(1, 2) + ["box"] * rng.randint(1, 2):
        made = r.table() if kind == "table" else r.box()
        if made is None:
            continue
        twin = _turned(made, cx, cy)
        listed = r.tables if kind == "table" else r.boxes
        if r.free(twin.footprint(), 0.0) if kind == "box" else r._free_against_wall(
                twin.footprint()):
            listed.append(twin)
            r.taken.append(twin.footprint())
        else:  # its twin does not fit: without one, the room would not be symmetric
            listed.pop()
            r.taken.remove(made.footprint())
    return TransportTask(r.arena("symmetric", seed, start), "symmetric")


def _long(seed: int) -> TransportTask:
    rng = random.Random(seed)
    room = _room(rng, (11.0, 13.0), (2.6, 3.6))
    r = _Room(rng, room)
    w, h = room.size_m
    for k, at in enumerate((0.33, 0.66)):  # walls jutting in from alternate sides
        x = room.x_min_m + at * w + rng.uniform(-0.5, 0.5)
        reach = rng.uniform(0.35, 0.55) * h
        if (k + seed) % 2:
            r.wall(x - INNER_WALL_M / 2, x + INNER_WALL_M / 2, room.y_max_m - reach,
                   room.y_max_m)
        else:
            r.wall(x - INNER_WALL_M / 2, x + INNER_WALL_M / 2, room.y_min_m,
                   room.y_min_m + reach)
    left = Room(room.x_min_m, room.x_min_m + 1.5, room.y_min_m, room.y_max_m)
    right = Room(room.x_max_m - 1.5, room.x_max_m, room.y_min_m, room.y_max_m)
    fetch, put = (left, right) if rng.random() < 0.5 else (right, left)
    start = r.start(fetch)
    r.floor_block(fetch)
    middle = Room(room.x_min_m + 1.6, room.x_max_m - 1.6, room.y_min_m, room.y_max_m)
    _furnish(r, middle, rng.randint(1, 2), rng.randint(1, 3))
    return TransportTask(r.arena("long", seed, start), "long", put, 8.0)


def _standard(seed: int) -> TransportTask:
    return TransportTask(random_arena(seed, floor_blocks=1), "standard")


FAMILIES: dict[str, Callable[[int], TransportTask]] = {
    "standard": _standard, "doorway": _doorway, "corridor": _corridor, "corner": _corner,
    "big": _big, "symmetric": _symmetric, "long": _long}
"""Each family's room drawer, by name (the module docstring says what each draws)."""


def transport_task(family: str, seed: int) -> TransportTask:
    """The seeded room ``seed`` of ``family`` (see the module docstring)."""
    if family not in FAMILIES:
        raise ConfigError(f"room family {family!r}: give one of {listing(FAMILIES)}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ConfigError(f"seed {seed!r}: give a whole number 0 or more")
    return FAMILIES[family](seed)
