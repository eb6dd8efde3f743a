"""What every ``busarm bench`` report shares: progress on stderr, the seeded-world options,
targets judged ok or FAIL, and the report printed as text or JSON (a FAIL makes the exit
code 1). Shared by the bench command modules as ``common`` is by all commands."""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from dataclasses import replace
from typing import Any

import click
from rich.console import Console

from busarm.cli.common import JobNotDone, Settings, no_servos, pass_settings

__all__ = [
    "judged",
    "said",
    "seeded_world_options",
    "verdict",
]


def said(settings: Settings) -> Callable[[str], None]:
    """A benchmark's progress, said on stderr."""
    return lambda text: settings.err.print(text, highlight=False)


def seeded_world_options(name: str, default: int, help_text: str
                          ) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """A benchmark over seeded twin worlds: ``--NAME`` (how many, 1..1000), --seed (the
    first one's), --workers, --json; the settings passed, no servos."""
    world = name.removesuffix("s")

    def options(func: Callable[..., Any]) -> Callable[..., Any]:
        func = pass_settings(no_servos(func))
        for option in (  # the last applied is the first listed
                click.option("--json", "as_json", is_flag=True,
                             help="Print the report as JSON."),
                click.option("--workers", type=click.IntRange(1, 8), default=1,
                             show_default=True, help=f"{world.capitalize()}s run side by "
                             "side, each in its own process."),
                click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0,
                             show_default=True, help=f"Seed of the first {world}."),
                click.option(f"--{name}", type=click.IntRange(1, 1000), default=default,
                             show_default=True, help=help_text)):
            func = option(func)
        return func
    return options


_MISSED = "busarm.bench.missed"
"""ctx.meta key: how many targets the report just judged missed."""


def verdict(good: bool) -> str:
    """ok or FAIL, as the report shows it; a FAIL is counted (``judged``)."""
    if not good:
        meta = click.get_current_context().meta
        meta[_MISSED] = meta.get(_MISSED, 0) + 1
    return "[green]ok[/]" if good else "[red]FAIL[/]"


def judged(settings: Settings, as_json: bool, data: dict[str, Any],
            show: Callable[[Settings], None]) -> None:
    """Print the report, as text (``show``) or JSON, and judge it by the targets the text
    gives: a target missed (FAIL) makes the exit code 1, after the whole report."""
    show(replace(settings, out=Console(file=io.StringIO())) if as_json else settings)
    if as_json:
        click.echo(json.dumps(data, indent=2))
    missed = click.get_current_context().meta.get(_MISSED, 0)
    if missed:
        raise JobNotDone(f"{missed} target(s) missed: FAIL in the report")
