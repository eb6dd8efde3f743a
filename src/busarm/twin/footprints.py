"""Where things stand on the table, seen from above: oriented rectangles and discs, in mm.

The twin refuses a scene whose objects interpenetrate, and only then: two blocks may
touch, a block may stand against a bin's wall. ``penetration_mm`` is the exact test, by
separating axes for two rectangles (a square block, a bin, a bar) and by nearest points
where a disc (a cylinder's footprint) is involved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = [
    "TOUCH_TOLERANCE_MM",
    "Footprint",
    "overlaps",
    "penetration_mm",
]


TOUCH_TOLERANCE_MM = 0.01
"""Interpenetration still counted as touching: rounding in a scene file, not an overlap."""


@dataclass(frozen=True)
class Footprint:
    """A rectangle of half sides (half_x, half_y) centred at (x, y), turned by ``yaw_deg``;
    or, with ``round``, a disc of radius ``half_x_mm``."""

    x_mm: float
    y_mm: float
    half_x_mm: float
    half_y_mm: float
    yaw_deg: float = 0.0
    round: bool = False

    @staticmethod
    def square(x_mm: float, y_mm: float, size_mm: float, yaw_deg: float = 0.0) -> Footprint:
        return Footprint(x_mm, y_mm, size_mm / 2, size_mm / 2, yaw_deg)

    @staticmethod
    def disc(x_mm: float, y_mm: float, diameter_mm: float) -> Footprint:
        return Footprint(x_mm, y_mm, diameter_mm / 2, diameter_mm / 2, 0.0, True)

    @property
    def radius_mm(self) -> float:
        """No point of the footprint is farther than this from its centre."""
        return self.half_x_mm if self.round else math.hypot(self.half_x_mm, self.half_y_mm)

    def axes(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The rectangle's own x and y directions in the table's frame."""
        c, s = math.cos(math.radians(self.yaw_deg)), math.sin(math.radians(self.yaw_deg))
        return (c, s), (-s, c)

    def corners(self) -> list[tuple[float, float]]:
        """The rectangle's corners, counter-clockwise (not for a disc)."""
        (ux, uy), (vx, vy) = self.axes()
        hx, hy = self.half_x_mm, self.half_y_mm
        return [(self.x_mm + sx * hx * ux + sy * hy * vx, self.y_mm + sx * hx * uy + sy * hy * vy)
                for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]

    def extent_along(self, nx: float, ny: float) -> float:
        """Half the footprint's width along the unit direction (nx, ny)."""
        if self.round:
            return self.half_x_mm
        (ux, uy), (vx, vy) = self.axes()
        return self.half_x_mm * abs(ux * nx + uy * ny) + self.half_y_mm * abs(vx * nx + vy * ny)

    def distance_from_mm(self, x_mm: float, y_mm: float) -> float:
        """How far the point is from the footprint (0 inside it)."""
        dx, dy = x_mm - self.x_mm, y_mm - self.y_mm
        if self.round:
            return max(0.0, math.hypot(dx, dy) - self.half_x_mm)
        (ux, uy), (vx, vy) = self.axes()
        u = max(0.0, abs(dx * ux + dy * uy) - self.half_x_mm)
        v = max(0.0, abs(dx * vx + dy * vy) - self.half_y_mm)
        return math.hypot(u, v)


def penetration_mm(a: Footprint, b: Footprint) -> float:
    """How deep ``a`` and ``b`` interpenetrate: the shortest shift that parts them (mm).

    Zero or less when they touch or stand apart (for two rectangles, minus the widest gap
    along their edges' normals, which is at most the true distance between them).
    """
    if a.round and b.round:
        return a.half_x_mm + b.half_x_mm - math.hypot(a.x_mm - b.x_mm, a.y_mm - b.y_mm)
    if a.round or b.round:
        disc, rect = (a, b) if a.round else (b, a)
        return _disc_rect_penetration(disc, rect)
    dx, dy = b.x_mm - a.x_mm, b.y_mm - a.y_mm
    depth = math.inf
    for nx, ny in (*a.axes(), *b.axes()):
        # Overlap of the two projections on this axis; a negative overlap is a gap.
        overlap = a.extent_along(nx, ny) + b.extent_along(nx, ny) - abs(dx * nx + dy * ny)
        depth = min(depth, overlap)
    return depth


def _disc_rect_penetration(disc: Footprint, rect: Footprint) -> float:
    (ux, uy), (vx, vy) = rect.axes()
    dx, dy = disc.x_mm - rect.x_mm, disc.y_mm - rect.y_mm
    u, v = dx * ux + dy * uy, dx * vx + dy * vy
    out_u, out_v = abs(u) - rect.half_x_mm, abs(v) - rect.half_y_mm
    if out_u <= 0 and out_v <= 0:  # the disc's centre is inside: leave by the nearest edge
        return disc.half_x_mm - max(out_u, out_v)
    return disc.half_x_mm - math.hypot(max(out_u, 0.0), max(out_v, 0.0))


def overlaps(a: Footprint, b: Footprint, tolerance_mm: float = TOUCH_TOLERANCE_MM) -> bool:
    """Whether ``a`` and ``b`` interpenetrate by more than ``tolerance_mm`` (touching is not
    overlapping)."""
    return penetration_mm(a, b) > tolerance_mm
