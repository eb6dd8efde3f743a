"""``actions list``: the sample action groups shipped with busarm, playable by name."""

from __future__ import annotations

import json

import click
from rich.table import Table

from busarm.arm.action_samples import SAMPLES, read_sample, sample_names
from busarm.cli.common import ArmContext, pass_arm

__all__ = [
    "samples_list",
]


@click.command("list")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@pass_arm
def samples_list(ac: ArmContext, as_json: bool) -> None:
    """The sample action groups: `busarm actions play NAME` plays one. No bus needed."""
    groups = {name: read_sample(name) for name in sample_names()}
    if as_json:
        click.echo(json.dumps({"samples": [
            {"name": name, "frames": len(g.frames), "duration_s": g.total_duration_ms / 1000.0,
             "description": SAMPLES[name].description} for name, g in groups.items()]}))
        return
    table = Table(title="sample action groups (busarm actions play NAME)", title_justify="left")
    table.add_column("name")
    table.add_column("frames", justify="right")
    table.add_column("time", justify="right")
    table.add_column("what it does")
    for name, g in groups.items():
        table.add_row(name, str(len(g.frames)), f"{g.total_duration_ms / 1000.0:.1f} s",
                      SAMPLES[name].description)
    ac.settings.out.print(table)
