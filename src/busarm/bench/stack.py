"""``busarm bench stack``: tag stacking over seeded tables of tagged blocks, scored against
the twin's truth.

Scene ``i`` is ``tagged_scene(seed + i)`` (3-5 tagged cubes of 25-35 mm) on a twin of its
own; ``busarm stack``'s job stacks every tag it sees at the place it chooses. Only this
module reads the truth (``Twin.blocks()``) at the end: the tower is complete and in order
when every block stands upright, its centre at the table plus the sides below it and half
its own (within ``Z_TOLERANCE_MM``), its centre within ``MAX_OFF_MM`` of the one below in
x and y. The placement error is that xy distance from the block below (the truth's).
The target: ``TARGET_COMPLETE`` of the scenes' towers complete and in order.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from busarm.apps.stack.job import StackJob
from busarm.bench.common import (
    Progress,
    SeededBenchReport,
    Verdict,
    machine_info,
    quiet,
    run_seeded_bench,
)
from busarm.robot import Robot
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.twin.lookalike import tagged_scene
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import BlockState

__all__ = [
    "MAX_OFF_MM",
    "MAX_WORKERS",
    "TARGET_COMPLETE",
    "Z_TOLERANCE_MM",
    "StackBenchReport",
    "StackRun",
    "run_stack",
    "run_stack_bench",
    "score_tower",
]


TARGET_COMPLETE = 0.95
MAX_OFF_MM = 8.0
"""A block's centre further than this from the one below's (x, y) is not on it."""
Z_TOLERANCE_MM = 3.0
MAX_WORKERS = 8


@dataclass
class StackRun:
    """One scene: its tags, the job's end and the truth's verdict."""

    seed: int
    ids: list[int] = field(default_factory=list)
    size_mm: float = 0.0
    end: str = ""
    why: str = ""
    complete: bool = False
    """The truth: every tag in the tower, in order, each on the one below."""
    errors_mm: list[float] = field(default_factory=list)
    """The truth: each block's xy distance from the one below (from the second up)."""
    looked_errors_mm: list[float] = field(default_factory=list)
    """What the job looked at: each block's distance from the tower's axis."""
    height_mm: float = 0.0
    seconds: float = 0.0
    wall_s: float = 0.0


def score_tower(truth: list[BlockState], tag_ids: list[int | None], table_z_mm: float
                ) -> tuple[bool, list[float]]:
    """Whether the blocks stand one on the other in tag-id order (see the module
    docstring), and each one's xy distance from the one below."""
    order = sorted((i for i, t in enumerate(tag_ids) if t is not None),
                   key=lambda i: tag_ids[i] or 0)
    blocks = {b.index: b for b in truth}
    ok, errors, base = True, [], table_z_mm
    for k, index in enumerate(order):
        b = blocks[index]
        ok = ok and b.is_upright and abs(b.z_mm - (base + b.size_mm / 2)) <= Z_TOLERANCE_MM
        if k:
            below = blocks[order[k - 1]]
            errors.append(math.hypot(b.x_mm - below.x_mm, b.y_mm - below.y_mm))
            ok = ok and errors[-1] <= MAX_OFF_MM
        base += b.size_mm
    return ok, errors


def run_stack(seed: int, intrinsics: Path, hand_eye: Path) -> StackRun:
    """One seeded table on a twin of its own (this process)."""
    wall = time.monotonic()
    scene = tagged_scene(seed)
    out = StackRun(seed, sorted(b.tag_id for b in scene.blocks if b.tag_id is not None),
                   scene.blocks[0].size_mm)
    with Robot.open(RobotConfig(TwinSpec(scene=scene), camera=CameraSpec(
            intrinsics=intrinsics, hand_eye=hand_eye))) as robot:
        assert robot.sim is not None
        try:
            report = StackJob(robot).run()
            out.end, out.why = report.end, report.why
            out.looked_errors_mm = [b.error_mm for b in report.tower]
            out.height_mm, out.seconds = report.height_mm, report.seconds
        except Exception as exc:  # a bench goes on to the next scene, saying why
            out.end, out.why = "stopped", f"{type(exc).__name__}: {exc}"
        out.complete, out.errors_mm = score_tower(
            robot.sim.blocks(), [b.tag_id for b in scene.blocks], robot.config.table_z_mm)
    out.wall_s = time.monotonic() - wall
    return out


@dataclass
class StackBenchReport(SeededBenchReport[StackRun]):
    def summary(self) -> dict[str, Any]:
        errors = [e for r in self.runs if r.complete for e in r.errors_mm]  # towers only
        complete = sum(r.complete for r in self.runs)
        return {"scenes": len(self.runs), "complete": complete,
                "complete_fraction": round(complete / len(self.runs), 4) if self.runs else 0.0,
                "blocks": sum(len(r.ids) for r in self.runs),
                "mean_error_mm": round(sum(errors) / len(errors), 2) if errors else None,
                "max_error_mm": round(max(errors), 2) if errors else None,
                "twin_seconds_per_scene": round(
                    sum(r.seconds for r in self.runs) / len(self.runs), 1) if self.runs else None}

    def text(self, verdict: Verdict) -> str:
        rows = [f"{'seed':>4} {'tags':14} {'size':>5} {'height':>6} {'truth':8} "
                f"{'mean err':>8} {'max err':>7} {'twin s':>6} {'here s':>6}  end"]
        for r in self.runs:
            mean = f"{sum(r.errors_mm) / len(r.errors_mm):8.1f}" if r.errors_mm else f"{'-':>8}"
            worst = f"{max(r.errors_mm):7.1f}" if r.errors_mm else f"{'-':>7}"
            rows.append(f"{r.seed:4d} {','.join(map(str, r.ids)):14} {r.size_mm:5.1f} "
                        f"{r.height_mm:6.1f} {'complete' if r.complete else 'NOT':8} {mean} "
                        f"{worst} {r.seconds:6.1f} {r.wall_s:6.1f}  {r.end}"
                        + (f": {r.why}" if r.end != "complete" else ""))
        s = self.summary()
        return "\n".join([
            f"{s['scenes']} seeded tables of tagged blocks, scored with the twin's truth "
            f"(each block on the one below: its centre within {MAX_OFF_MM:g} mm in x and y, "
            f"at the sides below it within {Z_TOLERANCE_MM:g} mm)", *rows,
            f"towers complete and in order: {s['complete']}/{s['scenes']} "
            f"({s['complete_fraction'] * 100:.0f}%) "
            f"{verdict(s['complete_fraction'] >= TARGET_COMPLETE)} "
            f"(target >= {TARGET_COMPLETE * 100:g}%); placement error from the block below "
            f"(truth, complete towers): mean {s['mean_error_mm']} mm, max {s['max_error_mm']} mm; "
            f"{s['twin_seconds_per_scene']} s of twin time a scene; {self.time_text}"])


def _run_line(done: int, total: int, r: StackRun) -> str:
    return (f"scene {done}/{total} (seed {r.seed}, tags {','.join(map(str, r.ids))}): "
            f"{'complete' if r.complete else 'NOT complete'} ({r.end}); {r.wall_s:.0f} s here")


def run_stack_bench(*, scenes: int = 20, seed: int = 0, workers: int = 1,
                    progress: Progress = quiet) -> StackBenchReport:
    """Stacking over ``scenes`` seeded tables (seeds ``seed``..; see the module docstring)."""
    return run_seeded_bench(StackBenchReport(machine_info(), workers=workers), run_stack,
                            _run_line, what="scenes", count=scenes, seed=seed,
                            max_workers=MAX_WORKERS, progress=progress)
