"""Live servo readings for the command line: rich tables of a servo's state, the scan's
progress bar and report, and what a reading that did not come says (re-exported by
busarm.cli.common)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import TypeVar

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from busarm.bus.id_scan import ScanResult
from busarm.bus.lx_port import LxServoPort
from busarm.errors import BusTimeoutError, ProtocolError
from busarm.protocol import AlarmFlag

__all__ = [
    "BAD_REPLY",
    "NOT_HERE",
    "NO_REPLY",
    "alarm_names",
    "fmt",
    "scan_progress",
    "scan_report",
    "scan_with_progress",
    "state_row",
    "state_table",
    "try_read",
]


T = TypeVar("T")

NO_REPLY = "no reply"
BAD_REPLY = "bad reply"
NOT_HERE = "n/a (the controller board cannot read it)"


def try_read(read: Callable[[], T]) -> T | str:
    """``read()``, or ``"no reply"`` if the servo did not answer (or ``"bad reply"``)."""
    try:
        return read()
    except BusTimeoutError:
        return NO_REPLY
    except ProtocolError:
        return BAD_REPLY


def fmt(value: object, spec: str = "", unit: str = "") -> str:
    """``value`` formatted with ``spec`` and ``unit``; strings ("no reply") as they are."""
    if isinstance(value, str):
        return value
    text = format(value, spec)
    return f"{text} {unit}" if unit else text


def state_row(bus: LxServoPort, sid: int, *, torque: bool = False) -> list[str]:
    """ID, position, temperature and voltage of one servo (and torque); "no reply" per field."""
    row = [
        str(sid),
        fmt(try_read(lambda: bus.read_position_deg(sid)), "+.1f"),
        fmt(try_read(lambda: bus.read_temp_c(sid)), "d"),
        fmt(try_read(lambda: bus.read_vin_v(sid)), ".2f"),
    ]
    if torque:
        loaded = try_read(lambda: bus.read_torque(sid))
        row.append(loaded if isinstance(loaded, str) else ("on" if loaded else "off"))
    return row


def state_table(
    bus: LxServoPort, ids: Iterable[int], *, title: str | None = None, torque: bool = False,
    targets: dict[int, float] | None = None,
) -> Table:
    """A table of live readings, one row per servo (optionally with each target)."""
    table = Table(title=title, title_justify="left")
    table.add_column("ID", justify="right")
    if targets is not None:
        table.add_column("target (deg)", justify="right")
    table.add_column("position (deg)", justify="right")
    table.add_column("temp (C)", justify="right")
    table.add_column("voltage (V)", justify="right")
    if torque:
        table.add_column("torque", justify="center")
    for sid in ids:
        row = state_row(bus, sid, torque=torque)
        if targets is not None:
            row.insert(1, f"{targets[sid]:+.1f}" if sid in targets else "")
        style = "red" if NO_REPLY in row else None
        table.add_row(*row, style=style)
    return table


def scan_with_progress(bus: LxServoPort, ids: Sequence[int], console: Console, *,
                       margin_s: float | None = None) -> ScanResult:
    """``bus.scan(ids)`` behind a progress bar (shown on ``console``, then removed);
    ``margin_s``: each ID's wait past its reply's wire time (the bus's default if None)."""
    with scan_progress(console, len(ids)) as advance:
        if margin_s is None:
            return bus.scan(ids, progress=lambda _sid: advance())
        return bus.scan(ids, margin_s=margin_s, progress=lambda _sid: advance())


@contextmanager
def scan_progress(console: Console, total: int) -> Iterator[Callable[[], None]]:
    """A transient progress bar for a scan of ``total`` IDs; yields its advance()."""
    progress = Progress(
        TextColumn("scanning IDs"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    )
    with progress:
        task: TaskID = progress.add_task("scan", total=total)
        yield lambda: progress.advance(task, 1)


def scan_report(bus: LxServoPort, result: ScanResult, console: Console, asked: int) -> None:
    """Print the servos a scan found (with readings) and any conflicts, in red."""
    console.print(
        f"scanned {asked} ID(s) in {result.duration_s:.2f} s: "
        f"found {len(result.found)} servo(s)"
        + (f": {', '.join(map(str, result.found))}" if result.found else "")
    )
    healthy = [sid for sid in result.found if sid not in result.conflicts]
    if healthy:
        console.print(state_table(bus, healthy))
    for sid in result.conflicts:
        console.print(
            f"[red]conflict: more than one servo answers at ID {sid} (duplicate IDs); "
            "disconnect all but one and renumber with set-id[/red]"
        )


def alarm_names(mask: AlarmFlag) -> str:
    """``over-temperature, stalled`` style names of an alarm mask (``none`` if empty)."""
    names = [f.name.lower().replace("_", "-") for f in AlarmFlag if f and f in mask and f.name]
    return ", ".join(names) or "none"
