"""Seeded tables beyond colour: blocks of mixed sizes, look-alikes, tagged blocks.

Three families, each the same scene for the same seed (as ``busarm.twin.clutter``'s,
whose lighting they share):

- ``lookalike_scene``: 3-6 cubes of 20-45 mm in red, green and blue among 2-4 things in
  a block's colour that are not blocks (a purple or red cylinder, a green disc, a blue
  bar, a box taller than a block), the usual red, green and blue trays.
- ``sized_scene``: 4-6 cubes of 20-45 mm, every size class (``SIZE_CLASSES_MM``) there,
  and a tray per class (its ``color`` the class's name).
- ``tagged_scene``: 3-5 cubes of one size (25-35 mm), each with its own AprilTag
  (ids 0..9), for sorting by tag and stacking.

Everything stands where the arm reaches (``REACH_RADIUS_MM``; tagged blocks within
``PLACE_RADIUS_MM``, where a straight-down grasp and a stack are easy) within
``PLACE_BEARING_DEG``, clear of the trays and the base, and ``LOOKALIKE_GAP_MM`` apart:
nothing touches. A block weighs what a wooden cube of its size does.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Sequence

from busarm.errors import ConfigError
from busarm.perception.size_classes import size_class as classify
from busarm.twin.clutter import BIN_CLEARANCE_MM, clutter_lighting
from busarm.twin.footprints import Footprint, penetration_mm
from busarm.twin.scene import (
    BASE_CLEARANCE_MM,
    BLOCK_SIZE_MM,
    DEFAULT_BINS,
    MIN_GAP_MM,
    PLACE_BEARING_DEG,
    PLACE_RADIUS_MM,
    REACH_RADIUS_MM,
    SIZE_CLASSES_MM,
    Bin,
    Block,
    Distractor,
    Lighting,
    Scene,
    Table,
)
from busarm.units import check_int_range, check_range

__all__ = [
    "LOOKALIKE_BLOCKS",
    "LOOKALIKE_BLOCK_MM",
    "LOOKALIKE_COLORS",
    "LOOKALIKE_GAP_MM",
    "LOOKALIKE_KINDS",
    "SIZED_BLOCKS",
    "SIZE_CLASSES_MM",
    "SIZE_MARGIN_MM",
    "TAGGED_BLOCKS",
    "TAGGED_BLOCK_MM",
    "TAGGED_IDS",
    "WOOD_G_PER_CM3",
    "block_mass_g",
    "lookalike_scene",
    "size_bins",
    "size_class",
    "sized_scene",
    "tagged_scene",
]

LOOKALIKE_COLORS = ("red", "green", "blue")
"""The block colours of these families (the default trays')."""
LOOKALIKE_BLOCK_MM = (20.0, 45.0)
"""Block sides of the lookalike and sized families."""
LOOKALIKE_BLOCKS = (3, 6)
SIZED_BLOCKS = (4, 6)
TAGGED_BLOCKS = (3, 5)
TAGGED_BLOCK_MM = (25.0, 35.0)
TAGGED_IDS = (0, 9)
"""The tag ids a tagged scene draws from (distinct)."""
LOOKALIKE_GAP_MM = 15.0
"""The least free space between any two things (and ``BIN_CLEARANCE_MM`` to a tray)."""
SIZE_MARGIN_MM = 1.5
"""A sized scene's blocks are at least this far from a class boundary (28, 37 mm), so a
side measured a millimetre off still falls in the right class."""
WOOD_G_PER_CM3 = 0.74
"""A wooden toy cube's density (the twin's 30 mm block weighs 20 g)."""
LOOKALIKE_KINDS = ("purple cylinder", "red cylinder", "green disc", "blue bar", "box")
"""What a look-alike may be (a box in any of ``LOOKALIKE_COLORS``)."""

_Draw = Callable[[random.Random, float, float], Footprint]


def block_mass_g(size_mm: float) -> float:
    """A wooden cube's mass (g) for its side (mm), to 0.1 g."""
    return round(WOOD_G_PER_CM3 * (size_mm / 10.0) ** 3, 1)


def size_class(size_mm: float) -> str:
    """The ``SIZE_CLASSES_MM`` class of a block side (28 and 37 mm themselves are medium);
    ConfigError outside ``BLOCK_SIZE_MM``."""
    return classify(check_range("block side", size_mm, *BLOCK_SIZE_MM, "mm"))


def size_bins() -> tuple[Bin, ...]:
    """One tray per size class where the default red, green and blue trays stand
    (small, medium, large in that order)."""
    return tuple(Bin(name, b.x_mm, b.y_mm, b.size_mm, b.wall_mm)
                 for name, b in zip(SIZE_CLASSES_MM, DEFAULT_BINS, strict=False))


def _rng(seed: int, family: str, part: str) -> random.Random:
    """A stream of its own per family and part: changing one leaves the others alone."""
    return random.Random(f"busarm.lookalike:{family}:{seed}:{part}")


def _spot(rng: random.Random, radius_mm: tuple[float, float]) -> tuple[float, float]:
    """A random point within ``radius_mm`` of the base axis (uniform over the area) and
    ``PLACE_BEARING_DEG``, to 0.01 mm."""
    r = math.sqrt(rng.uniform(radius_mm[0] ** 2, radius_mm[1] ** 2))
    bearing = math.radians(rng.uniform(*PLACE_BEARING_DEG))
    return round(r * math.cos(bearing), 2), round(r * math.sin(bearing), 2)


def _clear(fp: Footprint, placed: Sequence[Footprint], bins: Sequence[Bin], table: Table,
           gap_mm: float) -> bool:
    """On the table, off the base, ``BIN_CLEARANCE_MM`` from the trays and ``gap_mm``
    from everything placed."""
    return (table.contains(fp.x_mm, fp.y_mm, fp.radius_mm)
            and fp.distance_from_mm(0.0, 0.0) >= BASE_CLEARANCE_MM + 5.0
            and all(penetration_mm(fp, b.footprint) <= -BIN_CLEARANCE_MM for b in bins)
            and all(penetration_mm(fp, o) <= -gap_mm for o in placed))


def _layout(rng: random.Random, draws: Sequence[_Draw], bins: Sequence[Bin],
            radius_mm: tuple[float, float], gap_mm: float) -> list[Footprint]:
    """Place each drawn thing (a function of the rng and a spot) where it is clear of
    everything placed before, by rejection sampling; start over if one finds no room."""
    table = Table()
    for _attempt in range(100):
        placed: list[Footprint] = []
        for draw in draws:
            for _ in range(300):
                fp = draw(rng, *_spot(rng, radius_mm))
                if _clear(fp, placed, bins, table, gap_mm):
                    placed.append(fp)
                    break
            else:
                break
        if len(placed) == len(draws):
            return placed
    raise ConfigError(f"cannot place {len(draws)} things {gap_mm:g} mm apart in reach")


def _block_draw(size_mm: float) -> _Draw:
    def draw(rng: random.Random, x: float, y: float) -> Footprint:
        return Footprint.square(x, y, size_mm, round(rng.uniform(-45.0, 45.0), 2))
    return draw


def _lookalike(kind: str, color: str, rng: random.Random) -> Distractor:
    """A look-alike of ``kind`` at the origin (placed later), sizes drawn from ``rng``."""
    def u(lo: float, hi: float) -> float:
        return round(rng.uniform(lo, hi), 1)

    if kind.endswith("cylinder"):
        d = u(30.0, 35.0)
        return Distractor("cylinder", color, 0.0, 0.0, d, d, u(35.0, 60.0), 0.0, u(20.0, 40.0))
    if kind == "green disc":
        d = u(30.0, 60.0)
        return Distractor("disc", color, 0.0, 0.0, d, d, u(3.0, 8.0), 0.0, u(5.0, 20.0))
    if kind == "blue bar":
        return Distractor("bar", color, 0.0, 0.0, u(60.0, 150.0), u(10.0, 20.0),
                          u(10.0, 20.0), 0.0, u(10.0, 30.0))
    side = u(20.0, 35.0)  # the other side square-ish: within BOX_ASPECT_MAX of it
    return Distractor("box", color, 0.0, 0.0, side, u(max(20.0, side / 1.3), min(35.0, side * 1.3)),
                      u(50.0, 80.0), 0.0, u(25.0, 60.0))


def _thing_draw(thing: Distractor) -> _Draw:
    def draw(rng: random.Random, x: float, y: float) -> Footprint:
        yaw = 0.0 if thing.is_round else round(rng.uniform(-90.0, 90.0), 2)
        if thing.is_round:
            return Footprint.disc(x, y, thing.length_mm)
        return Footprint(x, y, thing.length_mm / 2, thing.width_mm / 2, yaw)
    return draw


def _count(name: str, value: int | None, rng: random.Random, bounds: tuple[int, int]) -> int:
    return rng.randint(*bounds) if value is None else check_int_range(name, value, *bounds)


def _blocks(colors: Sequence[str], sizes: Sequence[float], fps: Sequence[Footprint],
            tags: Sequence[int | None]) -> tuple[Block, ...]:
    return tuple(Block(c, fp.x_mm, fp.y_mm, fp.yaw_deg, s, block_mass_g(s), t)
                 for c, s, fp, t in zip(colors, sizes, fps, tags, strict=True))


def _size(rng: random.Random, lo: float, hi: float) -> float:
    return round(rng.uniform(lo, hi) * 2) / 2  # to 0.5 mm


def lookalike_scene(seed: int, blocks: int | None = None, *, lighting: bool = True) -> Scene:
    """A seeded table of ``blocks`` cubes (3..6; None = at random) of 20-45 mm in red,
    green and blue, among 2-4 look-alikes of ``LOOKALIKE_KINDS`` in block colours; the
    red, green and blue trays; ``lighting``: clutter's light of the seed (else the usual).
    """
    check_int_range("seed", seed, 0, 2**32 - 1)
    rng = _rng(seed, "lookalike", "blocks")
    count = _count("blocks", blocks, rng, LOOKALIKE_BLOCKS)
    sizes = [_size(rng, *LOOKALIKE_BLOCK_MM) for _ in range(count)]
    colors = [rng.choice(LOOKALIKE_COLORS) for _ in range(count)]
    things_rng = _rng(seed, "lookalike", "things")
    kinds = things_rng.sample(LOOKALIKE_KINDS, things_rng.randint(2, 4))
    things = [_lookalike(k, k.split()[0] if k != "box" else things_rng.choice(LOOKALIKE_COLORS),
                         things_rng) for k in kinds]
    trays = tuple(b for b in DEFAULT_BINS if b.color in LOOKALIKE_COLORS)
    fps = _layout(_rng(seed, "lookalike", "layout"),
                  [*map(_block_draw, sizes), *map(_thing_draw, things)], trays,
                  REACH_RADIUS_MM, LOOKALIKE_GAP_MM)
    placed = [Distractor(t.shape, t.color, fp.x_mm, fp.y_mm, t.length_mm, t.width_mm,
                         t.height_mm, fp.yaw_deg, t.mass_g)
              for t, fp in zip(things, fps[count:], strict=True)]
    return Scene(blocks=_blocks(colors, sizes, fps[:count], [None] * count), bins=trays,
                 seed=seed, source=f"lookalike {seed}", distractors=tuple(placed),
                 lighting=clutter_lighting(seed) if lighting else Lighting())


def sized_scene(seed: int, *, lighting: bool = True) -> Scene:
    """A seeded table of 4-6 cubes of 20-45 mm in red, green and blue, every size class
    there, each side at least ``SIZE_MARGIN_MM`` from a class boundary; a tray per class
    (``size_bins``)."""
    check_int_range("seed", seed, 0, 2**32 - 1)
    rng = _rng(seed, "sized", "blocks")
    count = rng.randint(*SIZED_BLOCKS)
    classes = [*SIZE_CLASSES_MM, *(rng.choice(list(SIZE_CLASSES_MM)) for _ in range(count - 3))]
    rng.shuffle(classes)
    sizes = []
    for name in classes:
        lo, hi = SIZE_CLASSES_MM[name]
        lo, hi = max(lo, LOOKALIKE_BLOCK_MM[0]), min(hi, LOOKALIKE_BLOCK_MM[1])
        sizes.append(_size(rng, lo + SIZE_MARGIN_MM if lo > LOOKALIKE_BLOCK_MM[0] else lo,
                           hi - SIZE_MARGIN_MM if hi < LOOKALIKE_BLOCK_MM[1] else hi))
    colors = [rng.choice(LOOKALIKE_COLORS) for _ in range(count)]
    trays = size_bins()
    fps = _layout(_rng(seed, "sized", "layout"), [*map(_block_draw, sizes)], trays,
                  REACH_RADIUS_MM, LOOKALIKE_GAP_MM)
    return Scene(blocks=_blocks(colors, sizes, fps, [None] * count), bins=trays, seed=seed,
                 source=f"sized {seed}",
                 lighting=clutter_lighting(seed) if lighting else Lighting())


def tagged_scene(seed: int, blocks: int | None = None, *, lighting: bool = True) -> Scene:
    """A seeded table of ``blocks`` cubes (3..5; None = at random) of one side (25-35 mm)
    in red, green and blue, each with its own tag id of ``TAGGED_IDS``, ``MIN_GAP_MM``
    apart within ``PLACE_RADIUS_MM``; the red, green and blue trays."""
    check_int_range("seed", seed, 0, 2**32 - 1)
    rng = _rng(seed, "tagged", "blocks")
    count = _count("blocks", blocks, rng, TAGGED_BLOCKS)
    size = _size(rng, *TAGGED_BLOCK_MM)
    tags = rng.sample(range(TAGGED_IDS[0], TAGGED_IDS[1] + 1), count)
    colors = [rng.choice(LOOKALIKE_COLORS) for _ in range(count)]
    trays = tuple(b for b in DEFAULT_BINS if b.color in LOOKALIKE_COLORS)
    fps = _layout(_rng(seed, "tagged", "layout"), [_block_draw(size)] * count, trays,
                  PLACE_RADIUS_MM, MIN_GAP_MM)
    return Scene(blocks=_blocks(colors, [size] * count, fps, tags), bins=trays, seed=seed,
                 source=f"tagged {seed}",
                 lighting=clutter_lighting(seed) if lighting else Lighting())
