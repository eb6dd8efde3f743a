"""What a pick-and-sort run did: one record per block, and the run's report."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "BlockOutcome",
    "RunReport",
]


@dataclass
class BlockOutcome:
    """What happened to one block."""

    color: str
    found_mm: tuple[float, float]
    outcome: str = "pending"
    """``sorted``, ``failed``, ``skipped`` or ``moved`` (gone from where it was seen after
    a missed grasp; if it is seen elsewhere, it has a record of its own there)."""
    reason: str = ""
    placed_mm: tuple[float, float] | None = None
    attempts: int = 0
    seconds: float = 0.0
    grasp_pitch_deg: float | None = None
    """The tool's pitch at the last grasp: -90 straight down, else tilted."""
    place: str = ""
    """The bin it was taken to (by the sorting rule), once it is."""
    steps_s: list[tuple[str, float]] = field(default_factory=list)
    """Where its last cycle's time went: each step's name (``closer``, ``confirmed``,
    ``above``, ``grip``, ``lift``, ``carry``, ``release``, ``done``) and when it ended, in
    seconds since the cycle began."""

    def to_dict(self) -> dict[str, object]:
        return {"color": self.color, "found_mm": [round(v, 1) for v in self.found_mm],
                "outcome": self.outcome, "reason": self.reason,
                "placed_mm": None if self.placed_mm is None else
                [round(v, 1) for v in self.placed_mm],
                "attempts": self.attempts, "seconds": round(self.seconds, 2),
                "grasp_pitch_deg": self.grasp_pitch_deg, "place": self.place,
                "steps_s": [[name, round(t, 3)] for name, t in self.steps_s]}


@dataclass
class RunReport:
    blocks: list[BlockOutcome] = field(default_factory=list)
    seconds: float = 0.0
    stopped: str = ""
    """Why the run stopped before the table was clear (empty if it did not)."""
    gripper: str = ""
    """The gripper's state when it stopped that way, as read back."""

    def totals(self) -> dict[str, object]:
        """Counts per outcome, the median cycle in s (None before a block is sorted: JSON
        has no NaN) and the run's seconds."""
        done = [b for b in self.blocks if b.outcome == "sorted"]
        cycle = round(float(np.median([b.seconds for b in done])), 2) if done else None
        return {"sorted": len(done),
                "failed": sum(b.outcome == "failed" for b in self.blocks),
                "skipped": sum(b.outcome == "skipped" for b in self.blocks),
                "moved": sum(b.outcome == "moved" for b in self.blocks),
                "median_cycle_s": cycle, "seconds": round(self.seconds, 1)}
