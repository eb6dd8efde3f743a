"""What a stacking run did: the tower's order, each block's placement as looked at, the
tower's height, and how the run ended."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "ENDS",
    "StackReport",
    "StackedBlock",
]


ENDS = ("complete", "too tall", "failed", "stopped")
"""How a run ends: every block stacked; stopped before a block the arm could not set on
the tower (by design, the tower so far kept); a block that could not be stacked; a stop
or an error."""


@dataclass
class StackedBlock:
    """One block of the tower: its tag id and side (mm, measured), where it was found,
    where its top was seen once set down (x, y, z mm), how far that is from the tower's
    axis (the bottom block: from the place asked), and the placements and grasps it took."""

    tag_id: int
    size_mm: float
    found_mm: tuple[float, float]
    seen_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    error_mm: float = 0.0
    placements: int = 0
    grasps: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {"tag_id": self.tag_id, "size_mm": round(self.size_mm, 2),
                "found_mm": [round(v, 1) for v in self.found_mm],
                "seen_mm": [round(v, 2) for v in self.seen_mm],
                "error_mm": round(self.error_mm, 2), "placements": self.placements,
                "grasps": self.grasps}


@dataclass
class StackReport:
    """The run: the ids to stack in order, where, the tower so far (bottom first), its
    height as looked at (mm over the table) and as the blocks' sides add up, and how it
    ended (``ENDS``) and why."""

    ids: list[int] = field(default_factory=list)
    place_mm: tuple[float, float] | None = None
    tower: list[StackedBlock] = field(default_factory=list)
    height_mm: float = 0.0
    end: str = ""
    why: str = ""
    seconds: float = 0.0

    @property
    def expected_height_mm(self) -> float:
        """The sides of the blocks stacked, added up."""
        return sum(b.size_mm for b in self.tower)

    @property
    def order(self) -> list[int]:
        return [b.tag_id for b in self.tower]

    def mean_error_mm(self) -> float | None:
        """The blocks' mean placement error as looked at, above the bottom one (None:
        fewer than two)."""
        above = [b.error_mm for b in self.tower[1:]]
        return sum(above) / len(above) if above else None

    def to_dict(self) -> dict[str, Any]:
        mean = self.mean_error_mm()
        return {
            "format": "busarm.stack_report", "version": 1, "ids": self.ids,
            "place_mm": None if self.place_mm is None else [round(v, 1) for v in self.place_mm],
            "order": self.order, "height_mm": round(self.height_mm, 2),
            "expected_height_mm": round(self.expected_height_mm, 2),
            "mean_error_mm": None if mean is None else round(mean, 2),
            "end": self.end, "why": self.why, "seconds": round(self.seconds, 2),
            "tower": [b.to_dict() for b in self.tower],
        }

    def text(self) -> str:
        """The report on one line, for a person."""
        if not self.tower:
            built = "no block stacked"
        else:
            order = " < ".join(str(i) for i in self.order)
            errors = ", ".join(f"{b.error_mm:.1f}" for b in self.tower)
            built = (f"tower {order} (bottom first) at ({self.place_mm[0]:.0f}, "
                     f"{self.place_mm[1]:.0f}) mm, {self.height_mm:.1f} mm tall as looked at "
                     f"({self.expected_height_mm:.1f} mm of blocks), placement errors "
                     f"{errors} mm" if self.place_mm is not None else f"tower {order}")
        return f"{built}; {self.end or 'not finished'}" + (f": {self.why}" if self.why else "")
