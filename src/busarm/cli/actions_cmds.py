"""``actions``: action groups in the vendor's .d6a format (or the shipped samples): show
their frames, play them, record one by teaching. ``actions list`` is ``samples_cmd``'s.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click
from rich.table import Table

from busarm.arm.action_samples import read_group_or_sample
from busarm.arm.actions import ActionFrame, ActionGroup, write_d6a
from busarm.cli.common import (
    ArmContext,
    RangeType,
    Settings,
    arm_options,
    check_writable,
    hold_where_it_stands,
    pass_arm,
    pass_settings,
)
from busarm.errors import ConfigError

__all__ = [
    "COMMANDS",
    "actions",
    "play",
    "record",
    "show",
]


@click.group()
@arm_options
@pass_settings
@click.pass_context
def actions(ctx: click.Context, settings: Settings, config: str, calibration: str | None) -> None:
    """Action groups in the vendor's .d6a format: show, play, record by teaching."""
    ctx.obj = ArmContext(settings, config, calibration)


def _group_table(ac: ArmContext, group: ActionGroup) -> Table:
    table = Table(title=f"{len(group.frames)} frames, {group.total_duration_ms / 1000:.1f} s",
                  title_justify="left")
    table.add_column("#", justify="right")
    table.add_column("time (ms)", justify="right")
    columns = ac.config.action_columns
    for sid in columns:
        table.add_column(f"servo {sid}", justify="right")
    for n, frame in enumerate(group.frames, start=1):
        table.add_row(str(n), str(frame.duration_ms), *(str(p) for p in frame.positions_pulses))
    return table


@actions.command()
@click.argument("file", metavar="FILE|SAMPLE")
@click.option("--json", "as_json", is_flag=True, help="Print JSON.")
@pass_arm
def show(ac: ArmContext, file: str, as_json: bool) -> None:
    """Show the frames of a .d6a file or a sample (pulses; joint angles in JSON). No bus
    needed."""
    group, _ = read_group_or_sample(file)
    if as_json:
        columns = ac.config.action_columns
        frames = []
        for frame in group.frames:
            item: dict[str, Any] = {
                "duration_ms": frame.duration_ms,
                "pulses": {str(s): p for s, p in zip(columns, frame.positions_pulses,
                                                     strict=False)},
            }
            if group.servo_count == len(columns):
                by_id = dict(zip(columns, frame.positions_pulses, strict=True))
                item["joints_deg"] = {
                    j.name: round(j.angle_deg_from_pulses(by_id[j.servo_id]), 3)
                    for j in ac.config.joints if j.servo_id in by_id
                }
            frames.append(item)
        click.echo(json.dumps({"file": str(file), "columns": list(columns), "frames": frames}))
        return
    ac.settings.out.print(_group_table(ac, group))


@actions.command()
@click.argument("file", metavar="FILE|SAMPLE")
@click.option("--speed-scale", type=RangeType("speed scale", 0.1, 10.0, "x"), default=1.0,
              show_default=True, metavar="FACTOR",
              help="Play faster (>1) or slower (<1): a factor of the recorded times.")
@pass_arm
def play(ac: ArmContext, file: str, speed_scale: float) -> None:
    """Play a .d6a action group, or a sample by name (`busarm actions list`).

    Ctrl+C stops the arm and holds it, and says at which frame.
    """
    group, _ = read_group_or_sample(file)
    total = len(group.frames)
    reached = 0

    def on_frame(n: int) -> None:
        nonlocal reached
        reached = n
        ac.settings.err.print(f"frame {n} of {total}", highlight=False)

    try:
        with ac.open() as a:
            a.action_targets(group)  # every frame checked before the first moves
            played = a.play(group, speed_scale=speed_scale, on_frame=on_frame)
    except KeyboardInterrupt as exc:
        where = f"at frame {reached} of {total}" if reached else f"before frame 1 of {total}"
        raise click.Abort(f"interrupted {where}") from exc
    ac.settings.out.print(f"played {played} of {total} frames", highlight=False)


@actions.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--interval", type=RangeType("interval", 0.05, 60.0, "s"),
              help="Capture a frame every S seconds  [default: one per Enter key]")
@click.option("--frames", "max_frames", type=click.IntRange(1, 10000),
              help="Stop after this many frames  [default: at Ctrl+C, or 'q' + Enter]")
@click.option("--time", "time_s", type=RangeType("time", 0.0, 30.0, "s"), metavar="S",
              help="Time of each frame in s  [default: the interval, or 1]")
@pass_arm
def record(ac: ArmContext, file: Path, interval: float | None, max_frames: int | None,
           time_s: float | None) -> None:
    """Record an action group by teaching: torque off, move the arm by hand.

    Each Enter (or each --interval) captures the present pose as one frame. At the end
    the servos hold where they are and FILE is written (atomically). A Ctrl+C ends it
    too: the frames so far are written, and the exit code is 130.
    """
    settings = ac.settings
    check_writable(file)  # before the teaching, not after it
    duration_ms = round(1000 * time_s) if time_s is not None else (
        round(interval * 1000) if interval else 1000)
    frames: list[ActionFrame] = []
    stopped_by: KeyboardInterrupt | None = None
    with ac.open() as a:
        a.set_torque(False)
        try:  # from the torque off: a Ctrl+C at once still leaves the arm holding
            settings.err.print("torque off: move the arm by hand; " + (
                "Ctrl+C ends" if interval else "Enter captures, q + Enter ends"))
            while max_frames is None or len(frames) < max_frames:
                if interval:
                    a.clock.sleep(interval if frames else 0.0)
                else:
                    line = sys.stdin.readline()
                    if not line or line.strip().lower() == "q":
                        break
                frames.append(a.record_frame(duration_ms))
                settings.err.print(f"frame {len(frames)}: "
                                   f"{' '.join(str(p) for p in frames[-1].positions_pulses)}")
        except KeyboardInterrupt as exc:  # what was taught is kept; exit code 130
            stopped_by = exc
        finally:
            hold_where_it_stands(a, settings)
        if frames:
            write_d6a(file, ActionGroup(tuple(frames)))
            settings.out.print(f"wrote {len(frames)} frames to {file}", highlight=False)
        if stopped_by is not None:  # inside the bus: the line says what the servos do
            raise click.Abort(f"interrupted after frame {len(frames)}" if frames else
                              "interrupted before any frame: nothing written") from stopped_by
    if not frames:
        raise ConfigError("no frame recorded: nothing written")


COMMANDS = [actions]
