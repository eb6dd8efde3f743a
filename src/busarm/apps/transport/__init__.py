"""Navigation transport: fetch a block from one named point and deliver it to another
(``TransportJob``, ``job``), picking on the floor from the base (``mobile_pick``,
``workspace``), the carried block's heat watched (``carry``), with its report
(``report``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.apps.transport.job import TransportJob, TransportReport

__all__ = [
    "TransportJob",
    "TransportReport",
]

_SOURCES = {
    "TransportJob": ".job",
    "TransportReport": ".job",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
