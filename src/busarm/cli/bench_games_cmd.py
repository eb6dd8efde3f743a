"""``busarm bench track`` and ``busarm bench stack``: the arm games on the twin, against
its truth (busarm.bench.track, busarm.bench.stack); added to the ``bench`` group by
``busarm.cli.main``."""

from __future__ import annotations

import click

from busarm.cli.bench_report import judged, said, seeded_world_options, verdict
from busarm.cli.common import Settings

__all__ = [
    "bench_stack",
    "bench_track",
]


@click.command("track")
@seeded_world_options("runs", 9, "Seeded runs (run i uses seed + i): the block slid along "
                       "a circle, a figure-eight and a walk by turns, at 20, 35 and 50 mm/s.")
def bench_track(settings: Settings, runs: int, seed: int, workers: int, as_json: bool) -> None:
    """Colour tracking on the twin, against its truth: a red block slid about at up to
    50 mm/s, each frame's true pixel error from the image centre. A few seconds a run."""
    from busarm.bench.track import run_track_bench

    report = run_track_bench(runs=runs, seed=seed, workers=workers, progress=said(settings))
    judged(settings, as_json, report.to_dict(), lambda shown: shown.out.print(
        f"[bold]busarm bench track[/]: {report.text(verdict)}", highlight=False))


@click.command("stack")
@seeded_world_options("scenes", 20, "Seeded tables of 3-5 tagged blocks (scene i uses "
                       "seed + i: busarm.twin.lookalike.tagged_scene).")
def bench_stack(settings: Settings, scenes: int, seed: int, workers: int,
                as_json: bool) -> None:
    """Tag stacking on the twin, against its truth: every tagged block stacked in id order,
    each on the one below (within 8 mm); the placement error from the block below. A few
    seconds a scene."""
    from busarm.bench.stack import run_stack_bench

    report = run_stack_bench(scenes=scenes, seed=seed, workers=workers,
                             progress=said(settings))
    judged(settings, as_json, report.to_dict(), lambda shown: shown.out.print(
        f"[bold]busarm bench stack[/]: {report.text(verdict)}", highlight=False))
