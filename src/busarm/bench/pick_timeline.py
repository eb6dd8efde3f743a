"""Where a pick-and-sort cycle's time goes: each sorted block's steps
(``BlockOutcome.steps_s``) cut into phases, their medians, and a picture of the cycles."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from busarm.fileio import atomic_path

__all__ = [
    "PHASES",
    "Steps",
    "draw_timeline",
    "median_phases",
    "phases",
]

Steps = Sequence[tuple[str, float]]
"""A cycle's steps: each one's name and when it ended, in s since the cycle began."""

PHASES = (("closer", "look closer", "#9ecae1"), ("confirmed", "judge its shape", "#3182bd"),
          ("above", "approach", "#fdae6b"), ("grip", "descend, grip", "#e6550d"),
          ("lift", "lift", "#a1d99b"), ("carry", "carry", "#31a354"),
          ("release", "lower, release", "#bcbddc"), ("done", "rise", "#756bb1"))
"""Each phase by the step that ends it: (step, label, colour)."""
OTHER = ("other", "#bdbdbd")
"""Steps not in ``PHASES`` (a block set down to be taken again, a retry)."""


def phases(steps: Steps) -> list[tuple[str, float, float]]:
    """The cycle's phases in order: (label, start s, duration s)."""
    labels = {step: label for step, label, _ in PHASES}
    out, start = [], 0.0
    for step, end in steps:
        out.append((labels.get(step, OTHER[0]), start, max(0.0, end - start)))
        start = end
    return out


def median_phases(cycles: Sequence[Steps]) -> list[tuple[str, float]]:
    """Each phase's median duration (s) over ``cycles`` (a phase a cycle skipped counts 0)."""
    labels = [label for _, label, _ in PHASES] + [OTHER[0]]
    sums = [{label: 0.0 for label in labels} for _ in cycles]
    for total, steps in zip(sums, cycles, strict=True):
        for label, _, seconds in phases(steps):
            total[label] += seconds
    return [(label, float(np.median([s[label] for s in sums])) if sums else 0.0)
            for label in labels if any(s[label] > 0 for s in sums)]


def draw_timeline(cycles: Sequence[Steps], path: Path, title: str) -> None:
    """A PNG of ``cycles`` (one bar each, phases in colour), written atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    colours = {label: colour for _, label, colour in PHASES} | {OTHER[0]: OTHER[1]}
    fig = Figure(figsize=(8.0, 1.9 + 0.25 * max(len(cycles), 1)), dpi=100,
                 layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for row, steps in enumerate(cycles):
        for label, start, seconds in phases(steps):
            ax.barh(row, seconds, left=start, height=0.8, color=colours[label],
                    edgecolor="white", linewidth=0.5)
    ax.set_yticks(range(len(cycles)), [f"block {k + 1}" for k in range(len(cycles))],
                  fontsize=7)
    ax.set_ylim(len(cycles) - 0.5, -0.5)
    ax.set_xlabel("twin seconds since the cycle began")
    shown = [label for label in colours if any(p[0] == label for c in cycles
                                                 for p in phases(c))]
    ax.legend(handles=[Patch(color=colours[label], label=label) for label in shown],
              fontsize=7, ncol=4, loc="lower center", bbox_to_anchor=(0.5, 1.0),
              frameon=False)
    fig.suptitle(title, fontsize=9)
    with atomic_path(path, "timeline picture") as tmp:
        fig.savefig(tmp, format="png")
