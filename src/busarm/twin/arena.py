"""Arenas for the mobile twin: a walled floor with tables, boxes, blocks and floor lines.

An arena is in metres, in its own frame (x, y on the floor, z up; the robot starts at
``start``). It is described in TOML (format ``busarm.arena``, version 1; see
``arena_to_toml`` for a complete example) or drawn from a seed (busarm.twin.arena_gen).
Every arena is checked when it is made: anything outside the room's walls, objects that
interpenetrate (touching is allowed), a block in the air, a line off the floor, or a
robot that would start inside something is refused with one error naming it.

- ``tables``: solid low tables (stands); blocks may stand on them.
- ``boxes``: obstacles on the floor, each a body the twin can move (a person stepping in).
- ``blocks``: coloured cubes on the floor or on a table (``on = <table index>``).
- ``lines``: floor tape (polylines; ``closed`` for a loop), seen by the camera only.
- ``walls``: inner walls (fixed, as tall as the room's): rooms, doorways and corridors
  inside the outer walls.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.tomlfile import TomlReader, load_toml, parse_toml, toml_string
from busarm.twin.footprints import Footprint, overlaps
from busarm.twin.scene import BLOCK_SIZE_MM, COLORS, DEFAULT_BLOCK_MM

__all__ = [
    "BLOCK_KEYS",
    "FLOOR_COLORS",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "HEIGHT_M",
    "LINE_COLORS",
    "LINE_KEYS",
    "LINE_WIDTH_M",
    "MAX_THINGS",
    "ROBOT_RADIUS_M",
    "ROOM_M",
    "SOLID_KEYS",
    "WALL_HEIGHT_M",
    "WALL_THICKNESS_M",
    "Arena",
    "ArenaBlock",
    "FloorLine",
    "Room",
    "Solid",
    "StartPose",
    "arena_from_toml",
    "arena_to_toml",
    "check_arena",
    "load_arena",
    "save_arena",
]


FORMAT_NAME = "busarm.arena"
FORMAT_VERSION = 1
ROBOT_RADIUS_M = 0.2
"""The base's footprint as a disc (the JetAuto with its wheels is about 0.3 x 0.25 m)."""
ROOM_M = (1.0, 30.0)
"""Sides a room may have."""
HEIGHT_M = (0.02, 2.0)
LINE_WIDTH_M = (0.01, 0.1)
WALL_THICKNESS_M = 0.05
WALL_HEIGHT_M = 0.3
LINE_COLORS = {"black": (0.03, 0.03, 0.03), "blue": (0.1, 0.25, 0.7),
               "red": (0.78, 0.08, 0.1), "green": (0.05, 0.5, 0.25),
               "yellow": (0.95, 0.8, 0.08), "white": (0.92, 0.92, 0.9)}
"""Floor tape (sRGB 0..1) as sold: vinyl marking tape's black, blue, red, green, yellow
and white."""
FLOOR_COLORS = {"light": (0.74, 0.72, 0.68), "dark": (0.16, 0.16, 0.17)}
"""The floor (sRGB 0..1): a light grey, or a dark one (rubber, lino) for white tape."""
MAX_THINGS = 200


@dataclass(frozen=True)
class Room:
    """The floor inside the walls (the walls stand just outside it)."""

    x_min_m: float = -1.0
    x_max_m: float = 3.0
    y_min_m: float = -1.5
    y_max_m: float = 1.5

    @property
    def size_m(self) -> tuple[float, float]:
        return self.x_max_m - self.x_min_m, self.y_max_m - self.y_min_m


@dataclass(frozen=True)
class Solid:
    """A table or a box: a rectangle on the floor (centre, sides, yaw) and a height."""

    x_m: float
    y_m: float
    size_x_m: float
    size_y_m: float
    height_m: float
    yaw_deg: float = 0.0

    def footprint(self) -> Footprint:
        return Footprint(self.x_m * 1000, self.y_m * 1000, self.size_x_m * 500,
                         self.size_y_m * 500, self.yaw_deg)


@dataclass(frozen=True)
class ArenaBlock:
    """A cube on the floor, or on table ``on``."""

    color: str
    x_m: float
    y_m: float
    yaw_deg: float = 0.0
    size_mm: float = DEFAULT_BLOCK_MM
    on: int | None = None

    def footprint(self) -> Footprint:
        return Footprint.square(self.x_m * 1000, self.y_m * 1000, self.size_mm, self.yaw_deg)


@dataclass(frozen=True)
class FloorLine:
    """Tape on the floor through ``points_m`` (a loop when ``closed``)."""

    points_m: tuple[tuple[float, float], ...]
    width_m: float = 0.03
    closed: bool = False
    color: str = "black"

    def segments(self) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        pts = list(self.points_m)
        if self.closed:
            pts.append(pts[0])
        return list(itertools.pairwise(pts))

    @property
    def length_m(self) -> float:
        return sum(math.dist(a, b) for a, b in self.segments())


@dataclass(frozen=True)
class StartPose:
    x_m: float = 0.0
    y_m: float = 0.0
    yaw_deg: float = 0.0


@dataclass(frozen=True)
class Arena:
    """A room and what is in it; checked when made (see the module docstring)."""

    room: Room = field(default_factory=Room)
    tables: tuple[Solid, ...] = ()
    boxes: tuple[Solid, ...] = ()
    blocks: tuple[ArenaBlock, ...] = ()
    lines: tuple[FloorLine, ...] = ()
    start: StartPose = field(default_factory=StartPose)
    name: str = "arena"
    seed: int | None = None
    source: str = "<memory>"
    walls: tuple[Solid, ...] = ()
    """Inner walls (their ``height_m`` as drawn; WALL_HEIGHT_M is the room's own)."""
    floor: str = "light"
    """The floor's colour: a name of ``FLOOR_COLORS``."""

    def __post_init__(self) -> None:
        check_arena(self)

    @property
    def fixed(self) -> tuple[Solid, ...]:
        """What never moves and the Lidar sees: the tables and the inner walls."""
        return (*self.tables, *self.walls)

    def block_z_m(self, index: int) -> float:
        """Where block ``index``'s centre stands (on the floor or its table)."""
        block = self.blocks[index]
        ground = 0.0 if block.on is None else self.tables[block.on].height_m
        return ground + block.size_mm / 2000


# ---------------------------------------------------------------------- checks

def _fail(arena: Arena, what: str) -> ConfigError:
    return ConfigError(f"arena {arena.source}: {what}")


def _inside_room(arena: Arena, name: str, fp: Footprint) -> None:
    r = arena.room
    # A disc's extremes along x and y: the error then names a point that is truly outside.
    x0, y0, rad = fp.x_mm, fp.y_mm, fp.half_x_mm
    pts = ([(x0 - rad, y0), (x0 + rad, y0), (x0, y0 - rad), (x0, y0 + rad)] if fp.round
           else fp.corners())
    for x, y in pts:
        if not (r.x_min_m * 1000 - 1e-6 <= x <= r.x_max_m * 1000 + 1e-6
                and r.y_min_m * 1000 - 1e-6 <= y <= r.y_max_m * 1000 + 1e-6):
            raise _fail(arena, f"{name} reaches ({x / 1000:.3f}, {y / 1000:.3f}) m, outside "
                        f"the room x {r.x_min_m:g}..{r.x_max_m:g} m, y {r.y_min_m:g}.."
                        f"{r.y_max_m:g} m")


def _number(arena: Arena, name: str, value: float, lo: float, hi: float, unit: str) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise _fail(arena, f"{name} = {value!r} {unit} is out of range {lo:g}..{hi:g} {unit}")


def check_arena(arena: Arena) -> None:
    """Refuse an arena that cannot be built (see the module docstring)."""
    r = arena.room
    for key in ("x_min_m", "x_max_m", "y_min_m", "y_max_m"):
        _number(arena, f"room.{key}", getattr(r, key), -100.0, 100.0, "m")
    for axis, size in zip("xy", r.size_m, strict=True):
        _number(arena, f"room's {axis} extent", round(size, 9), *ROOM_M, "m")
    count = (len(arena.tables) + len(arena.boxes) + len(arena.blocks) + len(arena.lines)
             + len(arena.walls))
    if count > MAX_THINGS:
        raise _fail(arena, f"{count} things; at most {MAX_THINGS}")
    floor: list[tuple[str, Footprint]] = []
    for kind, solids in (("table", arena.tables), ("box", arena.boxes),
                         ("wall", arena.walls)):
        for i, s in enumerate(solids):
            name = f"{kind} {i}"
            for key, lo, hi in (("x_m", -100.0, 100.0), ("y_m", -100.0, 100.0),
                                ("size_x_m", 0.02, 10.0), ("size_y_m", 0.02, 10.0),
                                ("height_m", *HEIGHT_M), ("yaw_deg", -360.0, 360.0)):
                _number(arena, f"{name} {key}", getattr(s, key), lo, hi,
                        "deg" if key == "yaw_deg" else "m")
            _inside_room(arena, name, s.footprint())
            floor.append((name, s.footprint()))
    _check_blocks(arena, floor)
    start = arena.start
    for key, lo, hi, unit in (("x_m", -100.0, 100.0, "m"), ("y_m", -100.0, 100.0, "m"),
                              ("yaw_deg", -360.0, 360.0, "deg")):
        _number(arena, f"start {key}", getattr(start, key), lo, hi, unit)
    robot = Footprint.disc(start.x_m * 1000, start.y_m * 1000, ROBOT_RADIUS_M * 2000)
    _inside_room(arena, "the robot at its start", robot)
    floor.append(("the robot at its start", robot))
    _check_overlaps(arena, floor)
    if arena.floor not in FLOOR_COLORS:
        raise _fail(arena, f"floor {arena.floor!r}; allowed: {', '.join(FLOOR_COLORS)}")
    for i, line in enumerate(arena.lines):
        _check_line(arena, i, line)


def _check_blocks(arena: Arena, floor: list[tuple[str, Footprint]]) -> None:
    for i, b in enumerate(arena.blocks):
        name = f"block {i}"
        if b.color not in COLORS:
            raise _fail(arena, f"{name} color {b.color!r}; allowed: {', '.join(COLORS)}")
        # Its place too: a nan would pass every comparison with its table.
        _number(arena, f"{name} x_m", b.x_m, -100.0, 100.0, "m")
        _number(arena, f"{name} y_m", b.y_m, -100.0, 100.0, "m")
        _number(arena, f"{name} size_mm", b.size_mm, *BLOCK_SIZE_MM, "mm")
        _number(arena, f"{name} yaw_deg", b.yaw_deg, -360.0, 360.0, "deg")
        fp = b.footprint()
        if b.on is None:
            _inside_room(arena, name, fp)
            floor.append((name, fp))
            continue
        if isinstance(b.on, bool) or not isinstance(b.on, int) or not (
                0 <= b.on < len(arena.tables)):
            raise _fail(arena, f"{name} is on table {b.on!r}; tables: 0.."
                        f"{len(arena.tables) - 1}" if arena.tables else
                        f"{name} is on table {b.on!r}, but the arena has no table")
        top = arena.tables[b.on].footprint()
        if any(top.distance_from_mm(x, y) > 1e-6 for x, y in fp.corners()):
            raise _fail(arena, f"{name} at ({b.x_m:g}, {b.y_m:g}) m is not all on table {b.on}")
    on_tables = [(f"block {i}", b.footprint()) for i, b in enumerate(arena.blocks)
                 if b.on is not None]
    _check_overlaps(arena, on_tables)


def _check_overlaps(arena: Arena, things: list[tuple[str, Footprint]]) -> None:
    for k, (name_a, a) in enumerate(things):
        for name_b, b in things[k + 1:]:
            if overlaps(a, b):
                raise _fail(arena, f"{name_a} and {name_b} overlap")


def _check_line(arena: Arena, i: int, line: FloorLine) -> None:
    name = f"line {i}"
    if line.color not in LINE_COLORS:
        raise _fail(arena, f"{name} color {line.color!r}; allowed: {', '.join(LINE_COLORS)}")
    _number(arena, f"{name} width_m", line.width_m, *LINE_WIDTH_M, "m")
    if not 2 <= len(line.points_m) <= 5000:
        raise _fail(arena, f"{name} has {len(line.points_m)} points; it needs 2..5000")
    for x, y in line.points_m:
        _inside_room(arena, name, Footprint.disc(x * 1000, y * 1000, line.width_m * 1000))
    if any(math.dist(a, b) < 1e-4 for a, b in line.segments()):
        raise _fail(arena, f"{name} has two points closer than 0.1 mm (repeat a point?)")


# ---------------------------------------------------------------------- files

SOLID_KEYS = {"x_m", "y_m", "size_x_m", "size_y_m", "height_m", "yaw_deg"}
BLOCK_KEYS = {"color", "x_m", "y_m", "yaw_deg", "size_mm", "on"}
LINE_KEYS = {"points_m", "width_m", "closed", "color"}


class _Reader(TomlReader):
    def __init__(self, source: str) -> None:
        super().__init__("arena", source)

    def items(self, data: dict[str, Any], key: str) -> list[dict[str, Any]]:
        value = data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.fail(key, "must be an array of tables ([[" + key + "]])")
        return value

    def real(self, data: dict[str, Any], key: str, where: str,
             default: float | None = None) -> float:
        return self.number(data, key, where, -1e6, 1e6, default)

    def arena(self, data: dict[str, Any]) -> Arena:
        self.unknown(data, "top level", {"format", "version", "name", "room", "start",
                                         "tables", "boxes", "blocks", "lines", "walls",
                                         "floor"})
        name = self.header(data, FORMAT_NAME, FORMAT_VERSION)
        room = self.table(data, "room")
        self.unknown(room, "room", {"x_min_m", "x_max_m", "y_min_m", "y_max_m"})
        start = data.get("start", {})
        if not isinstance(start, dict):
            raise self.fail("start", "must be a table")
        self.unknown(start, "start", {"x_m", "y_m", "yaw_deg"})
        floor = data.get("floor", "light")
        if not isinstance(floor, str):
            raise self.fail("floor", f"must be one of {', '.join(FLOOR_COLORS)}")
        return Arena(
            room=Room(*(self.real(room, k, "room") for k in
                        ("x_min_m", "x_max_m", "y_min_m", "y_max_m"))),
            tables=tuple(self.solid(d, f"tables[{i}]")
                         for i, d in enumerate(self.items(data, "tables"))),
            boxes=tuple(self.solid(d, f"boxes[{i}]")
                        for i, d in enumerate(self.items(data, "boxes"))),
            blocks=tuple(self.block(d, f"blocks[{i}]")
                         for i, d in enumerate(self.items(data, "blocks"))),
            lines=tuple(self.line(d, f"lines[{i}]")
                        for i, d in enumerate(self.items(data, "lines"))),
            start=StartPose(self.real(start, "x_m", "start", 0.0),
                            self.real(start, "y_m", "start", 0.0),
                            self.real(start, "yaw_deg", "start", 0.0)),
            name=name, source=self.source,
            walls=tuple(self.solid(d, f"walls[{i}]", wall=True)
                        for i, d in enumerate(self.items(data, "walls"))), floor=floor)

    def solid(self, d: dict[str, Any], where: str, wall: bool = False) -> Solid:
        self.unknown(d, where, SOLID_KEYS)
        x, y, sx, sy = (self.real(d, k, where) for k in ("x_m", "y_m", "size_x_m", "size_y_m"))
        h = self.real(d, "height_m", where, WALL_HEIGHT_M if wall else None)
        return Solid(x, y, sx, sy, h, self.real(d, "yaw_deg", where, 0.0))

    def block(self, d: dict[str, Any], where: str) -> ArenaBlock:
        self.unknown(d, where, BLOCK_KEYS)
        color = d.get("color")
        if not isinstance(color, str):
            raise self.fail(f"{where}.color", f"must be one of {', '.join(COLORS)}")
        on = d.get("on")
        if on is not None:
            on = self.integer(d, "on", where, 0, MAX_THINGS)
        return ArenaBlock(color, self.real(d, "x_m", where), self.real(d, "y_m", where),
                          self.real(d, "yaw_deg", where, 0.0),
                          self.real(d, "size_mm", where, DEFAULT_BLOCK_MM), on)

    def line(self, d: dict[str, Any], where: str) -> FloorLine:
        self.unknown(d, where, LINE_KEYS)
        raw = d.get("points_m")
        if not isinstance(raw, list) or not all(
                isinstance(p, list) and len(p) == 2 for p in raw):
            raise self.fail(f"{where}.points_m", "must be a list of [x, y] pairs in metres")
        points = tuple((self.real({"x": p[0]}, "x", f"{where}.points_m"),
                        self.real({"y": p[1]}, "y", f"{where}.points_m")) for p in raw)
        closed = d.get("closed", False)
        if not isinstance(closed, bool):
            raise self.fail(f"{where}.closed", f"must be true or false, got {closed!r}")
        color = d.get("color", "black")
        if not isinstance(color, str):
            raise self.fail(f"{where}.color", f"must be one of {', '.join(LINE_COLORS)}")
        return FloorLine(points, self.real(d, "width_m", where, 0.03), closed, color)


def arena_from_toml(text: str, source: str = "<string>") -> Arena:
    """Parse and check an arena; errors name ``source`` and the key or object."""
    return _Reader(source).arena(parse_toml(text, what="arena", source=source))


def load_arena(path: str | Path) -> Arena:
    """Read and check the arena file at ``path``."""
    data, source = load_toml(Path(path), what="arena", package="busarm.twin", shipped=())
    return _Reader(source).arena(data)


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return toml_string(v)
    # A float's repr is its shortest exact digits (read back to the same float) and valid
    # TOML; float() first for a numpy float, whose repr names its type.
    return repr(float(v)) if isinstance(v, float) else str(v)


def _fields(values: dict[str, object]) -> str:
    return ", ".join(f"{k} = {_toml_value(v)}" for k, v in values.items())


def arena_to_toml(arena: Arena) -> str:
    """The arena as a file ``load_arena`` reads back to the same arena."""
    r, s = arena.room, arena.start
    out = [f'format = "{FORMAT_NAME}"', f"version = {FORMAT_VERSION}",
           f"name = {toml_string(arena.name)}",
           *([f"floor = {toml_string(arena.floor)}"] if arena.floor != "light" else []), "",
           f"room = {{ {_fields(dict(x_min_m=r.x_min_m, x_max_m=r.x_max_m, y_min_m=r.y_min_m, y_max_m=r.y_max_m))} }}",  # noqa: E501
           f"start = {{ {_fields(dict(x_m=s.x_m, y_m=s.y_m, yaw_deg=s.yaw_deg))} }}", ""]
    for key, solids in (("tables", arena.tables), ("boxes", arena.boxes),
                        ("walls", arena.walls)):
        out += [f"[[{key}]]\n{_fields(vars(t)).replace(', ', chr(10))}\n" for t in solids]
    for b in arena.blocks:
        values = {k: v for k, v in vars(b).items() if v is not None}
        out.append(f"[[blocks]]\n{_fields(values).replace(', ', chr(10))}\n")
    for line in arena.lines:
        pts = ", ".join(f"[{_toml_value(x)}, {_toml_value(y)}]" for x, y in line.points_m)
        out.append(f"[[lines]]\nwidth_m = {_toml_value(line.width_m)}\nclosed = "
                   f"{'true' if line.closed else 'false'}\ncolor = \"{line.color}\"\n"
                   f"points_m = [{pts}]\n")
    return "\n".join(out)


def save_arena(path: str | Path, arena: Arena) -> None:
    """Write the arena to ``path`` atomically."""
    write_text_atomic(Path(path), arena_to_toml(arena), what="arena")
