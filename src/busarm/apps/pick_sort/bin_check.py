"""The bins looked into at the end of a pick-and-sort run: a block reported sorted that
the camera does not find in its bin (it bounced out, say) is reported failed instead."""

from __future__ import annotations

import math
from collections.abc import Callable

from busarm.apps.pick_sort.bins import TRAY_INSIDE_MM, BinPlaces
from busarm.apps.pick_sort.outcomes import RunReport
from busarm.apps.pick_sort.table_view import TableView
from busarm.errors import ConfigError
from busarm.units import place_text

__all__ = [
    "IN_TRAY_SLACK_MM",
    "RECOUNT_TURNS_DEG",
    "check_bins",
    "count_in_bin",
]


RECOUNT_TURNS_DEG = (40.0, -40.0)
"""Where a bin's check looks again from, turned from facing it, while it sees fewer blocks
there than were put in (blocks side by side in a tray can look like one)."""
IN_TRAY_SLACK_MM = 6.0
"""A block seen this far beyond a tray's inside (over its 2 mm wall) is still in it (one on
the second layer is seen a little beyond where it stands); one that fell out stands at
least half its side beyond the wall."""


def count_in_bin(view: TableView, places: BinPlaces, name: str, expected: int, *,
                 any_color: bool = False) -> int | None:
    """How many blocks bin ``name`` holds, as ``view``'s camera sees them from the look
    pose facing it and, while fewer than ``expected`` show, turned ``RECOUNT_TURNS_DEG``
    from there (the most seen; a block under another counted); blocks of its colour
    only unless ``any_color``. None if no look at it reaches."""
    arm = view.arm
    bx, by = places.bins[name]
    look = arm.config.pose("look")
    bearing = math.degrees(math.atan2(by, bx))
    reach = TRAY_INSIDE_MM + IN_TRAY_SLACK_MM
    most: int | None = None
    for turn in (0.0, *RECOUNT_TURNS_DEG):
        try:
            pose = arm.config.check_joints((bearing + turn, *look[1:]))
        except ConfigError:
            continue
        _, found = view.look(pose)
        inside = [v for v in found if (any_color or v.color == name)
                  and abs(v.location.x_mm - bx) < reach and abs(v.location.y_mm - by) < reach]
        seen = len(inside) + places.covered(name)
        most = seen if most is None else max(most, seen)
        if most >= expected:
            break
    return most


def check_bins(report: RunReport, view: TableView, places: BinPlaces, *,
               any_color: bool = False, progress: Callable[[str], None] = lambda _: None
               ) -> None:
    """Look into each bin of ``places`` a block of ``report`` was put in: one reported
    sorted that is not seen there is reported failed instead (said to ``progress``)."""
    for name in places.bins:
        sorted_here = [b for b in report.blocks if b.outcome == "sorted"
                       and (b.place or b.color) == name]
        if not sorted_here:
            continue
        seen = count_in_bin(view, places, name, len(sorted_here), any_color=any_color)
        if seen is None:
            continue  # no look at it from here: the release is trusted
        for missing in sorted_here[seen:]:
            missing.outcome = "failed"
            missing.reason = "not in its bin when the bins were checked (it fell out?)"
            progress(f"{missing.color} block from {place_text(missing.found_mm)}: not in "
                     "its bin")
