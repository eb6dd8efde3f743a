"""One job on each of many seeded twins, side by side: the benches' and the recorders'
worker pool, with the twin's camera calibrated once first."""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TypeVar

from busarm.progress import Progress
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.twin.spec import TwinSpec

__all__ = ["run_seeded"]

R = TypeVar("R")


def run_seeded(task: Callable[[int, Path, Path], R], seeds: Sequence[int], workers: int,
               progress: Progress, describe: Callable[[int, int, R], str],
               on_done: Callable[[R], None] | None = None) -> list[R]:
    """``task(seed, intrinsics, hand_eye)`` for every seed, in seed order, on ``workers``
    processes (1: this one), the twin's camera calibrated once first by our own flows;
    as each one ends, ``on_done(result)`` runs here and ``describe(done, total, result)``
    is said."""
    from busarm.robot.robot import Robot

    def done_one(result: R, count: int) -> None:
        if on_done is not None:
            on_done(result)
        progress(describe(count, len(seeds), result))

    with tempfile.TemporaryDirectory() as tmp:
        with Robot.open(RobotConfig(TwinSpec(blocks=0), camera=CameraSpec(folder=Path(tmp))),
                        progress=progress) as robot:
            robot.require_camera_calibration()
        intrinsics, hand_eye = Path(tmp) / "camera.json", Path(tmp) / "hand_eye.json"
        if workers == 1:
            out = []
            for seed in seeds:
                out.append(task(seed, intrinsics, hand_eye))
                done_one(out[-1], len(out))
            return out
        # Spawned, not forked: each worker starts its own OpenGL context for the cameras.
        context = multiprocessing.get_context("spawn")
        done: dict[int, R] = {}
        with concurrent.futures.ProcessPoolExecutor(workers, mp_context=context) as pool:
            futures = {pool.submit(task, seed, intrinsics, hand_eye): seed for seed in seeds}
            for future in concurrent.futures.as_completed(futures):
                done[futures[future]] = future.result()
                done_one(done[futures[future]], len(done))
        return [done[seed] for seed in seeds]
