"""``lidar scan | serve``: the 2D Lidar (a Slamtec RPLIDAR A1) on its own serial port.

The Lidar is not on the servo bus, so these commands take their own ``--lidar`` (or
$BUSARM_LIDAR), not the global --port; by default the simulated A1 in this process.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.cli.common import (
    RangeType,
    Settings,
    lidar_port_or_default,
    pass_settings,
    serve_until_stopped,
)

if TYPE_CHECKING:
    from busarm.robot.description import LidarPort

__all__ = [
    "COMMANDS",
    "LIDAR_OPTION",
    "lidar",
    "modes",
    "scan",
    "serve",
]


LIDAR_OPTION = click.option(
    "--lidar", "lidar_port", default=None, envvar="BUSARM_LIDAR",
    help="The Lidar's serial port (e.g. /dev/ttyUSB1, its own, not the servo bus's --port; "
         "or $BUSARM_LIDAR); lidar://sim[?hz=10] for the simulated A1 in a room, or "
         "twin://?family=arena[&seed=N] for a twin's, in this process. [default: the Lidar "
         "of a running `busarm twin serve --arena`, else lidar://sim]")


@click.group()
def lidar() -> None:
    """The 2D Lidar: a Slamtec RPLIDAR A1 on its own USB serial port (--lidar)."""


@lidar.command()
@LIDAR_OPTION
@click.option("--png", type=click.Path(dir_okay=False, path_type=Path),
              help="Also write a polar picture of the scan to this PNG file.")
@click.option("--json", "as_json", is_flag=True,
              help="Print the device, the summary and every beam as JSON.")
@click.option("--timeout", "timeout_s", type=RangeType("timeout", 0.2, 30.0, "s"), default=2.0,
              show_default=True, help="How long to wait for a complete revolution, in s.")
@click.option("--express", is_flag=True,
              help="Read the express scan (capsules; 4,000 samples/s on an A1) instead of "
                   "the standard one (2,000).")
@pass_settings
def scan(settings: Settings, lidar_port: str | None, png: Path | None, as_json: bool,
         timeout_s: float, express: bool) -> None:
    """Read one 360-degree scan: how many returns, the rate, the nearest return and its
    bearing (degrees counter-clockwise from the Lidar's forward axis). Without --lidar:
    the Lidar of --robot's robot file, or of the twin --port names (with an arena)."""
    from busarm.robot.lidar_port import open_lidar_port

    where = _lidar_port(settings, lidar_port)
    lidar_port = where.name
    with open_lidar_port(where) as device:
        device.use_express(express)
        one = device.read_scan(timeout_s)
        info, health = device.info, device.health
    returns = int(one.valid.sum())
    nearest = one.nearest()
    model = (f"RPLIDAR model 0x{info.model:02X} (firmware {info.firmware[0]}."
             f"{info.firmware[1]:02d}, hardware {info.hardware}) on {lidar_port}")
    if png is not None:
        from busarm.lidar.picture import write_scan_png

        write_scan_png(one, png, f"{model}: {returns} returns")
    if as_json:
        click.echo(json.dumps({
            "port": lidar_port, "model": info.model, "firmware": list(info.firmware),
            "hardware": info.hardware, "serial": info.serial_hex, "health": health.status.name,
            "beams": len(one), "returns": returns, "rate_hz": _number(one.rate_hz),
            "nearest_m": nearest[0] if nearest else None,
            "nearest_bearing_deg": math.degrees(nearest[1]) if nearest else None,
            "angles_deg": [round(math.degrees(a), 4) for a in one.angles_rad],
            "ranges_m": [_number(r) for r in one.ranges_m],
            "png": str(png) if png else None,
        }))
        return
    click.echo(model)
    rate = f"{one.rate_hz:.1f} Hz" if math.isfinite(one.rate_hz) else "rate unknown"
    click.echo(f"{len(one)} beams, {returns} returns, {rate}")
    if nearest is None:
        click.echo("no return in range")
    else:
        click.echo(f"nearest return {nearest[0]:.3f} m at bearing {math.degrees(nearest[1]):.1f} "
                   "deg (counter-clockwise from forward)")
    if png is not None:
        click.echo(f"polar picture written to {png}")


@lidar.command()
@LIDAR_OPTION
@pass_settings
def modes(settings: Settings, lidar_port: str | None) -> None:
    """The Lidar's sample rate and scan modes (GET_SAMPLERATE, GET_LIDAR_CONF, as
    Slamtec's SDK asks them; an A1 answers from firmware 1.24 on)."""
    from busarm.robot.lidar_port import open_lidar_port

    where = _lidar_port(settings, lidar_port)
    with open_lidar_port(where) as device:
        rate = device.sample_rate()
        found, typical = device.scan_modes()
    click.echo(f"sample time: standard {rate.standard_us} us, express {rate.express_us} us")
    for mode in found:
        click.echo(f"mode {mode.id} {mode.name}: {mode.sample_hz:,.0f} samples/s, up to "
                   f"{mode.max_distance_m:g} m, answers type 0x{mode.answer_type:02X}"
                   f"{' (typical)' if mode.id == typical else ''}")


def _lidar_port(settings: Settings, lidar_port: str | None) -> LidarPort:
    """The Lidar --lidar names, else the robot's, else the default."""
    from busarm.robot.port_url import parse_lidar_port

    where = _robots_lidar(settings) if lidar_port is None else None
    if where is None:
        where = parse_lidar_port(lidar_port_or_default(lidar_port))
    return where


def _number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


@lidar.command()
@click.option("--hz", "scan_hz", type=RangeType("Hz", 2.0, 10.0, "Hz"), default=5.5,
              show_default=True, help="Revolutions a second, in Hz.")
@click.option("--garbage", type=click.FloatRange(0.0, 1.0), default=0.0, show_default=True,
              help="Probability (0..1) per measurement of 1-6 random bytes before it.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the garbage generator.")
def serve(scan_hz: float, garbage: float, seed: int) -> None:
    """Serve a simulated RPLIDAR A1 in a rectangular room on a new pseudo-terminal until
    SIGINT (Ctrl+C) or SIGTERM: exit code 0. The first line of stdout is its device path,
    for --lidar."""
    from busarm.clock import WALL_CLOCK
    from busarm.sim.pty import PtyServer
    from busarm.sim.rplidar import SimRplidar

    device = SimRplidar(scan_hz=scan_hz, garbage_rate=garbage, seed=seed, clock=WALL_CLOCK)
    server = PtyServer(device)
    path = server.open()
    click.echo(path)
    sys.stdout.flush()
    click.echo(f"simulating an RPLIDAR A1 on {path} ({scan_hz:g} Hz, {device.nodes_per_rev} "
               "measurements a revolution); Ctrl+C or SIGTERM to stop", err=True)
    serve_until_stopped(server)
    click.echo("simulated Lidar stopped", err=True)


COMMANDS = [lidar]


def _robots_lidar(settings: Settings) -> LidarPort | None:
    """The Lidar of the robot --robot or --port describes, if it says one: a robot file's
    Lidar, or a twin's own in its arena."""
    from busarm.twin.spec import TwinSpec

    if settings.on_robot_file:
        description = settings.robot_description()
        if description.lidar is not None:
            return description.lidar.port
        world = description.world
    elif settings.port_given:
        world = settings.world()
    else:
        return None
    if isinstance(world, TwinSpec) and world.mobile:
        return replace(world, controller=None)  # the twin's Lidar alone
    return None
