"""What stands on the twin's table: blocks, bins and calibration boards, in millimetres.

A scene is data (``Scene``), read from a TOML file or drawn from a seed
(``random_scene``), always validated: a block off the table, overlapping another one or
a bin, or of an unknown colour is refused with the key and the allowed range. Positions
are in the arm's base frame (x forward, y left, z up; the table top at the arm config's
``table_z_mm``). Blocks are cubes standing on the table, turned by ``yaw_deg`` about z.
"""

from __future__ import annotations

import math
import random
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.units import check_int_range, check_range

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

SCENE_FORMAT = "busarm.scene"
SCENE_VERSION = 1

COLORS: dict[str, tuple[float, float, float]] = {
    "red": (0.80, 0.12, 0.10),
    "green": (0.12, 0.55, 0.20),
    "blue": (0.10, 0.25, 0.80),
    "yellow": (0.90, 0.80, 0.10),
}
"""Block colours the twin can paint (linear RGB 0..1): matte, as wooden toy blocks."""

DEFAULT_BLOCK_MM = 30.0
BOARD_KINDS = ("chessboard", "charuco", "tags")


@dataclass(frozen=True)
class Table:
    """The table top's extent in the base frame, in mm (the arm base stands on it)."""

    x_min_mm: float = -200.0
    x_max_mm: float = 420.0
    y_min_mm: float = -400.0
    y_max_mm: float = 400.0

    def contains(self, x_mm: float, y_mm: float, margin_mm: float = 0.0) -> bool:
        return (self.x_min_mm + margin_mm <= x_mm <= self.x_max_mm - margin_mm
                and self.y_min_mm + margin_mm <= y_mm <= self.y_max_mm - margin_mm)


@dataclass(frozen=True)
class Block:
    """A cube of ``size_mm`` standing on the table, centred at (x, y), turned by yaw."""

    color: str
    x_mm: float
    y_mm: float
    yaw_deg: float = 0.0
    size_mm: float = DEFAULT_BLOCK_MM
    mass_g: float = 20.0

    @property
    def radius_mm(self) -> float:
        """Half the diagonal: no part of the block is farther from its centre axis."""
        return self.size_mm * math.sqrt(0.5)


@dataclass(frozen=True)
class Bin:
    """An open tray for blocks of ``color``: outer side ``size_mm``, walls ``wall_mm`` high."""

    color: str
    x_mm: float
    y_mm: float
    size_mm: float = 90.0
    wall_mm: float = 12.0


@dataclass(frozen=True)
class Board:
    """A printed calibration target lying flat on the table (see busarm.vision.calibration).

    ``kind`` is ``chessboard`` or ``tags``; (x, y) is where the board's own origin (its
    first corner) lies, ``yaw_deg`` turns its x axis about the table's z.
    """

    kind: str
    x_mm: float
    y_mm: float
    yaw_deg: float = 0.0


@dataclass(frozen=True)
class Scene:
    """Everything on the table."""

    blocks: tuple[Block, ...] = ()
    bins: tuple[Bin, ...] = ()
    boards: tuple[Board, ...] = ()
    table: Table = field(default_factory=Table)
    seed: int | None = None
    source: str = "<memory>"

    def __post_init__(self) -> None:
        check_scene(self)

    def with_blocks(self, blocks: Sequence[Block]) -> Scene:
        return replace(self, blocks=tuple(blocks))


def _bin_at(color: str, bearing_deg: float, radius_mm: float = 195.0) -> Bin:
    b = math.radians(bearing_deg)
    return Bin(color, round(radius_mm * math.cos(b), 2), round(radius_mm * math.sin(b), 2))


DEFAULT_BINS = (_bin_at("red", 70.0), _bin_at("green", -70.0), _bin_at("blue", 110.0),
                _bin_at("yellow", -110.0))
"""One tray per colour beside the arm, where the arm reaches them but the blocks are not."""

BASE_CLEARANCE_MM = 90.0
"""Nothing stands closer than this to the arm's base axis (the base itself is there)."""


def _where(scene: Scene, what: str) -> str:
    return f"scene {scene.source}: {what}"


def _finite(scene: Scene, what: str, value: object, lo: float, hi: float) -> float:
    """``value`` as a float within lo..hi, else ConfigError naming the scene and ``what``."""
    return check_range(_where(scene, what), value, lo, hi)


def check_scene(scene: Scene) -> None:
    """Raise ConfigError naming the first thing in ``scene`` that cannot stand there."""
    t = scene.table
    for name in ("x_min_mm", "x_max_mm", "y_min_mm", "y_max_mm"):
        _finite(scene, f"table.{name}", getattr(t, name), -2000.0, 2000.0)
    if not (t.x_min_mm < -BASE_CLEARANCE_MM and t.x_max_mm > BASE_CLEARANCE_MM
            and t.y_min_mm < -BASE_CLEARANCE_MM and t.y_max_mm > BASE_CLEARANCE_MM):
        raise ConfigError(_where(scene, "the table must extend at least "
                                        f"{BASE_CLEARANCE_MM:g} mm around the arm base (0, 0)"))
    footprints: list[tuple[str, float, float, float]] = []
    for i, b in enumerate(scene.blocks):
        key = f"blocks[{i}]"
        if b.color not in COLORS:
            raise ConfigError(_where(scene, f"{key}.color = {b.color!r}; allowed: "
                                            f"{', '.join(COLORS)}"))
        size = _finite(scene, f"{key}.size_mm", b.size_mm, 10.0, 60.0)
        _finite(scene, f"{key}.mass_g", b.mass_g, 1.0, 500.0)
        _finite(scene, f"{key}.yaw_deg", b.yaw_deg, -360.0, 360.0)
        x = _finite(scene, f"{key}.x_mm", b.x_mm, -2000.0, 2000.0)
        y = _finite(scene, f"{key}.y_mm", b.y_mm, -2000.0, 2000.0)
        if not t.contains(x, y, b.radius_mm):
            raise ConfigError(_where(
                scene, f"{key} at ({x:g}, {y:g}) mm is off the table: its centre must lie in "
                f"x {t.x_min_mm + b.radius_mm:g}..{t.x_max_mm - b.radius_mm:g}, "
                f"y {t.y_min_mm + b.radius_mm:g}..{t.y_max_mm - b.radius_mm:g} mm"))
        footprints.append((key, x, y, size * math.sqrt(0.5)))
    for i, bin_ in enumerate(scene.bins):
        key = f"bins[{i}]"
        if bin_.color not in COLORS:
            raise ConfigError(_where(scene, f"{key}.color = {bin_.color!r}; allowed: "
                                            f"{', '.join(COLORS)}"))
        size = _finite(scene, f"{key}.size_mm", bin_.size_mm, 40.0, 200.0)
        _finite(scene, f"{key}.wall_mm", bin_.wall_mm, 2.0, 60.0)
        x = _finite(scene, f"{key}.x_mm", bin_.x_mm, -2000.0, 2000.0)
        y = _finite(scene, f"{key}.y_mm", bin_.y_mm, -2000.0, 2000.0)
        if not t.contains(x, y, size / 2):
            raise ConfigError(_where(scene, f"{key} at ({x:g}, {y:g}) mm is off the table"))
        footprints.append((key, x, y, size * math.sqrt(0.5)))
    for i, board in enumerate(scene.boards):
        key = f"boards[{i}]"
        if board.kind not in BOARD_KINDS:
            raise ConfigError(_where(scene, f"{key}.kind = {board.kind!r}; allowed: "
                                            f"{', '.join(BOARD_KINDS)}"))
        for name in ("x_mm", "y_mm"):
            _finite(scene, f"{key}.{name}", getattr(board, name), -2000.0, 2000.0)
        _finite(scene, f"{key}.yaw_deg", board.yaw_deg, -360.0, 360.0)
    for j, (key, x, y, r) in enumerate(footprints):
        if math.hypot(x, y) < BASE_CLEARANCE_MM + r * 0.5:
            raise ConfigError(_where(scene, f"{key} at ({x:g}, {y:g}) mm stands on the arm "
                                            f"base: keep it {BASE_CLEARANCE_MM:g} mm from (0, 0)"))
        for key2, x2, y2, r2 in footprints[j + 1:]:
            if math.hypot(x - x2, y - y2) < r + r2:
                raise ConfigError(_where(scene, f"{key} and {key2} overlap at ({x:g}, {y:g}) "
                                                 f"and ({x2:g}, {y2:g}) mm"))


# ---------------------------------------------------------------------- seeded scenes

PLACE_RADIUS_MM = (140.0, 250.0)
"""Where random blocks go: this far from the base axis (straight down reaches them) ..."""
REACH_RADIUS_MM = (110.0, 290.0)
"""... or, for scenes over all the table the arm can pick from (some blocks only with a
tilted grasp), this far."""
PLACE_BEARING_DEG = (-55.0, 55.0)
"""... and within these bearings (0 = straight ahead), in front of the arm."""
MIN_GAP_MM = 25.0
"""Free space between random blocks, so fingers fit between them."""
MAX_BLOCKS = 8
"""The most random blocks that always fit there that far apart."""


def random_scene(
    seed: int, blocks: int = 5, colors: Sequence[str] = ("red", "green", "blue"),
    *, size_mm: float = DEFAULT_BLOCK_MM, bins: bool = True,
    radius_mm: tuple[float, float] = PLACE_RADIUS_MM,
) -> Scene:
    """A seeded scene of ``blocks`` cubes with random positions, yaws and colours.

    Blocks stand in front of the arm, ``radius_mm`` from the base axis (by default where
    a top-down grasp reaches them) within ``PLACE_BEARING_DEG``, ``MIN_GAP_MM`` apart;
    every colour appears at least once when there are enough blocks; one bin per colour.
    """
    check_int_range("seed", seed, 0, 2**32 - 1)
    check_int_range("blocks", blocks, 0, MAX_BLOCKS)
    colors = list(colors)
    unknown = [c for c in colors if c not in COLORS]
    if not colors or unknown:
        raise ConfigError(f"colors {unknown or colors!r}: allowed {', '.join(COLORS)}")
    r_lo, r_hi = radius_mm
    if not (math.isfinite(r_lo) and math.isfinite(r_hi) and 0 <= r_lo < r_hi <= 1000):
        raise ConfigError(f"radius_mm = {radius_mm!r}: give (near, far) with "
                          "0 <= near < far <= 1000 mm")
    rng = random.Random(seed)
    chosen = [colors[i % len(colors)] for i in range(blocks)]
    rng.shuffle(chosen)
    trays = tuple(b for b in DEFAULT_BINS if b.color in colors) if bins else ()
    b_lo, b_hi = PLACE_BEARING_DEG
    for _attempt in range(200):  # an unlucky early block can leave no room: start again
        placed: list[Block] = []
        for color in chosen:
            for _ in range(300):
                r = math.sqrt(rng.uniform(r_lo**2, r_hi**2))  # uniform over the area
                bearing = math.radians(rng.uniform(b_lo, b_hi))
                x, y = r * math.cos(bearing), r * math.sin(bearing)
                if all(math.hypot(x - b.x_mm, y - b.y_mm)
                       >= size_mm * math.sqrt(2) + MIN_GAP_MM for b in placed) and all(
                        math.hypot(x - t.x_mm, y - t.y_mm)
                        >= (t.size_mm + size_mm) * math.sqrt(0.5) + MIN_GAP_MM for t in trays):
                    placed.append(Block(color, round(x, 2), round(y, 2),
                                        round(rng.uniform(-45.0, 45.0), 2), size_mm))
                    break
            else:
                break
        if len(placed) == blocks:
            break
    else:
        raise ConfigError(f"cannot place {blocks} blocks {MIN_GAP_MM:g} mm apart in "
                          "the reachable area; ask for fewer")
    return Scene(blocks=tuple(placed), bins=trays, seed=seed, source=f"seed {seed}")


# ---------------------------------------------------------------------- files

def _table_from(data: dict[str, Any], cls: Any, key: str, source: str) -> Any:
    fields = cls.__dataclass_fields__
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(f"scene {source}: {key}: unknown key(s) {unknown}; "
                          f"known: {sorted(fields)}")
    try:
        return cls(**data)
    except TypeError as exc:  # a missing required key
        raise ConfigError(f"scene {source}: {key}: {exc}") from None


def scene_from_toml(text: str, source: str = "<string>") -> Scene:
    """Parse a scene file's text (``format = "busarm.scene"``, ``version = 1``)."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"scene {source}: not valid TOML: {exc}") from None
    if data.get("format") != SCENE_FORMAT or data.get("version") != SCENE_VERSION:
        raise ConfigError(f"scene {source}: expected format = {SCENE_FORMAT!r} and version = "
                          f"{SCENE_VERSION}, got {data.get('format')!r} {data.get('version')!r}")
    known = {"format", "version", "table", "blocks", "bins", "boards", "seed"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigError(f"scene {source}: unknown key(s) {unknown}; known: {sorted(known)}")

    def items(key: str) -> list[dict[str, Any]]:
        value = data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise ConfigError(f"scene {source}: {key} must be an array of tables ([[{key}]])")
        return value

    table = data.get("table", {})
    if not isinstance(table, dict):
        raise ConfigError(f"scene {source}: table must be a table ([table])")
    seed = data.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise ConfigError(f"scene {source}: seed = {seed!r} must be an integer")
    return Scene(
        blocks=tuple(_table_from(b, Block, f"blocks[{i}]", source)
                     for i, b in enumerate(items("blocks"))),
        bins=tuple(_table_from(b, Bin, f"bins[{i}]", source) for i, b in enumerate(items("bins"))),
        boards=tuple(_table_from(b, Board, f"boards[{i}]", source)
                     for i, b in enumerate(items("boards"))),
        table=_table_from(table, Table, "table", source),
        seed=seed,
        source=source,
    )


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read scene file {path}: {exc}") from None
    return scene_from_toml(text, str(path))


def _toml_value(value: object) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(value)


def scene_to_toml(scene: Scene) -> str:
    """The scene as a file that ``scene_from_toml`` reads back identically."""
    lines = [f'format = "{SCENE_FORMAT}"', f"version = {SCENE_VERSION}"]
    if scene.seed is not None:
        lines.append(f"seed = {scene.seed}")
    lines += ["", "[table]"]
    lines += [f"{k} = {_toml_value(getattr(scene.table, k))}"
              for k in Table.__dataclass_fields__]
    for key, items in (("blocks", scene.blocks), ("bins", scene.bins), ("boards", scene.boards)):
        for item in items:
            lines += ["", f"[[{key}]]"]
            lines += [f"{k} = {_toml_value(getattr(item, k))}"
                      for k in type(item).__dataclass_fields__]
    return "\n".join(lines) + "\n"


def save_scene(path: str | Path, scene: Scene) -> None:
    """Write ``scene`` to ``path`` atomically."""
    write_text_atomic(path, scene_to_toml(scene), "scene file")
