"""Names that load on first use: packages' exports (PEP 562), so that importing a package
costs only what is used from it (``import busarm`` loads no MuJoCo, OpenCV or serial
port), and the backend tables (a name -> ``"module:factory"``, which an entry-point group
extends, as python-can's interface table), whose modules load when a backend is chosen."""

from __future__ import annotations

import importlib
import importlib.metadata
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from busarm.errors import ConfigError

__all__ = ["backend_table", "lazy_exports", "load_backend"]


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


def backend_table(builtins: Mapping[str, str], group: str) -> dict[str, str]:
    """``builtins`` (name -> ``"module:factory"``) and what installed packages add under
    the entry-point group ``group`` (``[project.entry-points."<group>"]`` in their
    pyproject). A built-in name is never replaced: a plugin cannot take over ``lx``."""
    found = {ep.name: ep.value for ep in importlib.metadata.entry_points(group=group)}
    return {**found, **builtins}


def load_backend(what: str, name: str, table: Mapping[str, str]) -> Callable[..., Any]:
    """The factory ``table`` names for ``name``, imported now (``"module:attr.attr"``);
    ConfigError naming the known names, or why it cannot load. ``what`` names the kind
    of backend in messages (``servo port``, ``Lidar``)."""
    target = table.get(name)
    if target is None:
        raise ConfigError(f"{what} {name!r} is not known; known: {', '.join(sorted(table))}")
    module_name, _, path = target.partition(":")
    try:
        value: Any = importlib.import_module(module_name)
        for attr in path.split("."):
            value = getattr(value, attr)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ConfigError(f"{what} {name!r}: cannot load {target}: {exc}") from exc
    if not callable(value):
        raise ConfigError(f"{what} {name!r}: {target} is not callable")
    factory: Callable[..., Any] = value
    return factory
