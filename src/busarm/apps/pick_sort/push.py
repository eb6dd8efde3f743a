"""Pushes that free a boxed-in block: where to drag it (closed fingers pressed on its
top) so that afterwards a grasp clears its neighbours. Pure geometry: no bus, no camera.

A push is tried in ``PUSH_DIRECTIONS`` directions and a few lengths. One is kept only if
the block, all the way along, stays off every other block (sliding past a touching one is
allowed; one it is seen a little into, it must leave behind), the bins and things that
are not blocks; the arm reaches the whole drag (the
tool straight down, else leaning: the closed pads' lower edge presses then) with no pad
on another block; and at its end a grasp of the block clears its neighbours. Of those,
the shortest wins, then one straight down, then the one towards the base (reach is
better there). If none frees the block, the push that leaves it furthest from its
neighbours is offered instead (the next look may still find a way).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner
from busarm.errors import UnreachableError

__all__ = [
    "BEHIND_MM",
    "BIN_KEEP_OFF_MM",
    "LIMIT_MARGIN_DEG",
    "PRESS_MM",
    "PUSH_DIRECTIONS",
    "PUSH_LENGTHS",
    "PUSH_PITCHES_DEG",
    "SLIDE_MM",
    "Push",
    "PushPlanner",
]


PUSH_DIRECTIONS = 16
"""Directions tried, evenly around the block."""
PUSH_LENGTHS = (1.0, 1.5)
"""Lengths tried, in block sides (shortest first)."""
SLIDE_MM = 1.0
"""A pushed block may slide along a neighbour it touches: its footprint is checked this
much smaller a side."""
BIN_KEEP_OFF_MM = 8.0
"""A pushed block stays this far from a bin's walls."""
PUSH_PITCHES_DEG = (-90.0, -75.0, -105.0, -60.0, -120.0)
"""Tool pitches a push is tried with: straight down, else leaning out (far blocks) or back
(near ones)."""
LIMIT_MARGIN_DEG = 3.0
"""A push keeps every joint this far inside its limits: pressing, the arm is off its line
a little, and the line is planned again from where it is."""
BEHIND_MM = 4.0
"""Leaning, the pads go down this far behind the block's face before pushing it."""
PRESS_MM = 3.0
"""Pushing, the closed fingers press this far into the block's top (friction drags it)."""


@dataclass(frozen=True)
class Push:
    """Drag the block from ``start`` to ``end`` (mm, base frame), the tool at ``pitch_deg``
    and ``roll_deg``, along ``path`` (tool points: above, on its top, at the end, above)."""

    start: tuple[float, float]
    end: tuple[float, float]
    pitch_deg: float
    roll_deg: float
    path: tuple[tuple[float, float, float], ...]
    frees: bool
    """Whether a grasp of it clears its neighbours at the end."""


@dataclass(frozen=True)
class PushPlanner:
    """Plans pushes of cubes for ``grasps`` (its table, block size and arm), keeping off
    the ``bins`` (their footprints)."""

    grasps: GraspPlanner
    bins: Sequence[Footprint] = ()

    def plan(self, x_mm: float, y_mm: float, yaw_deg: float, others: Sequence[Footprint],
             gaps_mm: Sequence[float] = (), obstacles: Sequence[Footprint] = ()
             ) -> Push | None:
        """The best push of the block at (x, y) turned ``yaw_deg`` among ``others`` (the
        other blocks' footprints) and ``obstacles`` (things that are not blocks: the
        block keeps ``BIN_KEEP_OFF_MM`` off them too); None if the arm cannot push it
        anywhere."""
        g = self.grasps
        best: tuple[tuple[float, ...], Push] | None = None
        for length in PUSH_LENGTHS:
            for k in range(PUSH_DIRECTIONS):
                angle = 2 * math.pi * k / PUSH_DIRECTIONS
                end = self._clear_end(x_mm, y_mm, yaw_deg, angle, length * g.block_mm, others,
                                      obstacles)
                if end is None:
                    continue
                push = self._reaching(x_mm, y_mm, yaw_deg, end, others, gaps_mm, obstacles)
                if push is None:
                    continue
                rank = self._rank(push, others)
                if best is None or rank < best[0]:
                    best = (rank, push)
            if best is not None and best[1].frees:
                break  # a shorter push that frees it beats any longer one
        return None if best is None else best[1]

    def _clear_end(self, x_mm: float, y_mm: float, yaw_deg: float, angle: float,
                   length_mm: float, others: Sequence[Footprint],
                   obstacles: Sequence[Footprint]) -> tuple[float, float] | None:
        """Where the block ends pushed this way, or None if it would meet something."""
        size = self.grasps.block_mm
        end = (x_mm + math.cos(angle) * length_mm, y_mm + math.sin(angle) * length_mm)
        # A square slid along a straight line sweeps the hull of where it starts and ends.
        start_sq = Footprint.square(x_mm, y_mm, size - 2 * SLIDE_MM, yaw_deg)
        end_sq = Footprint.square(*end, size - 2 * SLIDE_MM, yaw_deg)
        swept = Footprint.hull([*start_sq.corners, *end_sq.corners])
        way = (math.cos(angle), math.sin(angle))
        for o in others:
            if not o.overlaps(start_sq):
                if swept.overlaps(o):
                    return None
                continue
            # Seen a little into a neighbour it touches (the sightings' own errors): every
            # sweep would overlap it; the push must take the block away from it and leave
            # it clear (else half a millimetre left a boxed-in block no push at all).
            ox, oy = o.centre_mm
            if (x_mm - ox) * way[0] + (y_mm - oy) * way[1] <= 0.0 or end_sq.overlaps(o):
                return None
        if any(swept.overlaps(b, BIN_KEEP_OFF_MM) for b in (*self.bins, *obstacles)):
            return None
        return end

    def _reaching(self, x_mm: float, y_mm: float, yaw_deg: float, end: tuple[float, float],
                  others: Sequence[Footprint], gaps_mm: Sequence[float],
                  obstacles: Sequence[Footprint]) -> Push | None:
        """The push to ``end`` at the first tool pitch (``PUSH_PITCHES_DEG``) and roll the
        arm reaches it all the way with, or None."""
        g = self.grasps
        for pitch, face in ((p, f) for p in PUSH_PITCHES_DEG for f in (True, False)
                            if p != -90.0 or not f):
            path, alike = self._path(x_mm, y_mm, end, pitch, face=face)
            for roll in self._rolls(x_mm, y_mm, yaw_deg, pitch):
                try:
                    g.check_path(path, pitch, roll, LIMIT_MARGIN_DEG)
                    g.check_path(alike, pitch, roll, LIMIT_MARGIN_DEG)
                except UnreachableError:
                    continue
                if self._pads_hit(path, pitch, roll, others, obstacles):
                    continue  # the pads would press on a neighbour, or meet a thing
                try:
                    g.plan(end[0], end[1], yaw_deg, others, gaps_mm, obstacles)
                    frees = True
                except UnreachableError:  # boxed in still (NoClearGrasp), or out of reach
                    frees = False
                return Push((x_mm, y_mm), end, pitch, roll, path, frees)
        return None

    def _path(self, x_mm: float, y_mm: float, end: tuple[float, float], pitch_deg: float,
              *, face: bool) -> tuple[tuple[tuple[float, float, float], ...],
                                      tuple[tuple[float, float, float], ...]]:
        """The tool's path for a push, and the points it may stay short of. The closed
        pads press on the block's top and drag it (the fingers may stay short of the
        press: that height too); or (``face``) they go down behind the block, to its
        half height, and push its face: leaning, a pad's edge drags poorly, so that is
        tried first where the arm reaches behind the block."""
        g = self.grasps
        top = g.table_z_mm + g.block_mm
        above = top + g.approach_mm / 2
        if not face:
            path = ((x_mm, y_mm, above), (x_mm, y_mm, top - PRESS_MM),
                    (end[0], end[1], top - PRESS_MM), (end[0], end[1], above))
            return path, tuple((x, y, top) for x, y, _ in path[1:3])
        length = math.dist((x_mm, y_mm), end)
        dx, dy = (end[0] - x_mm) / length, (end[1] - y_mm) / length
        back = g.block_mm / 2 + max(g.pad_mm[0], g.pad_mm[1] / 2) + BEHIND_MM
        bx, by = x_mm - dx * back, y_mm - dy * back
        mid = g.table_z_mm + g.block_mm / 2
        return ((bx, by, above), (bx, by, mid), (bx + dx * length, by + dy * length, mid),
                (bx + dx * length, by + dy * length, above)), ()

    def _pads_hit(self, path: tuple[tuple[float, float, float], ...], pitch_deg: float,
                  roll_deg: float, others: Sequence[Footprint],
                  obstacles: Sequence[Footprint]) -> bool:
        """Whether the closed pads, anywhere from the push's start to its end, would
        touch a block other than the pushed one, or a thing that is not a block."""
        g = self.grasps

        def swept(tall: bool) -> list[Footprint]:
            """Each pad's footprint from the push's start to its end (the hull)."""
            start, end = (g.pads(GraspPlan(pitch_deg, roll_deg, path[0], tip, path[3]), 0.0,
                                 tall=tall) for tip in path[1:3])
            return [Footprint.hull([*a.corners, *b.corners]) for a, b in zip(start, end,
                                                                              strict=True)]

        return (any(p.overlaps(o, g.margin_mm) for p in swept(False) for o in others)
                or any(p.overlaps(o, g.margin_mm) for p in swept(True) for o in obstacles))

    def _rolls(self, x_mm: float, y_mm: float, yaw_deg: float, pitch_deg: float
               ) -> list[float]:
        """Wrist rolls to push with: squared to the block straight down, else any."""
        if pitch_deg == -90.0:
            try:
                return [self.grasps.roll_squared_deg(x_mm, y_mm, yaw_deg)]
            except UnreachableError:
                return []
        return [0.0, 45.0, -45.0]

    def _rank(self, push: Push, others: Sequence[Footprint]) -> tuple[float, ...]:
        """Smaller is better: freeing first; then towards the base; a push that does not
        free the block, the further from its neighbours the better."""
        (x0, y0), (x1, y1) = push.start, push.end
        toward_base = (math.hypot(x1, y1) - math.hypot(x0, y0)) / max(
            math.dist(push.start, push.end), 1e-9)
        leaning = float(push.pitch_deg != -90.0)  # straight down presses flat: surer
        if push.frees:
            return (0.0, leaning, toward_base)
        clearance = min((_distance_mm(push.end, o) for o in others), default=math.inf)
        return (1.0, leaning, -clearance, toward_base)


def _distance_mm(point: tuple[float, float], footprint: Footprint) -> float:
    """From a point to the nearest corner or centre of a footprint (a rough clearance)."""
    pts = np.vstack([footprint.corners, footprint.corners.mean(axis=0)])
    return float(np.min(np.hypot(pts[:, 0] - point[0], pts[:, 1] - point[1])))
