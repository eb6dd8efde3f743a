"""What stands on the twin's table: blocks, bins, calibration boards and distractors (things
that are not blocks), in millimetres, and how the room is lit.

A scene is data (``Scene``), read from a TOML or JSON file or drawn from a seed
(``random_scene``; ``busarm.twin.clutter.clutter_scene`` for tables like real ones),
always validated: a block off the table, interpenetrating another one, a bin or a
distractor, or of an unknown colour is refused with the key and the allowed range.
Touching is allowed (``busarm.twin.footprints``). Positions are in the arm's base frame
(x forward, y left, z up; the table top at the arm config's ``table_z_mm``). Blocks are
cubes standing on the table, turned by ``yaw_deg`` about z, an AprilTag on top if they
have a ``tag_id`` (``busarm.twin.block_tags``). ``busarm.twin.lookalike`` draws tables of
mixed sizes, tagged blocks and look-alikes.
"""

from __future__ import annotations

import json
import math
import random
import sys
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.perception.size_classes import SIZE_CLASSES_MM  # a bin's name may be a class's
from busarm.twin.footprints import TOUCH_TOLERANCE_MM, Footprint, penetration_mm
from busarm.units import check_int_range, check_range, listing

__all__ = [
    "BASE_CLEARANCE_MM",
    "BLOCK_SIZE_MM",
    "BOARD_KINDS",
    "BOX_ASPECT_MAX",
    "COLORS",
    "DEFAULT_BINS",
    "DEFAULT_BLOCK_MM",
    "DISTRACTOR_COLORS",
    "DISTRACTOR_SIZES_MM",
    "LIGHTING_RANGES",
    "MAX_BLOCKS",
    "MIN_GAP_MM",
    "PLACE_BEARING_DEG",
    "PLACE_RADIUS_MM",
    "REACH_RADIUS_MM",
    "SCENE_FORMAT",
    "SCENE_VERSION",
    "SCENE_WRITERS",
    "SIZE_CLASSES_MM",
    "TAG_IDS",
    "Bin",
    "Block",
    "Board",
    "Distractor",
    "Lighting",
    "Scene",
    "Table",
    "check_scene",
    "load_scene",
    "random_scene",
    "save_scene",
    "scene_from_json",
    "scene_from_toml",
    "scene_to_json",
    "scene_to_toml",
]


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

DISTRACTOR_COLORS: dict[str, tuple[float, float, float]] = {
    "grey": (0.40, 0.40, 0.42),
    "white": (0.92, 0.92, 0.90),
    "brown": (0.30, 0.20, 0.14),
    "purple": (0.42, 0.18, 0.52),
}
"""Colours of things that are not blocks, none of them a block colour. Purple still lies
inside busarm.vision's default blue threshold, as a violet pen would: only its shape
tells it from a block. A distractor may also have a block colour (``COLORS``): a
look-alike, in a block's colour but not a block."""

DISTRACTOR_SIZES_MM: dict[str, dict[str, tuple[float, float]]] = {
    "cylinder": {"length_mm": (20.0, 100.0), "height_mm": (30.0, 120.0)},
    "disc": {"length_mm": (20.0, 120.0), "height_mm": (1.0, 8.0)},
    "bar": {"length_mm": (60.0, 250.0), "width_mm": (5.0, 25.0), "height_mm": (5.0, 25.0)},
    "box": {"length_mm": (20.0, 40.0), "width_mm": (20.0, 40.0), "height_mm": (50.0, 90.0)},
}
"""Distractor shapes and their sizes: an upright cylinder (a cup, a glue stick), a flat
disc (a coaster, a coin), a bar lying down (a pen, a ruler), a small box standing up,
taller than a block (a juice carton); none is a cube. A round shape's footprint is a
circle of diameter ``length_mm`` (= ``width_mm``); a box's is square-ish (its longer side
at most ``BOX_ASPECT_MAX`` times the shorter)."""
BOX_ASPECT_MAX = 1.5

DEFAULT_BLOCK_MM = 30.0
BLOCK_SIZE_MM = (10.0, 60.0)
"""Block sides the twin builds (toy blocks are 25-40 mm)."""
BOARD_KINDS = ("chessboard", "charuco", "tags")
TAG_IDS = (0, 586)
"""The AprilTag 36h11 ids a block may carry (``Block.tag_id``)."""


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
    """A cube of ``size_mm`` standing on the table, centred at (x, y), turned by yaw;
    ``tag_id``: the AprilTag 36h11 printed on its top face (None: a plain block)."""

    color: str
    x_mm: float
    y_mm: float
    yaw_deg: float = 0.0
    size_mm: float = DEFAULT_BLOCK_MM
    mass_g: float = 20.0
    tag_id: int | None = None

    @property
    def radius_mm(self) -> float:
        """Half the diagonal: no part of the block is farther from its centre axis."""
        return self.size_mm * math.sqrt(0.5)

    @property
    def footprint(self) -> Footprint:
        """The square it stands on."""
        return Footprint.square(self.x_mm, self.y_mm, self.size_mm, self.yaw_deg)


@dataclass(frozen=True)
class Bin:
    """An open tray for blocks of ``color`` (or of a ``SIZE_CLASSES_MM`` size class): outer
    side ``size_mm``, walls ``wall_mm`` high."""

    color: str
    x_mm: float
    y_mm: float
    size_mm: float = 90.0
    wall_mm: float = 12.0

    @property
    def footprint(self) -> Footprint:
        """Its outer square (nothing may stand in a wall; a block may stand against one)."""
        return Footprint.square(self.x_mm, self.y_mm, self.size_mm)


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
class Distractor:
    """Something on the table that is not a block, for a sorter to leave alone.

    ``shape`` is one of ``DISTRACTOR_SIZES_MM`` (its sizes' ranges), ``color`` one of
    ``DISTRACTOR_COLORS`` or of ``COLORS`` (a look-alike). ``length_mm`` x ``width_mm``
    is its footprint, centred at (x, y) and turned by ``yaw_deg``; a cylinder's or a
    disc's diameter is both.
    In the twin it is a free body named ``distractor<i>`` (i its index in the scene).
    """

    shape: str
    color: str
    x_mm: float
    y_mm: float
    length_mm: float
    width_mm: float
    height_mm: float
    yaw_deg: float = 0.0
    mass_g: float = 30.0

    @property
    def is_round(self) -> bool:
        return self.shape in ("cylinder", "disc")

    @property
    def footprint(self) -> Footprint:
        if self.is_round:
            return Footprint.disc(self.x_mm, self.y_mm, self.length_mm)
        return Footprint(self.x_mm, self.y_mm, self.length_mm / 2, self.width_mm / 2,
                         self.yaw_deg)


LIGHTING_RANGES: dict[str, tuple[float, float]] = {
    "intensity": (0.4, 1.6),
    "key_azimuth_deg": (-180.0, 180.0),
    "key_elevation_deg": (15.0, 90.0),
    "key_share": (0.0, 0.8),
    "color_temp_k": (2700.0, 6500.0),
}
"""What a room with a desk lamp or a window gives (see ``Lighting``)."""


@dataclass(frozen=True)
class Lighting:
    """How the table is lit: the room's light and its key light (a desk lamp, a window).

    ``intensity`` scales every light (1 = the twin's usual room); ``key_share`` is the
    key light's part of the light (0.2 = no stronger than the room's four other lights,
    more for a lamp close by); it shines from ``key_azimuth_deg`` (bearing, 0 = from
    beyond the table's far edge, +x) and ``key_elevation_deg`` above the table (90 =
    straight down); ``color_temp_k`` tints all of it as the camera sees it, 5000 K
    neutral, 2700 K a warm desk lamp, 6500 K daylight from a window (a camera's white
    balance takes most of that away: ``busarm.twin.clutter`` draws 4500-5800 K). The
    defaults are the twin's lighting from before there was this.
    """

    intensity: float = 1.0
    key_azimuth_deg: float = 0.0
    key_elevation_deg: float = 90.0
    key_share: float = 0.2
    color_temp_k: float = 5000.0


@dataclass(frozen=True)
class Scene:
    """Everything on the table, and the light on it."""

    blocks: tuple[Block, ...] = ()
    bins: tuple[Bin, ...] = ()
    boards: tuple[Board, ...] = ()
    table: Table = field(default_factory=Table)
    seed: int | None = None
    source: str = "<memory>"
    distractors: tuple[Distractor, ...] = ()
    lighting: Lighting = field(default_factory=Lighting)

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


def _check_color(scene: Scene, key: str, color: str, allowed: dict[str, Any]) -> None:
    if color not in allowed:
        raise ConfigError(_where(scene, f"{key}.color = {color!r}; allowed: "
                                        f"{', '.join(allowed)}"))


def check_scene(scene: Scene) -> None:
    """Raise ConfigError naming the first thing in ``scene`` that cannot stand there."""
    t = scene.table
    for name in ("x_min_mm", "x_max_mm", "y_min_mm", "y_max_mm"):
        _finite(scene, f"table.{name}", getattr(t, name), -2000.0, 2000.0)
    if not (t.x_min_mm < -BASE_CLEARANCE_MM and t.x_max_mm > BASE_CLEARANCE_MM
            and t.y_min_mm < -BASE_CLEARANCE_MM and t.y_max_mm > BASE_CLEARANCE_MM):
        raise ConfigError(_where(scene, "the table must extend at least "
                                        f"{BASE_CLEARANCE_MM:g} mm around the arm base (0, 0)"))
    footprints = [*_check_blocks(scene), *_check_bins(scene), *_check_distractors(scene)]
    for i, board in enumerate(scene.boards):
        key = f"boards[{i}]"
        if board.kind not in BOARD_KINDS:
            raise ConfigError(_where(scene, f"{key}.kind = {board.kind!r}; allowed: "
                                            f"{', '.join(BOARD_KINDS)}"))
        for name in ("x_mm", "y_mm"):
            _finite(scene, f"{key}.{name}", getattr(board, name), -2000.0, 2000.0)
        _finite(scene, f"{key}.yaw_deg", board.yaw_deg, -360.0, 360.0)
    for name, (lo, hi) in LIGHTING_RANGES.items():
        _finite(scene, f"lighting.{name}", getattr(scene.lighting, name), lo, hi)
    _check_overlaps(scene, footprints)


def _check_blocks(scene: Scene) -> list[tuple[str, Footprint]]:
    t, out = scene.table, []
    for i, b in enumerate(scene.blocks):
        key = f"blocks[{i}]"
        _check_color(scene, key, b.color, COLORS)
        _finite(scene, f"{key}.size_mm", b.size_mm, *BLOCK_SIZE_MM)
        _finite(scene, f"{key}.mass_g", b.mass_g, 1.0, 500.0)
        _finite(scene, f"{key}.yaw_deg", b.yaw_deg, -360.0, 360.0)
        if b.tag_id is not None:
            check_int_range(_where(scene, f"{key}.tag_id (AprilTag 36h11)"), b.tag_id,
                            *TAG_IDS)
        x = _finite(scene, f"{key}.x_mm", b.x_mm, -2000.0, 2000.0)
        y = _finite(scene, f"{key}.y_mm", b.y_mm, -2000.0, 2000.0)
        if not t.contains(x, y, b.radius_mm):
            raise ConfigError(_where(
                scene, f"{key} at ({x:g}, {y:g}) mm is off the table: its centre must lie in "
                f"x {t.x_min_mm + b.radius_mm:g}..{t.x_max_mm - b.radius_mm:g}, "
                f"y {t.y_min_mm + b.radius_mm:g}..{t.y_max_mm - b.radius_mm:g} mm"))
        _check_base(scene, key, x, y, b.radius_mm)
        out.append((key, b.footprint))
    return out


def _check_bins(scene: Scene) -> list[tuple[str, Footprint]]:
    out = []
    for i, bin_ in enumerate(scene.bins):
        key = f"bins[{i}]"
        _check_color(scene, key, bin_.color, {**COLORS, **SIZE_CLASSES_MM})
        size = _finite(scene, f"{key}.size_mm", bin_.size_mm, 40.0, 200.0)
        _finite(scene, f"{key}.wall_mm", bin_.wall_mm, 2.0, 60.0)
        x = _finite(scene, f"{key}.x_mm", bin_.x_mm, -2000.0, 2000.0)
        y = _finite(scene, f"{key}.y_mm", bin_.y_mm, -2000.0, 2000.0)
        if not scene.table.contains(x, y, size / 2):
            raise ConfigError(_where(scene, f"{key} at ({x:g}, {y:g}) mm is off the table"))
        _check_base(scene, key, x, y, size * math.sqrt(0.5))
        out.append((key, bin_.footprint))
    return out


def _check_base(scene: Scene, key: str, x: float, y: float, radius_mm: float) -> None:
    if math.hypot(x, y) < BASE_CLEARANCE_MM + radius_mm * 0.5:
        raise ConfigError(_where(scene, f"{key} at ({x:g}, {y:g}) mm stands on the arm "
                                        f"base: keep it {BASE_CLEARANCE_MM:g} mm from (0, 0)"))


def _check_distractors(scene: Scene) -> list[tuple[str, Footprint]]:
    out = []
    for i, d in enumerate(scene.distractors):
        key = f"distractors[{i}]"
        if d.shape not in DISTRACTOR_SIZES_MM:
            raise ConfigError(_where(scene, f"{key}.shape = {d.shape!r}; allowed: "
                                            f"{', '.join(DISTRACTOR_SIZES_MM)}"))
        _check_color(scene, key, d.color, {**DISTRACTOR_COLORS, **COLORS})
        for name, (lo, hi) in DISTRACTOR_SIZES_MM[d.shape].items():
            _finite(scene, f"{key}.{name} of a {d.shape}", getattr(d, name), lo, hi)
        if d.shape == "box" and max(d.length_mm, d.width_mm) > BOX_ASPECT_MAX * min(
                d.length_mm, d.width_mm):
            raise ConfigError(_where(scene, f"{key} is a box of {d.length_mm!r} x "
                                            f"{d.width_mm!r} mm: its longer side may be at most "
                                            f"{BOX_ASPECT_MAX:g} x the shorter"))
        if d.is_round and d.width_mm != d.length_mm:
            raise ConfigError(_where(scene, f"{key}.width_mm = {d.width_mm!r}: a {d.shape} is "
                                            f"round, give its diameter as both length_mm and "
                                            f"width_mm ({d.length_mm!r})"))
        _finite(scene, f"{key}.mass_g", d.mass_g, 1.0, 1000.0)
        _finite(scene, f"{key}.yaw_deg", d.yaw_deg, -360.0, 360.0)
        x = _finite(scene, f"{key}.x_mm", d.x_mm, -2000.0, 2000.0)
        y = _finite(scene, f"{key}.y_mm", d.y_mm, -2000.0, 2000.0)
        fp = d.footprint
        if not scene.table.contains(x, y, fp.radius_mm):
            raise ConfigError(_where(scene, f"{key} at ({x:g}, {y:g}) mm hangs off the table"))
        if fp.distance_from_mm(0.0, 0.0) < BASE_CLEARANCE_MM:
            raise ConfigError(_where(scene, f"{key} at ({x:g}, {y:g}) mm comes within "
                                            f"{BASE_CLEARANCE_MM:g} mm of the arm base (0, 0)"))
        out.append((key, fp))
    return out


def _check_overlaps(scene: Scene, footprints: list[tuple[str, Footprint]]) -> None:
    """Refuse the first pair that interpenetrates (touching is fine)."""
    for j, (key, a) in enumerate(footprints):
        for key2, b in footprints[j + 1:]:
            if abs(a.x_mm - b.x_mm) > a.radius_mm + b.radius_mm or abs(
                    a.y_mm - b.y_mm) > a.radius_mm + b.radius_mm:
                continue  # far apart: skip the exact test
            depth = penetration_mm(a, b)
            if depth > TOUCH_TOLERANCE_MM:
                raise ConfigError(_where(
                    scene, f"{key} at ({a.x_mm:g}, {a.y_mm:g}) mm and {key2} at "
                    f"({b.x_mm:g}, {b.y_mm:g}) mm overlap by {depth:.2f} mm; they may touch "
                    f"but not interpenetrate more than {TOUCH_TOLERANCE_MM:g} mm"))


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
        raise ConfigError(f"colors {', '.join(unknown or colors)}: allowed {', '.join(COLORS)}")
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
        raise ConfigError(f"scene {source}: {key}: unknown key(s) {listing(unknown)}; "
                          f"known: {listing(sorted(fields))}")
    try:
        return cls(**data)
    except TypeError as exc:  # a missing required key
        raise ConfigError(f"scene {source}: {key}: {exc}") from None


def scene_from_toml(text: str, source: str = "<string>") -> Scene:
    """Parse a scene file's text (``format = "busarm.scene"``, ``version = 1``).

    Besides ``[table]``, ``[[blocks]]``, ``[[bins]]`` and ``[[boards]]``, a file may hold
    ``[[distractors]]`` (the fields of ``Distractor``) and a ``[lighting]`` table (the
    fields of ``Lighting``; absent = the usual light).
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"scene {source}: not valid TOML: {exc}") from None
    return _scene_from_data(data, source)


def scene_from_json(text: str, source: str = "<string>") -> Scene:
    """Parse a scene file written as JSON: the same keys as the TOML file's, with
    ``blocks``, ``bins``, ``boards`` and ``distractors`` as arrays of objects."""
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise ConfigError(f"scene {source}: not valid JSON: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"scene {source}: expected a JSON object, got "
                          f"{type(data).__name__}")
    return _scene_from_data(data, source)


def _scene_from_data(data: dict[str, Any], source: str) -> Scene:
    if data.get("format") != SCENE_FORMAT or data.get("version") != SCENE_VERSION:
        raise ConfigError(f"scene {source}: expected format = {SCENE_FORMAT!r} and version = "
                          f"{SCENE_VERSION}, got {data.get('format')!r} {data.get('version')!r}")
    known = {"format", "version", "table", "blocks", "bins", "boards", "distractors",
             "lighting", "seed"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ConfigError(f"scene {source}: unknown key(s) {listing(unknown)}; known: "
                          f"{listing(sorted(known))}")

    def items(key: str) -> list[dict[str, Any]]:
        value = data.get(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise ConfigError(f"scene {source}: {key} must be an array of tables ([[{key}]])")
        return value

    def table(key: str) -> dict[str, Any]:
        value = data.get(key, {})
        if not isinstance(value, dict):
            raise ConfigError(f"scene {source}: {key} must be a table ([{key}])")
        return value

    seed = data.get("seed")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int)):
        raise ConfigError(f"scene {source}: seed = {seed!r} must be an integer")
    return Scene(
        blocks=tuple(_table_from(b, Block, f"blocks[{i}]", source)
                     for i, b in enumerate(items("blocks"))),
        bins=tuple(_table_from(b, Bin, f"bins[{i}]", source) for i, b in enumerate(items("bins"))),
        boards=tuple(_table_from(b, Board, f"boards[{i}]", source)
                     for i, b in enumerate(items("boards"))),
        table=_table_from(table("table"), Table, "table", source),
        seed=seed,
        source=source,
        distractors=tuple(_table_from(d, Distractor, f"distractors[{i}]", source)
                          for i, d in enumerate(items("distractors"))),
        lighting=_table_from(table("lighting"), Lighting, "lighting", source),
    )


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file: JSON if it is named ``.json``, else TOML."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read scene file {path}: {exc}") from None
    if path.suffix.lower() == ".json":
        return scene_from_json(text, str(path))
    return scene_from_toml(text, str(path))  # .toml, and files named any other way


def _toml_value(value: object) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    return repr(value)


def _fields(item: Any) -> dict[str, Any]:
    """A dataclass's fields but those that are None (TOML has no null; absent = None)."""
    return {k: v for k, v in asdict(item).items() if v is not None}


def scene_to_toml(scene: Scene) -> str:
    """The scene as a file that ``scene_from_toml`` reads back identically."""
    lines = [f'format = "{SCENE_FORMAT}"', f"version = {SCENE_VERSION}"]
    if scene.seed is not None:
        lines.append(f"seed = {scene.seed}")
    lines += ["", "[table]"]
    lines += [f"{k} = {_toml_value(getattr(scene.table, k))}"
              for k in Table.__dataclass_fields__]
    if scene.lighting != Lighting():  # a file for the usual light stays as it was
        lines += ["", "[lighting]"]
        lines += [f"{k} = {_toml_value(getattr(scene.lighting, k))}"
                  for k in Lighting.__dataclass_fields__]
    for key, items in (("blocks", scene.blocks), ("bins", scene.bins), ("boards", scene.boards),
                       ("distractors", scene.distractors)):
        for item in items:
            lines += ["", f"[[{key}]]"]
            lines += [f"{k} = {_toml_value(v)}" for k, v in _fields(item).items()]
    return "\n".join(lines) + "\n"


def scene_to_json(scene: Scene) -> str:
    """The scene as JSON that ``scene_from_json`` reads back identically."""
    data: dict[str, Any] = {"format": SCENE_FORMAT, "version": SCENE_VERSION}
    if scene.seed is not None:
        data["seed"] = scene.seed
    data["table"] = asdict(scene.table)
    if scene.lighting != Lighting():
        data["lighting"] = asdict(scene.lighting)
    for key, items in (("blocks", scene.blocks), ("bins", scene.bins), ("boards", scene.boards),
                       ("distractors", scene.distractors)):
        if items:
            data[key] = [_fields(item) for item in items]
    return json.dumps(data, indent=1) + "\n"


SCENE_WRITERS = {".toml": scene_to_toml, ".json": scene_to_json}
"""How a scene file is written, by its name's extension."""


def save_scene(path: str | Path, scene: Scene) -> None:
    """Write ``scene`` to ``path`` atomically, as TOML or JSON by its extension
    (ConfigError for any other, naming the allowed ones)."""
    suffix = Path(path).suffix.lower()
    writer = SCENE_WRITERS.get(suffix)
    if writer is None:
        raise ConfigError(f"scene file {path}: extension {suffix or '(none)'!r} is not one of "
                          f"{', '.join(SCENE_WRITERS)}")
    write_text_atomic(path, writer(scene), "scene file")
