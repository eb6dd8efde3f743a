"""Packages whose names load on first use (PEP 562), so that importing a package costs
only what is used from it (``import busarm`` loads no MuJoCo, OpenCV or serial port)."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any

__all__ = ["lazy_exports"]


def lazy_exports(package: str, sources: Mapping[str, str], exported: Sequence[str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """A package's ``__getattr__`` and ``__dir__``: each name in ``sources`` is loaded
    from its module (``".sub"``: relative to ``package``) on first use, then kept."""
    missing = sorted(set(exported) - set(sources))
    if missing:
        raise ImportError(f"{package}.__all__ names {missing}, which no module gives")

    def __getattr__(name: str) -> Any:
        module = sources.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module, package), name)
        vars(sys.modules[package])[name] = value  # later look-ups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted({*vars(sys.modules[package]), *exported})

    return __getattr__, __dir__
