"""Line following: a lap of the taped floor loop, stopping for obstacles and clearing
blocks off the line (``LineFollowJob``, ``job``), the wrist camera looking ahead at the
floor (``floor_look``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.apps.line_follow.job import LineFollowJob, LineFollowReport

__all__ = [
    "LineFollowJob",
    "LineFollowReport",
]

_SOURCES = {
    "LineFollowJob": ".job",
    "LineFollowReport": ".job",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
