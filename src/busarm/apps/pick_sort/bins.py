"""The bins: where the next block of a colour goes, how many a bin takes, and the wrist
roll that sets it down square with the fingers clear of the blocks beside it."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner
from busarm.errors import ConfigError, UnreachableError

__all__ = [
    "BIN_PLACES",
    "BIN_RADIUS_MM",
    "BIN_SLOTS_MM",
    "IN_BIN_MM",
    "STACK_DROP_MM",
    "BinPlaces",
]


BIN_RADIUS_MM = 45.0
"""A block seen this close to a bin's centre is in or at that bin: not to be picked."""
IN_BIN_MM = 35.0
"""A block whose centre is this close to its bin's centre is sorted: inside a 90 mm tray
(a cube squared to the walls fits with its centre up to 28 mm off along each axis; the
slots are 28 mm from the centre)."""
BIN_SLOTS_MM = ((-20.0, -20.0), (20.0, -20.0), (-20.0, 20.0), (20.0, 20.0))
"""Where blocks go in a bin (from its centre): 2 x 2, 10 mm apart (the camera sees them
apart when it checks the bin)."""
BIN_PLACES = (*((slot, 0) for slot in range(4)), (0, 1), (1, 1), (2, 1))
"""The places a bin takes, in order: (slot, layer). The second layer stands square on the
first, three blocks: a fourth would have a neighbour on both sides of both finger axes
(a 10 mm gap takes no finger pad), and a third layer would stand above the tray's walls
and the camera's view of it."""
STACK_DROP_MM = 3.0
"""A block for the second layer is let go this far above the first layer's tops."""


class BinPlaces:
    """Places in the ``bins`` (colour -> centre x, y mm), filled in ``BIN_PLACES``
    order, for blocks set down by ``planner``'s arm."""

    def __init__(self, bins: Mapping[str, tuple[float, float]], planner: GraspPlanner) -> None:
        self.bins = dict(bins)
        self.planner = planner
        self._placed: dict[str, int] = {}

    @property
    def capacity(self) -> int:
        """How many blocks a bin takes (``BIN_PLACES``)."""
        return len(BIN_PLACES)

    def is_full(self, color: str) -> bool:
        return self._placed.get(color, 0) >= self.capacity

    def next_layer(self, color: str) -> int:
        """The layer the next block of ``color`` goes to (0, 1)."""
        return BIN_PLACES[min(self._placed.get(color, 0), self.capacity - 1)][1]

    def take_back(self, color: str) -> None:
        """The last place taken for ``color`` is free again (its block did not get there)."""
        self._placed[color] -= 1

    def next_spot(self, color: str, things: Sequence[Footprint] = (), gap_mm: float = 0.0,
                  release_z_mm: float = 0.0) -> tuple[float, float, int, float]:
        """Where in the bin the next block of ``color`` goes (``BIN_PLACES``): x, y, its
        layer (0, 1), and the wrist roll that squares it to the bin's walls with the
        fingers clear of the blocks already beside it in that layer, and, opened
        ``gap_mm`` to let go at ``release_z_mm``, of ``things`` beside the bin."""
        bx, by = self.bins[color]
        k = self._placed.get(color, 0)
        if k >= self.capacity:
            raise ConfigError(f"the {color} bin is full ({self.capacity} blocks)")
        self._placed[color] = k + 1
        slot, layer = BIN_PLACES[k]
        dx, dy = BIN_SLOTS_MM[slot]
        beside = [BIN_SLOTS_MM[other] for other, lay in BIN_PLACES[:k] if lay == layer]
        square = self.planner.roll_squared_deg(bx + dx, by + dy, 0.0)

        def along_neighbours(roll: float) -> float:
            """How much the fingers would close towards a block beside (0: across)."""
            axis = math.radians(self.planner.finger_axis_deg(bx + dx, by + dy, roll))
            return max((abs(math.cos(axis) * (ox - dx) + math.sin(axis) * (oy - dy))
                        / math.hypot(ox - dx, oy - dy) for ox, oy in beside), default=0.0)

        def on_a_thing(roll: float) -> bool:
            if not things:
                return False
            at = (bx + dx, by + dy, release_z_mm)
            pads = self.planner.pads(GraspPlan(-90.0, roll, at, at, at), gap_mm, tall=True)
            return any(p.overlaps(t, self.planner.margin_mm) for p in pads for t in things)

        rolls = []
        for roll in (square, square + 90.0, square - 90.0):
            try:
                rolls.append((on_a_thing(roll), round(along_neighbours(roll), 3), abs(roll),
                              roll))
            except UnreachableError:
                continue
        roll = min(rolls)[-1] if rolls else square
        return bx + dx, by + dy, layer, roll
