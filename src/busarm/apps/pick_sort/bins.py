"""The bins: where the next block of a colour goes, how many a bin takes, and the wrist
roll that sets it down square with the fingers clear of the blocks beside it."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner
from busarm.errors import ConfigError, UnreachableError

__all__ = [
    "BIN_PLACES",
    "BIN_RADIUS_MM",
    "BIN_SEEN_MM",
    "BIN_SLOTS_MM",
    "IN_BIN_MM",
    "MAX_PAIR_MM",
    "SLOT_GAP_MM",
    "STACK_CLEAR_MM",
    "STACK_DROP_MM",
    "TIGHT_ROOM_MM",
    "TOP_SLACK_MM",
    "TRAY_FLOOR_MM",
    "TRAY_INSIDE_MM",
    "TRAY_WALL_MM",
    "TRAY_WALL_THICKNESS_MM",
    "WALL_CLEARANCE_MM",
    "BinPlaces",
    "bin_takes",
    "in_tray",
    "place_offset_mm",
    "slot_offset_mm",
]


BIN_RADIUS_MM = 45.0
"""A block seen this close to a bin's centre is in or at that bin: not to be picked."""
BIN_SEEN_MM = 60.0
"""A block seen this close to a bin's centre along both of the base's axes (a tray
stands square to them) is in that bin: one on a tray's second layer, located as if it
stood on the table, is seen up to about 15 mm beyond the tray's side (a block on the
table keeps a finger's room off it)."""
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
"""A block for the second layer is let go this far above the first layer's tops (and
one with little room this far above the floor: ``TIGHT_ROOM_MM``)."""
TRAY_INSIDE_MM = 41.0
"""Half the inside of a tray (90 mm, 2 mm walls): a block's side stays this near its centre."""
TRAY_FLOOR_MM = 2.0
"""A tray's floor stands this high over the table ..."""
TRAY_WALL_MM = 12.0
"""... and its walls this high."""
TIGHT_ROOM_MM = 4.0
"""A block set down with less room than this to a tray's wall or a block beside it is
lowered until it nearly stands (let go ``STACK_DROP_MM`` above the floor), the pads
kept over what they stand above: dropped from the usual height (a 44 mm cube 21 mm), in
the twin it bounced off the wall and stayed wedged on it, 14 deg leaning, and the block
then set on it fell off (lookalike seed 1001 of ``--seed 1000``)."""
WALL_CLEARANCE_MM = 1.5
"""... less this, not to lean on the wall."""
SLOT_GAP_MM = 1.0
"""Blocks side by side in a bin stand at least this far apart."""
TOP_SLACK_MM = 6.0
"""A block on the second layer is at most this much wider than the one it stands on."""
MAX_PAIR_MM = 90.0
"""Two blocks stand one on the other in a bin no taller than this (two of 45 mm, the
largest blocks: a bin takes one such pair where side by side they would not fit). Every
carry passes over the tallest pair (``BinPlaces.tallest_mm``): in the twin a pair of 78
and 82 mm, swept by a carry at the usual height, was knocked out of its tray."""
STACK_CLEAR_MM = 15.0
"""A block carried over the bins clears the tallest pair in them by this."""


TRAY_WALL_THICKNESS_MM = 4.0
"""A tray's walls are this thick (the twin's: 90 mm outside, 82 mm inside)."""
_OUT = TRAY_INSIDE_MM + TRAY_WALL_THICKNESS_MM / 2
_LONG = 2 * TRAY_INSIDE_MM + 2 * TRAY_WALL_THICKNESS_MM
_WALLS_MM = tuple((sx * _OUT, sy * _OUT, _LONG if sy else TRAY_WALL_THICKNESS_MM,
                   _LONG if sx else TRAY_WALL_THICKNESS_MM, TRAY_WALL_MM)
                  for sx, sy in ((1, 0), (-1, 0), (0, 1), (0, -1)))
"""A tray's four walls from its centre: x, y, their extent along x and y, and their top
(mm)."""


def in_tray(x_mm: float, y_mm: float, bin_mm: tuple[float, float]) -> bool:
    """Whether a block's centre at (x, y) lies over the inside of the tray at ``bin_mm``
    (standing square to the base's axes): the block is in it (a block on a wall or
    beyond has its centre over the wall or outside)."""
    return abs(x_mm - bin_mm[0]) < TRAY_INSIDE_MM and abs(y_mm - bin_mm[1]) < TRAY_INSIDE_MM


def slot_offset_mm(slot: int, size_mm: float) -> tuple[float, float]:
    """Where a block ``size_mm`` wide goes in ``slot`` (``BIN_SLOTS_MM``), from the bin's
    centre: the slot's place, drawn in if the block would otherwise reach the wall."""
    reach = min(1.0, (TRAY_INSIDE_MM - WALL_CLEARANCE_MM - size_mm / 2) / 20.0)
    dx, dy = BIN_SLOTS_MM[slot]
    return dx * max(reach, 0.0), dy * max(reach, 0.0)


Place = tuple[int, int, float, float]
"""A place in a bin: its slot (``BIN_SLOTS_MM``), layer (0, 1), and where the block's
centre stands from the bin's centre (x, y mm)."""
Taken = list[tuple[int, int, float, float, float]]
"""A bin's places taken, in order: (slot, layer, block size mm, x, y mm from the centre)."""


def place_offset_mm(slot: int, size_mm: float, corner: bool = False) -> tuple[float, float]:
    """Where a block ``size_mm`` wide stands in ``slot``, from the bin's centre: the
    slot's place (``slot_offset_mm``), or pushed out to both walls (``corner``: it leaves
    the other slots more room)."""
    if not corner:
        return slot_offset_mm(slot, size_mm)
    out = TRAY_INSIDE_MM - WALL_CLEARANCE_MM - size_mm / 2
    dx, dy = BIN_SLOTS_MM[slot]
    return math.copysign(out, dx), math.copysign(out, dy)


def _free_places(taken: Taken, size_mm: float) -> Iterator[Place]:
    """The places a block ``size_mm`` wide fits in a bin holding ``taken``, in
    ``BIN_PLACES`` order (a slot's place before its corner): free, clear of the
    blocks in the other slots; on the second layer centred on a block no smaller than it
    less ``TOP_SLACK_MM``, the two no taller than ``MAX_PAIR_MM``."""
    for slot, layer in BIN_PLACES:
        if any(s == slot and lay == layer for s, lay, *_ in taken):
            continue
        if layer == 1:  # on the block below, as near its centre as the walls let it
            most = TRAY_INSIDE_MM - WALL_CLEARANCE_MM - size_mm / 2
            spots = [(math.copysign(min(abs(x), most), x), math.copysign(min(abs(y), most), y))
                     for s, lay, size, x, y in taken
                     if s == slot and lay == 0 and size + TOP_SLACK_MM >= size_mm
                     and size + size_mm <= MAX_PAIR_MM][:1]
        else:
            spots = [place_offset_mm(slot, size_mm, corner) for corner in (False, True)]
        for dx, dy in spots:
            # Clear of every block in the other slots, either layer: one on the second
            # layer may be wider than the one it stands on (in the twin a block set down
            # beside such a pair knocked its top block out of the tray).
            if not any(s != slot and abs(dx - ox) < (size_mm + size) / 2 + SLOT_GAP_MM
                       and abs(dy - oy) < (size_mm + size) / 2 + SLOT_GAP_MM
                       for s, _, size, ox, oy in taken):
                yield slot, layer, dx, dy


def _fill(taken: Taken, sizes_mm: Sequence[float]) -> int:
    """How many of blocks with these sides go into a bin holding ``taken``, the largest
    set down first, each in the first place it fits."""
    taken = list(taken)
    for size in sorted(sizes_mm, reverse=True):
        place = next(_free_places(taken, size), None)
        if place is not None:
            taken.append((place[0], place[1], size, place[2], place[3]))
    return len(taken)


def _best_place(taken: Taken, size_mm: float, coming_mm: Sequence[float]) -> Place | None:
    """The place for a block ``size_mm`` wide that leaves the most room for the blocks
    still ``coming_mm`` to the bin (the first such place, in ``_free_places`` order)."""
    best, most = None, -1
    for place in _free_places(taken, size_mm):
        if not coming_mm:
            return place
        room = _fill([*taken, (place[0], place[1], size_mm, place[2], place[3])], coming_mm)
        if room > most:
            best, most = place, room
    return best


def bin_takes(sizes_mm: Sequence[float]) -> int:
    """How many of blocks with these sides (mm) one empty bin takes at best (the largest
    set down first, each in the first place it fits)."""
    return _fill([], sizes_mm)


class BinPlaces:
    """Places in the ``bins`` (colour -> centre x, y mm), filled in ``BIN_PLACES``
    order, for blocks set down by ``planner``'s arm. A block too large for a place (it
    would lean on a wall, or on the block beside it) takes the next that fits it; one on
    the second layer stands on a block no smaller than itself less ``TOP_SLACK_MM``."""

    def __init__(self, bins: Mapping[str, tuple[float, float]], planner: GraspPlanner) -> None:
        self.bins = dict(bins)
        self.planner = planner
        self._placed: dict[str, Taken] = {}
        """Per colour, the places taken in order."""
        self._coming: dict[str, list[float]] = {}
        """Per colour, the sides of the blocks seen waiting to go there (``expect``)."""
        self._leaning: dict[str, set[int]] = {}
        """Per colour, the slots whose block may lean (set down tilted): none on it."""

    @property
    def capacity(self) -> int:
        """How many blocks of the usual size a bin takes (``BIN_PLACES``)."""
        return len(BIN_PLACES)

    def count(self, color: str) -> int:
        """How many blocks have been put in ``color``'s bin."""
        return len(self._placed.get(color, []))

    def covered(self, color: str) -> int:
        """How many blocks in ``color``'s bin stand under another (out of the camera's
        sight)."""
        return sum(layer == 1 for _, layer, *_ in self._placed.get(color, []))

    def is_full(self, color: str, size_mm: float = 30.0) -> bool:
        """Whether no place is left in ``color``'s bin for a block ``size_mm`` wide."""
        return self._place(color, size_mm) is None

    def next_layer(self, color: str, size_mm: float = 30.0) -> int:
        """The layer the next block of ``color``, ``size_mm`` wide, goes to (0, 1)."""
        return self._layer_and_below(color, size_mm)[0]

    def below_mm(self, color: str, size_mm: float = 30.0) -> float:
        """The size of the block the next one of ``color`` stands on (0: the floor)."""
        return self._layer_and_below(color, size_mm)[1]

    def _layer_and_below(self, color: str, size_mm: float) -> tuple[int, float]:
        """``next_layer`` and ``below_mm`` from one choice of the place."""
        place = self._place(color, size_mm)
        if place is None or place[1] == 0:
            return (1 if place is None else 0), 0.0
        return 1, next(size for slot, layer, size, *_ in self._placed[color]
                       if slot == place[0] and layer == 0)

    @property
    def tallest_mm(self) -> float:
        """The tallest stack in any bin (mm above its floor), by the blocks put there."""
        stacks: dict[tuple[str, int], float] = {}
        for color, taken in self._placed.items():
            for slot, _, size, *_ in taken:
                stacks[color, slot] = stacks.get((color, slot), 0.0) + size
        return max(stacks.values(), default=0.0)

    def heights_mm(self, color: str, size_mm: float, carry_mm: float, release_mm: float
                   ) -> tuple[float, float]:
        """How high above the table the next block of ``color`` (``size_mm`` wide, held
        at its middle) is carried to its bin, and let go there: over the first layer for
        the second, and over the tallest pair in any bin (``STACK_CLEAR_MM``); let go
        just above the block below (a drop from the first layer's height bounces it off)."""
        layer, below = self._layer_and_below(color, size_mm)
        carry = max(carry_mm + layer * below, self.tallest_mm + STACK_CLEAR_MM + size_mm / 2)
        return carry, release_mm if layer == 0 else below + STACK_DROP_MM + size_mm / 2

    def release_mm(self, color: str, usual_mm: float, roll_deg: float, gap_mm: float
                   ) -> float:
        """How high above the table the block last given a place in ``color``'s bin
        (``next_spot``), held at its middle at ``roll_deg``, is let go, the fingers to
        open ``gap_mm`` apart: on the second layer where ``heights_mm`` said
        (``usual_mm``); on the first at ``usual_mm`` or, with little room
        (``TIGHT_ROOM_MM``), ``STACK_DROP_MM`` over the floor; on either layer with the
        pads ``STACK_DROP_MM`` over every wall and block they stand above."""
        slot, layer, size, dx, dy = self._placed[color][-1]
        others = self._placed[color][:-1]
        # Each block already there, where it stands, and how high its top is.
        blocks = [(x, y, w, w, TRAY_FLOOR_MM + sum(size for s, lay, size, *_ in others
                                                   if s == slot_k and lay <= layer_k))
                  for slot_k, layer_k, w, x, y in others if (slot_k, layer_k) != (slot, 0)]
        room = min([TRAY_INSIDE_MM - max(abs(dx), abs(dy)) - size / 2,
                    *(max(abs(dx - x), abs(dy - y)) - (size + w) / 2
                      for x, y, w, _, _ in blocks)])
        low = (usual_mm if layer == 1 or room >= TIGHT_ROOM_MM
               else TRAY_FLOOR_MM + STACK_DROP_MM + size / 2)
        bx, by = self.bins[color]
        z0 = self.planner.table_z_mm
        at = (bx + dx, by + dy, z0 + usual_mm)
        try:
            pads = self.planner.pads(GraspPlan(-90.0, roll_deg, at, at, at), gap_mm,
                                     tall=True)
        except UnreachableError:
            return usual_mm
        over = [top + STACK_DROP_MM for x, y, u, v, top in (*_WALLS_MM, *blocks)
                if any(p.overlaps(Footprint.rectangle(bx + x, by + y, u, v, 0.0),
                                  self.planner.margin_mm) for p in pads)]
        release = max([low, *over])
        if not self.planner.kin.reaches(bx + dx, by + dy, z0 + release, -90.0):
            return usual_mm
        return release

    def may_lean(self, color: str) -> None:
        """The block last put in ``color``'s bin may not stand flat (it was held tilted):
        nothing is set on it."""
        slot = self._placed[color][-1][0]
        self._leaning.setdefault(color, set()).add(slot)

    def take_back(self, color: str) -> None:
        """The last place taken for ``color`` is free again (its block did not get there)."""
        self._placed[color].pop()

    def expect(self, color: str, sizes_mm: Sequence[float]) -> None:
        """The blocks seen waiting to go to ``color``'s bin, by side (mm): each block is
        set down where it leaves them the most room."""
        self._coming[color] = list(sizes_mm)

    def _place(self, color: str, size_mm: float) -> Place | None:
        """The place of ``BIN_PLACES`` for a block ``size_mm`` wide (``_best_place``;
        the block itself is one of those expected, the nearest in size)."""
        coming = list(self._coming.get(color, []))
        if coming:
            coming.remove(min(coming, key=lambda s: abs(s - size_mm)))
        taken = self._placed.get(color, [])
        # (A leaning block's slot counts its second layer as taken: by nothing at all.)
        unsure = [(slot, 1, 0.0, x, y) for slot, lay, _, x, y in taken
                  if lay == 0 and slot in self._leaning.get(color, ())]
        return _best_place([*taken, *unsure], size_mm, coming)

    def next_spot(self, color: str, things: Sequence[Footprint] = (), gap_mm: float = 0.0,
                  release_z_mm: float = 0.0, size_mm: float = 30.0
                  ) -> tuple[float, float, int, float]:
        """Where in the bin the next block of ``color`` (``size_mm`` wide) goes: x, y,
        its layer (0, 1), and the wrist roll that squares it to the bin's walls with the
        fingers clear of the blocks already beside it in that layer, and, opened
        ``gap_mm`` to let go at ``release_z_mm``, of ``things`` beside the bin."""
        bx, by = self.bins[color]
        place = self._place(color, size_mm)
        if place is None:
            raise ConfigError(f"the {color} bin is full ({self.count(color)} blocks)")
        slot, layer, dx, dy = place
        beside = [(x, y) for _, lay, _, x, y in self._placed.get(color, []) if lay == layer]
        self._placed.setdefault(color, []).append((slot, layer, size_mm, dx, dy))
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
