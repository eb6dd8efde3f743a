"""Colour tracking: the arm looks down at the table and keeps a block of one colour
centred in the wrist camera while a person slides it about (``TrackJob``, ``job``), the
camera aimed through the arm's IK (``aim``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.apps.track.job import TrackJob, TrackReport, TrackSettings

__all__ = [
    "TrackJob",
    "TrackReport",
    "TrackSettings",
]

_SOURCES = {
    "TrackJob": ".job",
    "TrackReport": ".job",
    "TrackSettings": ".job",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
