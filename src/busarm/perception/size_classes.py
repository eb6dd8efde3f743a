"""Block size classes by side, for sorting by size: small (< 28 mm), medium (28-37 mm) and
large (> 37 mm), the sizes of the toy blocks a desk has (20-45 mm)."""

from __future__ import annotations

import math

from busarm.errors import ConfigError

__all__ = [
    "SIZE_CLASSES_MM",
    "size_class",
]


SIZE_CLASSES_MM: dict[str, tuple[float, float]] = {
    "small": (10.0, 28.0), "medium": (28.0, 37.0), "large": (37.0, 60.0)}
"""Each class's sides (mm), smallest first; 28 and 37 mm themselves are medium."""


def size_class(side_mm: float) -> str:
    """The ``SIZE_CLASSES_MM`` class of a block ``side_mm`` wide (beyond the classes'
    ends, the nearest class); ConfigError if it is not a positive length."""
    if not (isinstance(side_mm, int | float) and math.isfinite(side_mm) and side_mm > 0):
        raise ConfigError(f"block side {side_mm!r}: give a length in mm above 0")
    small, large = SIZE_CLASSES_MM["small"][1], SIZE_CLASSES_MM["large"][0]
    return "small" if side_mm < small else "medium" if side_mm <= large else "large"
