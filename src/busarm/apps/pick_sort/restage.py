"""Blocks taken tilted for a bin's second layer: turned with the tool, such a block would
lean when set down straight on the first layer, so it is set down on the table first, at
a free place near the base where it can be taken again straight down. Pure geometry: no
bus, no camera."""

from __future__ import annotations

import math
from collections.abc import Sequence

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlanner, Thing
from busarm.errors import UnreachableError
from busarm.units import place_text

__all__ = [
    "STAGING_BEARINGS_DEG",
    "STAGING_RADII_MM",
    "Restaged",
    "staging_spot",
]


STAGING_RADII_MM = (150.0, 130.0, 170.0, 190.0, 210.0, 230.0)
STAGING_BEARINGS_DEG = tuple(range(-60, 61, 5))
"""Where a block taken tilted may be set down to be taken again straight down."""


class Restaged(Exception):
    """A block taken tilted (for a second layer, or a large one) was set down to be taken
    straight down."""

    def __init__(self, spot_mm: tuple[float, float]) -> None:
        super().__init__(f"taken tilted, it would land leaning in the bin: set down at "
                         f"{place_text(spot_mm)} to be taken straight down")
        self.spot_mm = spot_mm


def staging_spot(planner: GraspPlanner, blocks: Sequence[Footprint],
                 keep_off: Sequence[Footprint], things: Sequence[Thing],
                 gaps_mm: Sequence[float], room_mm: float) -> tuple[float, float] | None:
    """The first free place (nearest the base, then by bearing) where a square ``room_mm``
    wide (a block and a finger's room) misses the other ``blocks`` and ``keep_off``
    (things, bins) and a straight-down grasp clears the blocks and ``things``; None if
    there is none."""
    avoid = [*blocks, *keep_off]
    for radius in STAGING_RADII_MM:
        for bearing in STAGING_BEARINGS_DEG:
            x = radius * math.cos(math.radians(bearing))
            y = radius * math.sin(math.radians(bearing))
            if any(Footprint.square(x, y, room_mm, 0.0).overlaps(k) for k in avoid):
                continue
            try:
                if planner.plan(x, y, 0.0, blocks, gaps_mm, things).pitch_deg == -90.0:
                    return x, y
            except UnreachableError:
                continue
    return None
