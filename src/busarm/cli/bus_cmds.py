"""Commands about the bus as a whole: ``ports``, ``scan``, ``monitor``."""

from __future__ import annotations

import click
from rich.live import Live
from rich.table import Table

from busarm.bus.id_scan import SCAN_MARGIN_S
from busarm.bus.lx_port import LxServoPort
from busarm.bus.transport import usb_latency_timer_ms
from busarm.cli.common import (
    ID_LIST,
    RangeType,
    Settings,
    pass_settings,
    scan_report,
    scan_with_progress,
    state_table,
)
from busarm.errors import BusTimeoutError
from busarm.protocol import MAX_SERVO_ID

__all__ = [
    "COMMANDS",
    "SERVO_ADAPTERS",
    "monitor",
    "ports",
    "scan",
]


# USB-serial chips found on LX servo adapters (BusLinker boards, one-wire adapters, HATs).
SERVO_ADAPTERS: dict[tuple[int, int], str] = {
    (0x1A86, 0x7523): "CH340",
    (0x1A86, 0x55D4): "CH9102",
    (0x10C4, 0xEA60): "CP210x",
    (0x0403, 0x6001): "FTDI FT232R",
    (0x0403, 0x6015): "FTDI FT-X",
}


@click.command()
@pass_settings
def ports(settings: Settings) -> None:
    """List serial ports, marking the ones that look like a servo adapter.

    The latency column is the USB latency timer in ms (Linux, FTDI-style drivers):
    every reply waits that long, so 1 ms is best.
    """
    from serial.tools import list_ports

    found = sorted(list_ports.comports(), key=lambda p: p.device)
    if not found:
        settings.out.print("no serial ports found (a simulated bus is always there: --port sim)")
        return
    table = Table(title="serial ports", title_justify="left")
    for name in ("device", "USB VID:PID", "description", "servo adapter?", "latency (ms)"):
        table.add_column(name)
    for p in found:
        usb = f"{p.vid:04x}:{p.pid:04x}" if p.vid is not None and p.pid is not None else ""
        chip = SERVO_ADAPTERS.get((p.vid or -1, p.pid or -1))
        latency = usb_latency_timer_ms(p.device)
        lat = "" if latency is None else str(latency)
        if latency is not None and latency > 1:
            lat = f"[yellow]{latency} (set to 1)[/yellow]"
        table.add_row(
            p.device, usb, p.description or "",
            f"[green]yes: {chip}[/green]" if chip else "", lat,
        )
    settings.out.print(table)


@click.command()
@click.option(
    "--ids", "ids", type=ID_LIST, default=f"0-{MAX_SERVO_ID}", show_default=True,
    help="IDs to ask, e.g. 0-20 or 1,2,3,10.",
)
@click.option(
    "--margin-ms", type=RangeType("margin", 0.0, 100.0, "ms"), metavar="MS",
    default=SCAN_MARGIN_S * 1000, show_default=True,
    help="Wait this much longer for each ID, in ms, than its reply takes on the wire (servos "
         "slow to answer; a late reply is recognised anyway).",
)
@pass_settings
def scan(settings: Settings, ids: list[int], margin_ms: float) -> None:
    """Find the servos on the bus; show their position (deg), voltage (V), temperature (C).

    IDs answered by more than one servo (duplicate IDs) are reported in red. Exit code 1
    when no servo answers at all.
    """
    with settings.open_bus() as bus:
        result = scan_with_progress(bus, ids, settings.err, margin_s=margin_ms / 1000)
        scan_report(bus, result, settings.out, len(ids))
        port = bus.transport.name
    if not result.found and not result.conflicts:  # outside the bus: nothing to stop
        raise BusTimeoutError(
            f"no servo answered on {port} at {settings.baudrate} baud: check that the servos "
            "are powered (their own supply: USB does not power them), the baud rate (--baud; "
            "LX servos use 115200), the echo setting (--echo auto) and the port (--port; "
            "`busarm ports` lists them)"
        )


@click.command()
@click.option("--ids", "ids", type=ID_LIST,
              help="IDs to watch, e.g. 1-5,10  [default: those a scan finds]")
@click.option(
    "--interval", type=RangeType("interval", 0.0, 3600.0, "s"), metavar="S", default=0.5,
    show_default=True, help="Time between refreshes in s.",
)
@click.option("--count", type=click.IntRange(min=1), help="Stop after this many refreshes.")
@pass_settings
def monitor(
    settings: Settings, ids: list[int] | None, interval: float, count: int | None,
) -> None:
    """Live table of position (deg), temperature (C), voltage (V) and torque per servo.

    Refreshes until Ctrl+C (exit code 130) or --count refreshes (exit code 0). It only
    reads: it sends no stop, and the servos go on doing what they do (a move of
    another program goes on). When the output is not a terminal, every refresh is printed.
    """
    with settings.open_bus() as bus:
        if ids is None:
            ids = scan_with_progress(bus, range(MAX_SERVO_ID + 1), settings.err).found
            if not ids:
                settings.out.print("no servos found")
                return
        _monitor_loop(settings, bus, ids, interval, count)


def _monitor_loop(
    settings: Settings, bus: LxServoPort, ids: list[int], interval: float, count: int | None,
) -> None:
    out = settings.out

    def table(n: int) -> Table:
        return state_table(bus, ids, torque=True, title=f"{bus.transport.name}  refresh {n}")

    n = 1
    if not out.is_terminal:
        while True:
            out.print(table(n))
            if count is not None and n >= count:
                return
            n += 1
            bus.clock.sleep(interval)
    with Live(table(n), console=out, auto_refresh=False) as live:
        while count is None or n < count:
            bus.clock.sleep(interval)
            n += 1
            live.update(table(n), refresh=True)


COMMANDS = [ports, scan, monitor]
