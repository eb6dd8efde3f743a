"""Named points on a map: where the base should stand to pick or place (TOML).

Format ``busarm.points``, version 1 (metres and degrees in the map's frame)::

    format = "busarm.points"
    version = 1
    name = "my living room"
    map = "map.yaml"          # optional: the map they are on (relative to this file)

    [points.shelf]
    x_m = 1.20
    y_m = -0.40
    yaw_deg = 90.0
    surface_m = 0.0           # where blocks stand there: the floor (0), or a table's top

A point is where the base's centre stands, facing the blocks (they are looked for about
WORK_AHEAD_M ahead of it, and the base never drives over that spot). Reading checks
every value and refuses unknown keys, one error naming the file and the key; writing is
atomic.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.tomlfile import TomlReader, parse_toml, toml_string

__all__ = [
    "COORD_LIMIT_M",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "NAME_RULE",
    "POINT_KEYS",
    "SURFACE_M",
    "WORK_AHEAD_M",
    "NamedPoint",
    "NamedPoints",
    "check_point_name",
    "load_points",
    "map_reference",
    "points_from_toml",
    "points_to_toml",
    "save_points",
]


FORMAT_NAME = "busarm.points"
FORMAT_VERSION = 1
COORD_LIMIT_M = 1000.0
SURFACE_M = (0.0, 0.5)
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,31}")
NAME_RULE = "1..32 letters, digits, '-' or '_', starting with a letter"
POINT_KEYS = {"x_m", "y_m", "yaw_deg", "surface_m"}
WORK_AHEAD_M = 0.2
"""Where the blocks are at a point: about this far ahead of the base's centre (just past
the chassis's front, 0.15 m: within the arm's straight-down reach of the floor)."""


@dataclass(frozen=True)
class NamedPoint:
    name: str
    pose: Pose2D
    surface_m: float = 0.0
    """The height blocks stand on there (0: the floor)."""

    @property
    def work_spot_m(self) -> tuple[float, float]:
        """Where the blocks are (WORK_AHEAD_M ahead of the point)."""
        p = self.pose
        return (p.x_m + WORK_AHEAD_M * math.cos(p.yaw_rad),
                p.y_m + WORK_AHEAD_M * math.sin(p.yaw_rad))


@dataclass(frozen=True)
class NamedPoints:
    name: str
    points: dict[str, NamedPoint] = field(default_factory=dict)
    map_path: Path | None = None
    """The map the points are on, if the file names one (resolved against its folder)."""
    source: str = "<string>"

    def get(self, name: str) -> NamedPoint:
        """The point ``name``; a ConfigError listing the names if there is none."""
        if name not in self.points:
            names = ", ".join(sorted(self.points)) or "(none)"
            raise ConfigError(f"no point {name!r} in {self.source}; its points: {names}")
        return self.points[name]


def check_point_name(name: str) -> str:
    """``name`` if it can name a point; else a ConfigError saying what can."""
    if not _NAME.fullmatch(name):
        raise ConfigError(f"point name {name!r}: {NAME_RULE}")
    return name


class _Reader(TomlReader):
    def __init__(self, source: str) -> None:
        super().__init__("points file", source)

    def read(self, data: dict[str, Any], folder: Path | None) -> NamedPoints:
        self.unknown(data, "top level", {"format", "version", "name", "map", "points"})
        name = self.header(data, FORMAT_NAME, FORMAT_VERSION)
        map_value = data.get("map")
        if map_value is not None and (not isinstance(map_value, str) or not map_value):
            raise self.fail("map", f"must be a map file's path, got {map_value!r}")
        map_path = None if map_value is None else (
            Path(map_value) if folder is None else folder / map_value)
        table = self.table(data, "points")
        points = {key: self.point(key, value) for key, value in table.items()}
        if not points:
            raise self.fail("points", "has no points: add [points.NAME] tables")
        return NamedPoints(name, points, map_path, self.source)

    def point(self, key: str, value: object) -> NamedPoint:
        where = f"points.{key}"
        if not _NAME.fullmatch(key):
            raise self.fail(where, f"a point's name is {NAME_RULE}")
        if not isinstance(value, dict):
            raise self.fail(where, "must be a table")
        self.unknown(value, where, POINT_KEYS)
        x, y = (self.number(value, k, where, -COORD_LIMIT_M, COORD_LIMIT_M) for k in
                ("x_m", "y_m"))
        yaw = self.number(value, "yaw_deg", where, -360.0, 360.0, 0.0)
        surface = self.number(value, "surface_m", where, *SURFACE_M, 0.0)
        return NamedPoint(key, Pose2D(x, y, math.radians(yaw)), surface)


def points_from_toml(text: str, source: str = "<string>",
                     folder: Path | None = None) -> NamedPoints:
    return _Reader(source).read(parse_toml(text, what="points file", source=source), folder)


def load_points(path: str | Path) -> NamedPoints:
    """Read and check a points file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"points file {path}: cannot read it ({exc.strerror})") from exc
    return points_from_toml(text, str(path), path.parent)


def points_to_toml(points: NamedPoints, map_file: str | None = None) -> str:
    lines = [f'format = "{FORMAT_NAME}"', f"version = {FORMAT_VERSION}",
             f"name = {toml_string(points.name)}"]
    if map_file is not None:
        lines.append(f"map = {toml_string(map_file)}")
    for p in points.points.values():
        lines += ["", f"[points.{p.name}]", f"x_m = {p.pose.x_m:.4f}",
                  f"y_m = {p.pose.y_m:.4f}", f"yaw_deg = {p.pose.yaw_deg:.2f}",
                  f"surface_m = {p.surface_m:.4f}"]
    return "\n".join(lines) + "\n"


def map_reference(map_file: str | Path, points_file: str | Path) -> str:
    """The map's path as a points file names it: relative to the points file's folder
    when it can be, else absolute."""
    try:
        return str(Path(map_file).resolve().relative_to(Path(points_file).resolve().parent))
    except ValueError:
        return str(Path(map_file).resolve())


def save_points(path: str | Path, points: NamedPoints, map_file: str | None = None) -> None:
    """Write a points file atomically (``map_file``: the map's path relative to it)."""
    write_text_atomic(Path(path), points_to_toml(points, map_file))

