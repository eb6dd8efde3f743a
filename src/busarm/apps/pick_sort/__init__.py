"""Pick-and-sort: look at the table, pick each coloured block, put it in its colour's bin
(``PickSorter``; ``PickJob`` is the run with its report, as every interface starts it).

The job's parts, one module each: ``sorter`` (the cycle), ``table_view`` (surveys),
``grasp`` and ``gripping`` (plans and the squeeze), ``push`` and ``restage`` (making room),
``footprint`` (what the fingers sweep), ``bins``, ``look_poses``, ``settings``, and the
run's records, outcomes and report (``records``, ``outcomes``, ``report``, ``job``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.apps.pick_sort.job import PickJob
    from busarm.apps.pick_sort.outcomes import RunReport
    from busarm.apps.pick_sort.settings import PickSortSettings
    from busarm.apps.pick_sort.sorter import PickSorter

__all__ = [
    "PickJob",
    "PickSortSettings",
    "PickSorter",
    "RunReport",
]

_SOURCES = {
    "PickSorter": ".sorter",
    "PickSortSettings": ".settings",
    "RunReport": ".outcomes",
    "PickJob": ".job",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
