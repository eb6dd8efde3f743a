"""``busarm bench teleop``: a leader arm on a second simulated bus driving the twin in real
time (busarm.bench.teleop); added to the ``bench`` group by ``busarm.cli.main``."""

from __future__ import annotations

import click

from busarm.cli.bench_report import judged, said, verdict
from busarm.cli.common import RangeType, Settings, pass_settings

__all__ = ["bench_teleop"]


@click.command("teleop")
@click.option("--seconds", type=RangeType("--seconds", 1.0, 600.0, "s"), default=10.0,
              show_default=True, help="How long the leader drives the twin, in s.")
@click.option("--fps", type=RangeType("--fps", 1.0, 100.0, "frames/s"), default=50.0,
              show_default=True, help="The loop's pace, in frames/s.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@pass_settings
def bench_teleop(settings: Settings, seconds: float, fps: float, as_json: bool) -> None:
    """A leader arm (simulated servos behind a pseudo-terminal, turned by a hand along
    sines) drives the real-time twin's arm one frame at a time: the rate kept (target
    >= 30 Hz), each frame's time, and against the twin's truth how far behind the hand
    the follower is and by how much it misses it then. Wall time: run it on a quiet
    computer."""
    from busarm.bench.teleop import run_teleop_bench

    report = run_teleop_bench(seconds=seconds, fps=round(fps), progress=said(settings))
    judged(settings, as_json, report.to_dict(), lambda shown: shown.out.print(
        f"[bold]busarm bench teleop[/]: {report.text(verdict)}", highlight=False))
