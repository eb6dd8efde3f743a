"""``sim serve``: the simulated arm on a pseudo-terminal, for any serial program.

The simulator is imported when a command runs, so the rest of the CLI never
depends on it.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.cli.common import (
    CheckedType,
    Settings,
    announced,
    pass_settings,
    serve_until_stopped,
)
from busarm.errors import ConfigError
from busarm.units import parse_ids

if TYPE_CHECKING:
    pass

__all__ = [
    "COMMANDS",
    "PROBABILITY",
    "SimIdsType",
    "serve",
    "sim",
]


class SimIdsType(CheckedType):
    """Servo IDs for the simulator; a repeated ID puts two servos on it (a conflict)."""

    name = "ids"

    def parse(self, text: str) -> list[int]:
        return parse_ids(text)


PROBABILITY = click.FloatRange(0.0, 1.0)


@click.group()
def sim() -> None:
    """The simulated arm (servos 1-5 and gripper 10), for tests and other programs."""


@sim.command()
@click.option("--ids", type=SimIdsType(), default="1,2,3,4,5,10", show_default=True,
              help="Servo IDs; repeat one (1,1,2) to simulate two servos sharing an ID.")
@click.option("--echo", is_flag=True,
              help="Echo every byte the host sends, like a one-wire adapter.")
@click.option("--no-timing", is_flag=True,
              help="Answer at once instead of at the speed of the wire.")
@click.option("--turnaround-ms", type=click.FloatRange(0.0, 100.0), default=0.5,
              show_default=True, help="Delay in ms before a servo starts its reply.")
@click.option("--drop", type=PROBABILITY, default=0.0, show_default=True,
              help="Probability (0..1) that each byte on the wire is lost.")
@click.option("--corrupt", type=PROBABILITY, default=0.0, show_default=True,
              help="Probability (0..1) that each byte on the wire is corrupted.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the fault generator (same seed, same faults).")
@click.option("--state", type=click.Path(dir_okay=False, path_type=Path),
              help="JSON file of the servos' stored settings (IDs, offsets, limits) and "
                   "horn positions: loaded if it exists (then --ids is ignored), rewritten "
                   "on every stored write and, with the positions, when it stops.")
@click.option("--block", is_flag=True,
              help="A 3 cm block sits between the gripper's fingers (servo 10 stops on it).")
@click.option("--board", is_flag=True,
              help="Behind a simulated controller board: the board's frames at 1,000,000 "
                   "baud on the pty (port board:///dev/pts/N), IMU and battery reports, four "
                   "wheel motors.")
@pass_settings
def serve(
    settings: Settings, ids: list[int], echo: bool, no_timing: bool, turnaround_ms: float,
    drop: float, corrupt: float, seed: int, state: Path | None, block: bool, board: bool,
) -> None:
    """Serve simulated servos on a new pseudo-terminal until SIGINT (Ctrl+C) or SIGTERM,
    its way to stop: exit code 0.

    The first line of stdout is the port to give --port: the device path (e.g.
    /dev/pts/7; open it with any serial program, at any baud rate: the simulated wire
    runs at --baud), or with --board board:///dev/pts/7 (the board's link at 1,000,000
    baud, its servo line at --baud).
    """
    from busarm.sim.board import SimBoard
    from busarm.sim.bus import FaultInjection, SimBus, WireTiming

    if board and echo:
        raise ConfigError("--echo: a controller board's link does not echo (give one of "
                          "--board and --echo)")
    from busarm.clock import WALL_CLOCK
    from busarm.sim.pty import PtyServer

    bus = SimBus.with_ids(
        ids,
        timing=WireTiming(settings.baudrate, turnaround_ms / 1000.0, not no_timing),
        echo=echo,
        faults=FaultInjection(drop_rate=drop, corrupt_rate=corrupt, seed=seed),
        state_file=state,
        clock=WALL_CLOCK,  # served: the programs at the pty wait in wall-clock time
    )
    if block:
        bus.put_block_in_gripper()
    server = PtyServer(SimBoard(bus) if board else bus)
    path = server.open()
    port = f"board://{path}" if board else path
    # Found by commands without --port while it runs; written before the path is shown,
    # so that no client waits for it (the server answers only once it serves).
    with announced("sim", port):
        click.echo(port)
        sys.stdout.flush()
        servos = ", ".join(str(s.servo_id) for s in bus.servos)
        timing = "no wire timing" if no_timing else f"{settings.baudrate} baud"
        click.echo(
            f"simulating servos {servos} "
            + ("behind a controller board " if board else "") + f"on {path} ({timing}"
            + (", echo" if echo else "") + (f", state {state}" if state else "")
            + "); Ctrl+C or SIGTERM to stop; commands without --port use it",
            err=True,
        )
        serve_until_stopped(server)
    click.echo("simulator stopped", err=True)


COMMANDS = [sim]
