"""The help in one style on every command: after an option's text one bracket of extras,
``[env var: ...; default: ...; 0<=x<=9; required]`` (click's own order), never two (a
default written in the text and click's range, say) and no full stop after it; a range
the text gives already is not said again; a number option's metavar names its unit
(``MM``, ``DEG_S``, ``MS``) or kind (``N`` for counts)."""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence

import click

__all__ = [
    "UNIT_METAVARS",
    "OneStyleContext",
    "OneStyleFormatter",
    "apply",
    "metavar_from_help",
    "one_bracket",
    "unit_metavar",
]


_EXTRAS = re.compile(r"\s*\[((?:env var|default|required|-?[\d.]+<=x|x[<>]=?)[^\[\]]*)\]")
"""A bracket of extras, click's or one written in the help text."""
_RANGE = re.compile(r"^(-?[\d.]+)<=x<=(-?[\d.]+)$")
_TEXT_RANGE = re.compile(r"(-?\d+(?:\.\d+)?)\.\.(-?\d+(?:\.\d+)?)")
_ORDER = ("env var", "default", "", "required")  # "": a range

UNIT_METAVARS = {"s": "S", "ms": "MS", "mm": "MM", "deg": "DEG", "deg/s": "DEG_S",
                 "mm/s": "MM_S", "px": "PX", "V": "V", "C": "C", "x": "FACTOR",
                 "frames/s": "FPS", "probability": "PROBABILITY", "m": "M", "m/s": "M_S"}
"""The metavar of a number option in each unit."""
_UNITS_IN_TEXT = ("mm/s", "deg/s", "frames/s", "probability", "ms", "mm", "deg", "px", "s")
"""Looked for in a number option's help, in this order (``mm/s`` before ``mm``)."""


def unit_metavar(unit: str) -> str | None:
    """The metavar of a number in ``unit`` (None if the unit has none)."""
    return UNIT_METAVARS.get(unit)


def metavar_from_help(text: str) -> str:
    """The metavar of a (non-integer) number option whose help says its unit."""
    for unit in _UNITS_IN_TEXT:
        if re.search(rf"(?<![\w'/.]){re.escape(unit)}(?![\w/])", text, re.IGNORECASE):
            return UNIT_METAVARS[unit]
    return "NUMBER"


def _kind(item: str) -> int:
    return next((i for i, key in enumerate(_ORDER) if key and item.startswith(key)), 2)


def _said(item: str, text: str) -> bool:
    """Whether ``item`` is a range the text gives already (``50..100``, ``(0..1)``)."""
    bounds = _RANGE.match(item)
    return bounds is not None and any(
        float(lo) == float(bounds[1]) and float(hi) == float(bounds[2])
        for lo, hi in _TEXT_RANGE.findall(text))


def one_bracket(help_text: str) -> str:
    """``help_text`` with its brackets of extras made one, in click's order."""
    items: list[str] = []

    def take(match: re.Match[str]) -> str:
        items.extend(item.strip() for item in match[1].split("; "))
        return ""

    text = _EXTRAS.sub(take, help_text).rstrip()
    items = sorted((i for i in items if not _said(i, text)), key=_kind)
    return f"{text}  [{'; '.join(items)}]" if items else text


class OneStyleFormatter(click.HelpFormatter):
    """Writes every option's help in one style (``one_bracket``)."""

    def write_dl(self, rows: Sequence[tuple[str, str]], col_max: int = 30,
                 col_spacing: int = 2) -> None:
        super().write_dl([(term, one_bracket(text)) for term, text in rows], col_max,
                         col_spacing)


class OneStyleContext(click.Context):
    formatter_class = OneStyleFormatter


def _commands(group: click.Group) -> Iterator[click.Command]:
    for command in group.commands.values():
        yield command
        if isinstance(command, click.Group):
            yield from _commands(command)


def apply(root: click.Group) -> None:
    """Give ``root`` and every command under it the one help style (call once, after
    every command is added)."""
    for command in (root, *_commands(root)):
        command.context_class = OneStyleContext
