"""Tag stacking: the tagged blocks stacked at one place in tag-id order, lowest at the
bottom (``StackJob``; busarm.apps.stack.job says how).

The parts: ``tag_view`` (the blocks as their tags show them), ``job`` (the run),
``report`` and ``settings``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.apps.stack.job import StackJob
    from busarm.apps.stack.report import StackReport
    from busarm.apps.stack.settings import StackSettings

__all__ = [
    "StackJob",
    "StackReport",
    "StackSettings",
]

_SOURCES = {
    "StackJob": ".job",
    "StackReport": ".report",
    "StackSettings": ".settings",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
