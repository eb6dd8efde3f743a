"""``busarm bench``: bus throughput and latency beside the wire limit."""

from __future__ import annotations

import json

import click
from rich.table import Table

from busarm.bench import BenchReport, run_bench, sim_pty_server
from busarm.cli.common import IdListType, RangeType, Settings, pass_settings

TARGET_RATIO = 0.90
TARGET_SCAN_S = 1.0
TARGET_CPU_US = 30.0


@click.command()
@click.option("--ids", "servo_ids", type=IdListType(), default="1,2,3,4,5,10", show_default=True,
              help="Servos on the bus; the first is used for the position-read run.")
@click.option("--reads", type=click.IntRange(10, 1_000_000), default=3000, show_default=True,
              help="Position reads to time.")
@click.option("--loops", type=click.IntRange(1, 100_000), default=200, show_default=True,
              help="Full state loops (position, temperature, voltage of every servo).")
@click.option("--scans", type=click.IntRange(1, 100), default=3, show_default=True,
              help="Full ID scans 0..253.")
@click.option("--turnaround-ms", type=RangeType("turnaround", 0.0, 100.0, "ms"), default=0.5,
              show_default=True,
              help="Servo reply delay in ms, used for the wire limit (and by the simulator).")
@click.option("--sim-echo", is_flag=True,
              help="With --port sim: the simulated adapter echoes what is sent (one-wire style).")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def bench(
    settings: Settings, servo_ids: list[int], reads: int, loops: int, scans: int,
    turnaround_ms: float, sim_echo: bool, as_json: bool,
) -> None:
    """Measure position reads, a full-arm state loop and an ID scan against the wire limit.

    With the default port `sim`, the simulated arm runs in its own process on a
    pseudo-terminal with 115200-baud wire timing, so the numbers include the real
    serial path. On hardware (`--port /dev/ttyUSB0`) this is the first diagnostic to
    run: a rate far below the wire limit points at adapter latency or a noisy bus.
    """
    kwargs = dict(servo_ids=servo_ids, reads=reads, loops=loops, scans=scans,
                  turnaround_ms=turnaround_ms, echo=settings.echo)
    if settings.port == "sim":
        ids = ",".join(map(str, servo_ids))
        with sim_pty_server(turnaround_ms, ids, echo=sim_echo) as path:
            report = run_bench(path, **kwargs)  # type: ignore[arg-type]
        report.port = f"sim (own process, pty {path})"
    else:
        report = run_bench(settings.port, **kwargs)  # type: ignore[arg-type]
    if as_json:
        click.echo(json.dumps(report.to_dict(), indent=2))
    else:
        _print(settings, report)


def _print(settings: Settings, report: BenchReport) -> None:
    m = report.machine
    settings.out.print(
        f"[bold]busarm bench[/] on {report.port}: {report.baudrate} baud, turnaround "
        f"{report.turnaround_ms} ms, echo {'on' if report.echo else 'off'}\n"
        f"machine: {m['cpu']}, {m['cores']} cores, Python {m['python']}, {m['os']}"
    )
    table = Table()
    for col in ("measurement", "rate", "wire limit", "of limit", "p50 ms", "p99 ms",
                "client CPU", "errors"):
        table.add_column(col, justify="left" if col == "measurement" else "right")
    for r in report.results:
        ok = r.ratio >= TARGET_RATIO
        table.add_row(
            r.name,
            f"{r.rate:,.1f} {r.unit}",
            f"{r.wire_limit:,.1f}",
            f"[{'green' if ok else 'yellow'}]{r.ratio:.1%}[/]",
            f"{r.latency_ms['p50']:.3f}",
            f"{r.latency_ms['p99']:.3f}",
            "" if r.cpu_us_median is None else f"{r.cpu_us_median:.1f} us",
            str(r.errors),
        )
    settings.out.print(table)
    scan = report.results[-1]  # bench_scan is always last
    settings.out.print(
        f"scan: best {scan.extra['best_s']} s, median {scan.extra['median_s']} s "
        f"(target <= {TARGET_SCAN_S} s), found {scan.extra['found']}"
    )
