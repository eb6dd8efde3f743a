"""Reading the TOML files that describe the robot's parts (the arm, the chassis).

One reader checks every value as it is read; an error names the file, the key, the bad
value and the allowed range. Unknown keys are refused (a misspelt key would otherwise be
silently ignored, and its default used).
"""

from __future__ import annotations

import sys
from importlib import resources
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError
from busarm.units import check_int_range, check_range, listing, shown

__all__ = [
    "TomlReader",
    "load_toml",
    "parse_toml",
    "toml_string",
]


if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib


def load_toml(name_or_path: str | Path, *, what: str, package: str,
              shipped: tuple[str, ...]) -> tuple[dict[str, Any], str]:
    """A shipped file by name (``package``/configs/NAME.toml) or any file by path: its
    table and where it came from."""
    if isinstance(name_or_path, str) and name_or_path in shipped:
        source = f"{name_or_path} (shipped)"
        text = (resources.files(package) / "configs" / f"{name_or_path}.toml").read_text(
            encoding="utf-8")
    else:
        path = Path(name_or_path)
        source = str(path)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            listed = f" (shipped: {', '.join(shipped)})" if shipped else ""
            raise ConfigError(f"{what} {path}: no such file{listed}") from None
        except (OSError, UnicodeDecodeError) as exc:
            raise ConfigError(f"{what} {path}: cannot read it: {exc}") from None
    return parse_toml(text, what=what, source=source), source


def parse_toml(text: str, *, what: str, source: str) -> dict[str, Any]:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{what} {source}: not valid TOML: {exc}") from None


class TomlReader:
    """Checked reads from one parsed file; errors say ``WHAT SOURCE: KEY: ...``."""

    def __init__(self, what: str, source: str) -> None:
        self.what = what
        self.source = source

    def fail(self, key: str, message: str) -> ConfigError:
        return ConfigError(f"{self.what} {self.source}: {key}: {message}")

    def table(self, data: dict[str, Any], key: str) -> dict[str, Any]:
        value = data.get(key)
        if not isinstance(value, dict):
            raise self.fail(key, "missing table" if value is None else "must be a table")
        return value

    def number(
        self, data: dict[str, Any], key: str, where: str, lo: float, hi: float,
        default: float | None = None,
    ) -> float:
        value = data.get(key, default)
        name = f"{where}.{key}"
        if value is None:
            raise self.fail(name, "missing")
        return check_range(f"{self.what} {self.source}: {name}", value, lo, hi)

    def integer(
        self, data: dict[str, Any], key: str, where: str, lo: int, hi: int,
        default: int | None = None,
    ) -> int:
        value = data.get(key, default)
        name = f"{where}.{key}"
        if value is None:
            raise self.fail(name, "missing")
        if isinstance(value, bool) or not isinstance(value, int):  # named without the range
            raise self.fail(name, f"must be an integer, got {shown(value)}")
        return check_int_range(f"{self.what} {self.source}: {name}", value, lo, hi)

    def unknown(self, data: dict[str, Any], where: str, known: set[str]) -> None:
        extra = sorted(set(data) - known)
        if extra:
            raise self.fail(where, f"unknown key(s) {listing(extra)}; known: "
                                   f"{listing(sorted(known))}")

    def header(self, data: dict[str, Any], fmt: str, version: int) -> str:
        """Check ``format`` and ``version``; return the file's non-empty ``name``."""
        if data.get("format") != fmt:
            raise self.fail("format", f"must be {fmt!r}, got {data.get('format')!r}")
        if data.get("version") != version:
            raise self.fail("version", f"{data.get('version')!r}; this busarm reads version "
                                       f"{version}")
        name = data.get("name")
        if not isinstance(name, str) or not name.strip():
            raise self.fail("name", f"must be a non-empty string, got {name!r}")
        return name


def toml_string(text: str) -> str:
    """``text`` as a TOML basic string: quotes, backslashes and control characters escaped."""
    return '"' + "".join(f"\\u{ord(c):04x}" if c in '"\\' or ord(c) < 0x20 or ord(c) == 0x7F
                         else c for c in text) + '"'
