"""Mapping and navigation on the mobile base: ``build_map`` explores a room with the Lidar
(``explore``), ``Navigator`` localises on a map, plans and follows paths (``navigator``);
both read the Lidar scan after scan (``sensing``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.apps.navigation.explore import MapRun, build_map
    from busarm.apps.navigation.navigator import Navigator, NavSettings, Trip

__all__ = [
    "MapRun",
    "NavSettings",
    "Navigator",
    "Trip",
    "build_map",
]

_SOURCES = {
    "build_map": ".explore",
    "MapRun": ".explore",
    "Navigator": ".navigator",
    "NavSettings": ".navigator",
    "Trip": ".navigator",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
