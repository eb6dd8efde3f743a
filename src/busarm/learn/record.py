"""``busarm record --expert pick-sort``: expert episodes on seeded twin tables, many side
by side, written as one LeRobotDataset; how many, how fast, how many kept.

Episode ``i`` is table ``seed + i`` of the task (busarm.learn.tasks); the expert's
success is the twin's truth at its end. Failed episodes are kept out, or with
``keep_failed`` kept and marked (``next.success`` never set in them).
"""

from __future__ import annotations

import functools
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError
from busarm.learn.dataset import DatasetWriter
from busarm.learn.expert import Episode, EpisodeTask, run_expert
from busarm.learn.features import DEFAULT_FPS, Features
from busarm.learn.tasks import HELD_OUT_SEED, check_task
from busarm.progress import Progress, quiet
from busarm.robot.seeded_runs import run_seeded
from busarm.twin.spec import TwinSpec
from busarm.units import check_int_range

__all__ = [
    "MAX_WORKERS",
    "RecordReport",
    "expert_episode",
    "record_expert",
]

MAX_WORKERS = 64


@dataclass
class RecordReport:
    """What a recording made: episodes run, kept and successful (the twin's truth),
    frames written, and the wall time it took here."""

    task: str
    root: str
    episodes: int = 0
    successes: int = 0
    kept: int = 0
    frames: int = 0
    seconds: float = 0.0
    sim_seconds: float = 0.0
    workers: int = 1
    failures: list[dict[str, Any]] = field(default_factory=list)

    @property
    def success_rate(self) -> float:
        return self.successes / self.episodes if self.episodes else 0.0

    @property
    def episodes_per_hour(self) -> float:
        return 3600.0 * self.episodes / self.seconds if self.seconds > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "success_rate": round(self.success_rate, 4),
                "episodes_per_hour": round(self.episodes_per_hour)}

    def text(self) -> str:
        return (f"{self.episodes} {self.task} episodes in {self.seconds:.0f} s on "
                f"{self.workers} worker(s): {self.episodes_per_hour:.0f} episodes an hour; "
                f"the expert succeeded in {self.successes}/{self.episodes} "
                f"({100 * self.success_rate:.1f}%, the twin's truth); {self.kept} kept "
                f"({self.frames} frames) in {self.root}")


def expert_episode(task: str, fps: int, seed: int, intrinsics: Path, hand_eye: Path
                   ) -> Episode:
    """One expert episode (a worker's job: ``run_seeded``'s task)."""
    return run_expert(EpisodeTask(seed, task, seed, fps, intrinsics, hand_eye))


def record_expert(root: Path, *, task: str = "one-block", episodes: int = 10, seed: int = 0,
                  fps: int = DEFAULT_FPS, workers: int = 1, keep_failed: bool = False,
                  progress: Progress = quiet) -> RecordReport:
    """Record ``episodes`` expert episodes of ``task`` on tables ``seed``.. into a new
    LeRobotDataset at ``root``."""
    check_task(task)
    check_int_range("episodes", episodes, 1, 100_000)
    check_int_range("workers", workers, 1, MAX_WORKERS)
    check_int_range("fps", fps, 1, 100)
    if not 0 <= seed <= HELD_OUT_SEED - episodes:
        raise ConfigError(f"seed = {seed}: the tables {seed}..{seed + episodes - 1} must lie "
                          f"in 0..{HELD_OUT_SEED - 1} (from {HELD_OUT_SEED} on they are kept "
                          "for evaluation)")
    report = RecordReport(task, str(root), workers=workers)
    start = time.monotonic()
    config = TwinSpec().arm_config()  # the arm of the twin's tables
    with DatasetWriter(root, Features.of(config, fps=fps)) as writer:
        def keep(e: Episode) -> None:
            report.episodes += 1
            report.successes += e.success
            report.sim_seconds += e.sim_s
            if not e.success and len(report.failures) < 20:
                report.failures.append({"seed": e.spec.seed, "why": e.why})
            if e.frames and (e.success or keep_failed):
                writer.add(e.text, e.states, e.actions, task_state=e.task_state,
                           success=e.success)
                report.kept += 1
                report.frames += e.frames

        def describe(done: int, total: int, e: Episode) -> str:
            verdict = "done" if e.success else f"failed ({e.why})"
            return (f"episode {done}/{total} (table {e.spec.seed}): {verdict}, {e.frames} "
                    f"frames, {e.sim_s:.1f} s of twin time in {e.wall_s:.1f} s")

        run_seeded(functools.partial(expert_episode, task, fps),
                   [seed + i for i in range(episodes)], workers, progress, describe, keep)
    report.seconds = time.monotonic() - start
    if report.kept == 0:  # the writer left nothing behind
        raise ConfigError(f"no episode was kept ({report.episodes} run, none succeeded): "
                          f"{report.failures[:1]}")
    return report
