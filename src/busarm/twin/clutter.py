"""Seeded tables like real ones: blocks in rows and clusters, touching or a few mm apart,
things that are not blocks among them, and the light of a desk lamp or a window.

``clutter_scene(seed)`` draws such a table; the same seed gives the same scene. Blocks
come in groups, each turned by its own yaw: single blocks, touching pairs, rows of 2-4
with 0-15 mm gaps, 2x2 squares (touching, or with gaps) and staggered clusters of 3,
anywhere the arm reaches (``REACH_RADIUS_MM`` within ``PLACE_BEARING_DEG``, some right
at its edge), clear of the bins and the base. Blocks drawn as touching stand
``TOUCH_GAP_MM`` apart, so that rounding to 0.01 mm never makes them interpenetrate.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence

from busarm.errors import ConfigError
from busarm.twin.footprints import penetration_mm
from busarm.twin.scene import (
    BASE_CLEARANCE_MM,
    COLORS,
    DEFAULT_BINS,
    DEFAULT_BLOCK_MM,
    DISTRACTOR_COLORS,
    PLACE_BEARING_DEG,
    REACH_RADIUS_MM,
    Bin,
    Block,
    Distractor,
    Lighting,
    Scene,
    Table,
)
from busarm.units import check_int_range, check_range

__all__ = [
    "BIN_CLEARANCE_MM",
    "CLUTTER_BLOCK_MM",
    "CLUTTER_DEFAULT_BLOCKS",
    "CLUTTER_DISTRACTOR_COLORS",
    "CLUTTER_LIGHTING",
    "CLUTTER_MAX_BLOCKS",
    "DISTRACTOR_GAP_MM",
    "EDGE_BAND_MM",
    "MAX_DISTRACTORS",
    "MAX_GROUP_GAP_MM",
    "TOUCH_GAP_MM",
    "Offsets",
    "clutter_lighting",
    "clutter_scene",
]


CLUTTER_MAX_BLOCKS = 12
CLUTTER_DEFAULT_BLOCKS = 8
CLUTTER_BLOCK_MM = (25.0, 40.0)
"""Block sides a clutter scene may have (toy blocks)."""
MAX_GROUP_GAP_MM = 15.0
"""The widest gap between neighbours in a row or cluster."""
TOUCH_GAP_MM = 0.03
"""How far apart blocks drawn as touching stand: touching, to the twin and to the eye."""
BIN_CLEARANCE_MM = 20.0
"""No block nearer a bin than this (a finger fits between them)."""
DISTRACTOR_GAP_MM = 3.0
"""No distractor nearer than this to a block, a bin or another distractor."""
MAX_DISTRACTORS = 4
CLUTTER_DISTRACTOR_COLORS = tuple(c for c in DISTRACTOR_COLORS if c != "purple")
"""The colours the family's distractors come in: purple lies inside the default blue range
(busarm/vision/configs/colors.toml), and the locator does not yet tell a purple cup from a
blue block by its shape; a scene file may still have purple things."""
"""The most distractors a clutter scene may ask for."""
EDGE_BAND_MM = 25.0
"""A group is sometimes put this close to the far edge of the reach."""
CLUTTER_LIGHTING: dict[str, tuple[float, float]] = {
    "intensity": (0.8, 1.1),
    "key_azimuth_deg": (-180.0, 180.0),
    "key_elevation_deg": (30.0, 90.0),
    "key_share": (0.2, 0.35),
    "color_temp_k": (4500.0, 5800.0),
}
"""The lights clutter scenes draw from (a part of ``LIGHTING_RANGES``)."""

Offsets = list[tuple[float, float]]


def _rng(seed: int, part: str) -> random.Random:
    """A stream of its own per part of the scene: changing one leaves the others alone."""
    return random.Random(f"busarm.clutter:{seed}:{part}")


def _gap(rng: random.Random) -> float:
    """A gap between neighbours: touching a third of the time, else 0.5-15 mm."""
    if rng.random() < 0.35:
        return TOUCH_GAP_MM
    return round(rng.uniform(0.5, MAX_GROUP_GAP_MM), 1)


def _group_offsets(rng: random.Random, remaining: int, size: float) -> Offsets:
    """Block centres of one group in its own frame, centred on (0, 0)."""
    kinds = [("single", 0.25), ("pair", 0.2), ("row", 0.25), ("square", 0.15),
             ("cluster", 0.15)]
    need = {"single": 1, "pair": 2, "row": 2, "square": 4, "cluster": 3}
    kinds = [(k, w) for k, w in kinds if need[k] <= remaining]
    kind = rng.choices([k for k, _ in kinds], [w for _, w in kinds])[0]
    offsets: Offsets = [(0.0, 0.0)]
    if kind == "pair":  # touching, one slid along the other's face
        offsets.append((size + TOUCH_GAP_MM, rng.uniform(-size / 2, size / 2)))
    elif kind == "row":
        for _ in range(rng.randint(2, min(4, remaining)) - 1):
            offsets.append((offsets[-1][0] + size + _gap(rng), rng.uniform(-3.0, 3.0)))
    elif kind == "square":
        touching = rng.random() < 0.6
        gx = TOUCH_GAP_MM if touching else _gap(rng)
        gy = TOUCH_GAP_MM if touching else _gap(rng)
        offsets = [(i * (size + gx), j * (size + gy)) for i in (0, 1) for j in (0, 1)]
    elif kind == "cluster":  # two side by side, a third on the next row, shifted
        offsets.append((size + _gap(rng), 0.0))
        offsets.append((rng.uniform(0.0, size), size + _gap(rng)))
    mx = sum(x for x, _ in offsets) / len(offsets)
    my = sum(y for _, y in offsets) / len(offsets)
    return [(x - mx, y - my) for x, y in offsets]


def _anchor(rng: random.Random) -> tuple[float, float]:
    """Where a group's centre goes: anywhere in reach, sometimes right at its far edge."""
    r_lo, r_hi = REACH_RADIUS_MM
    if rng.random() < 0.3:
        r = rng.uniform(r_hi - EDGE_BAND_MM, r_hi)
    else:
        r = math.sqrt(rng.uniform(r_lo**2, r_hi**2))  # uniform over the area
    bearing = math.radians(rng.uniform(*PLACE_BEARING_DEG))
    return r * math.cos(bearing), r * math.sin(bearing)


def _fits(block: Block, placed: Sequence[Block], bins: Sequence[Bin], table: Table) -> bool:
    """In reach, on the table, clear of the bins and not into any block placed."""
    r = math.hypot(block.x_mm, block.y_mm)
    bearing = math.degrees(math.atan2(block.y_mm, block.x_mm))
    if not (REACH_RADIUS_MM[0] <= r <= REACH_RADIUS_MM[1]
            and PLACE_BEARING_DEG[0] <= bearing <= PLACE_BEARING_DEG[1]
            and r >= BASE_CLEARANCE_MM + block.radius_mm * 0.5  # as check_scene has it
            and table.contains(block.x_mm, block.y_mm, block.radius_mm)):
        return False
    fp = block.footprint
    return (all(penetration_mm(fp, b.footprint) <= -BIN_CLEARANCE_MM for b in bins)
            and all(penetration_mm(fp, b.footprint) <= 0.0 for b in placed))


def _place_group(rng: random.Random, offsets: Offsets, size: float, placed: list[Block],
                 bins: Sequence[Bin], table: Table) -> list[Block] | None:
    """The group's blocks at a random spot and yaw where they all fit, or None."""
    for _ in range(60):
        yaw = round(rng.uniform(-45.0, 45.0), 2)
        c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
        ax, ay = _anchor(rng)
        group: list[Block] = []
        for ox, oy in offsets:
            block = Block("red", round(ax + c * ox - s * oy, 2), round(ay + s * ox + c * oy, 2),
                          yaw, size)
            if not _fits(block, [*placed, *group], bins, table):
                break
            group.append(block)
        else:
            return group
    return None


def _layout(rng: random.Random, count: int, sizes: tuple[float, float],
            bins: Sequence[Bin], table: Table) -> list[Block]:
    """``count`` blocks in groups, by rejection sampling (colours come later)."""
    for _attempt in range(100):  # an unlucky early group can leave no room: start again
        placed: list[Block] = []
        misses = 0
        while len(placed) < count and misses < 30:
            size = sizes[0] if sizes[0] == sizes[1] else min(
                max(round(rng.uniform(*sizes) * 2) / 2, sizes[0]), sizes[1])  # to 0.5 mm
            offsets = _group_offsets(rng, count - len(placed), size)
            group = _place_group(rng, offsets, size, placed, bins, table)
            if group is None:
                misses += 1
            else:
                placed += group
        if len(placed) == count:
            return placed
    raise ConfigError(f"cannot place {count} blocks in the reachable area; ask for fewer")


def _colors(rng: random.Random, count: int, colors: Sequence[str]) -> list[str]:
    """Any mix: all of one colour now and then, else a random few of ``colors``."""
    k = 1 if len(colors) == 1 or rng.random() < 0.15 else rng.randint(2, len(colors))
    chosen = rng.sample(list(colors), k)
    return [rng.choice(chosen) for _ in range(count)]


def clutter_lighting(seed: int) -> Lighting:
    """A room's light for clutter scene ``seed``: a lamp or a window on any side, high or
    low, the room a little dimmer or brighter than usual, warm to cool (4500-5800 K as the
    camera sees it after its white balance). Within ``CLUTTER_LIGHTING``, where
    busarm.vision's default colour thresholds still hold every block colour."""
    rng = _rng(seed, "lighting")
    values = {name: rng.uniform(lo, hi) for name, (lo, hi) in CLUTTER_LIGHTING.items()}
    return Lighting(**{name: float(round(v, -1 if name == "color_temp_k" else 2))
                       for name, v in values.items()})


def _draw_distractor(rng: random.Random) -> Distractor:
    """A cup or glue stick, a coaster or coin, or a pen or ruler, somewhere in view."""
    shape = rng.choice(("cylinder", "disc", "bar"))
    color = rng.choice(CLUTTER_DISTRACTOR_COLORS)
    r = rng.uniform(REACH_RADIUS_MM[0], REACH_RADIUS_MM[1] + 30.0)
    bearing = math.radians(rng.uniform(PLACE_BEARING_DEG[0] - 5, PLACE_BEARING_DEG[1] + 5))
    x, y = round(r * math.cos(bearing), 2), round(r * math.sin(bearing), 2)
    yaw = round(rng.uniform(-90.0, 90.0), 2)
    if shape == "cylinder":
        d = round(rng.uniform(25.0, 70.0), 1)
        return Distractor(shape, color, x, y, d, d, round(rng.uniform(45.0, 80.0), 1), 0.0,
                          float(round(rng.uniform(40.0, 150.0))))
    if shape == "disc":
        d = round(rng.uniform(30.0, 90.0), 1)
        return Distractor(shape, color, x, y, d, d, round(rng.uniform(2.0, 6.0), 1), 0.0,
                          float(round(rng.uniform(5.0, 40.0))))
    return Distractor(shape, color, x, y, round(rng.uniform(80.0, 180.0), 1),
                      round(rng.uniform(8.0, 20.0), 1), round(rng.uniform(8.0, 15.0), 1), yaw,
                      float(round(rng.uniform(10.0, 40.0))))


def _distractor_fits(thing: Distractor, blocks: Sequence[Block], bins: Sequence[Bin],
                     others: Sequence[Distractor], table: Table) -> bool:
    fp = thing.footprint
    if (not table.contains(thing.x_mm, thing.y_mm, fp.radius_mm)
            or fp.distance_from_mm(0.0, 0.0) < BASE_CLEARANCE_MM):
        return False
    near = [*(b.footprint for b in blocks), *(b.footprint for b in bins),
            *(o.footprint for o in others)]
    return all(penetration_mm(fp, o) <= -DISTRACTOR_GAP_MM for o in near)


def _distractors(rng: random.Random, count: int, blocks: Sequence[Block],
                 bins: Sequence[Bin], table: Table) -> list[Distractor]:
    """``count`` distractors where they fit (fewer only if the table has no room left)."""
    out: list[Distractor] = []
    for _ in range(count):
        for _try in range(200):
            thing = _draw_distractor(rng)
            if _distractor_fits(thing, blocks, bins, out, table):
                out.append(thing)
                break
    return out


def clutter_scene(
    seed: int, blocks: int = CLUTTER_DEFAULT_BLOCKS, colors: Sequence[str] = tuple(COLORS),
    *, distractors: int | None = None, size_mm: float | tuple[float, float] = DEFAULT_BLOCK_MM,
    lighting: bool = True, bins: bool = True,
) -> Scene:
    """A seeded cluttered table of up to ``blocks`` blocks (0..12; at least half of them).

    Colours: any mix of ``colors``, now and then all of one. ``distractors``: how many
    things that are not blocks (0..4; None = 0-3 at random). ``size_mm``: the blocks'
    side, or a (smallest, largest) range each group draws its own from (25..40 mm).
    ``lighting``: a lamp or window of the seed's (else the usual light). ``bins``: one
    tray per colour of ``colors``, where ``DEFAULT_BINS`` has it.
    """
    check_int_range("seed", seed, 0, 2**32 - 1)
    check_int_range("blocks", blocks, 0, CLUTTER_MAX_BLOCKS)
    if distractors is not None:
        check_int_range("distractors", distractors, 0, MAX_DISTRACTORS)
    colors = list(colors)
    unknown = [c for c in colors if c not in COLORS]
    if not colors or unknown or len(set(colors)) != len(colors):
        raise ConfigError(f"colors {', '.join(unknown or colors)}: give distinct colours of "
                          f"{', '.join(COLORS)}")
    lo, hi = (size_mm, size_mm) if isinstance(size_mm, int | float) else size_mm
    lo = check_range("size_mm", lo, *CLUTTER_BLOCK_MM, "mm")
    hi = check_range("size_mm", hi, lo, CLUTTER_BLOCK_MM[1], "mm")
    table = Table()
    trays = tuple(b for b in DEFAULT_BINS if b.color in colors) if bins else ()
    layout_rng = _rng(seed, "layout")
    count = layout_rng.randint((blocks + 1) // 2, blocks)
    placed = _layout(layout_rng, count, (lo, hi), trays, table)
    painted = [Block(c, b.x_mm, b.y_mm, b.yaw_deg, b.size_mm)
               for c, b in zip(_colors(_rng(seed, "colors"), count, colors), placed,
                               strict=True)]
    things_rng = _rng(seed, "distractors")
    n_things = things_rng.randint(0, 3) if distractors is None else distractors
    things = _distractors(things_rng, n_things, painted, trays, table)
    return Scene(blocks=tuple(painted), bins=trays, table=table, seed=seed,
                 source=f"clutter {seed}", distractors=tuple(things),
                 lighting=clutter_lighting(seed) if lighting else Lighting())
