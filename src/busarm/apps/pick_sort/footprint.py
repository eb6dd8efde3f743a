"""What things cover on the table, seen from above: convex polygons in mm (base frame),
and whether two of them overlap. A grasp uses them to keep its finger pads off the
neighbours of the block it takes."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.perception.obstacles import near_convex

__all__ = [
    "TOUCH_MM",
    "FloatArray",
    "Footprint",
]


FloatArray = npt.NDArray[np.float64]

TOUCH_MM = 1e-6
"""Polygons that meet along an edge (within this) do not overlap: touching is allowed."""


@dataclass(frozen=True)
class Footprint:
    """A convex polygon on the table: its corners (N x 2, mm, base frame, in order)."""

    corners: FloatArray

    @classmethod
    def square(cls, x_mm: float, y_mm: float, side_mm: float, yaw_deg: float) -> Footprint:
        """A cube's footprint: ``side_mm`` square centred at (x, y), turned ``yaw_deg``."""
        return cls.rectangle(x_mm, y_mm, side_mm, side_mm, yaw_deg)

    @classmethod
    def rectangle(cls, x_mm: float, y_mm: float, u_mm: float, v_mm: float,
                  u_deg: float) -> Footprint:
        """``u_mm`` along the direction ``u_deg``, ``v_mm`` across it, centred at (x, y)."""
        a = math.radians(u_deg)
        u = np.array([math.cos(a), math.sin(a)]) * u_mm / 2
        v = np.array([-math.sin(a), math.cos(a)]) * v_mm / 2
        c = np.array([x_mm, y_mm])
        return cls(np.array([c - u - v, c + u - v, c + u + v, c - u + v]))

    @classmethod
    def hull(cls, points: Iterable[FloatArray]) -> Footprint:
        """The convex hull of points on the table (Andrew's monotone chain)."""
        pts = sorted({(float(p[0]), float(p[1])) for p in points})
        if len(pts) < 3:
            raise ValueError("a footprint needs at least 3 distinct points")

        def half(seq: list[tuple[float, float]]) -> list[tuple[float, float]]:
            out: list[tuple[float, float]] = []
            for p in seq:
                while len(out) >= 2 and _cross(out[-2], out[-1], p) <= 0:
                    out.pop()
                out.append(p)
            return out[:-1]

        return cls(np.array(half(pts) + half(pts[::-1])))

    @property
    def centre_mm(self) -> tuple[float, float]:
        c = self.corners.mean(axis=0)
        return float(c[0]), float(c[1])

    def reaches(self, points_mm: FloatArray, margin_mm: float) -> bool:
        """Whether any of ``points_mm`` (N x 2 or N x 3, mm) lies within ``margin_mm`` of
        it, at any height (a thing of unknown height standing on it)."""
        points = np.asarray(points_mm, dtype=np.float64)
        return bool(near_convex(self.corners, points[:, :2], margin_mm).any())

    def overlaps(self, other: Footprint, margin_mm: float = 0.0) -> bool:
        """Whether the two come closer than ``margin_mm`` (separating axes; with no margin,
        touching does not count): the margin keeps a doubt about where a thing is."""
        for poly in (self.corners, other.corners):
            edges = np.roll(poly, -1, axis=0) - poly
            for nx, ny in zip(-edges[:, 1], edges[:, 0], strict=True):
                axis = np.array([nx, ny]) / max(math.hypot(nx, ny), 1e-12)
                a, b = self.corners @ axis, other.corners @ axis
                gap = max(b.min() - a.max(), a.min() - b.max())
                if gap >= margin_mm - TOUCH_MM:
                    return False
        return True


def _cross(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
