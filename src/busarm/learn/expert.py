"""One demonstration by busarm's own expert (pick-and-sort's planner) on a seeded twin
table, sampled at a fixed rate (busarm.learn.tap) and judged on the twin's truth.

An episode begins where a policy's would (busarm.learn.env): the arm at its look pose,
the table just seen (``observation.environment_state`` from that look). Then the expert
works (``one-block``: its grasp, carry and release of that block; ``table``: its whole
run) while the tap samples state and action, and ends with the arm still for
``SETTLE_S``. Success is the twin's truth at the end: every block in its colour's tray.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.sorter import PickSorter
from busarm.errors import BusArmError
from busarm.learn.tap import ServoTap
from busarm.learn.tasks import is_done, task_scene, task_state, task_text
from busarm.perception.locate import Sighting
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.spec import TwinSpec

__all__ = [
    "SETTLE_S",
    "Episode",
    "EpisodeTask",
    "first_look",
    "robot_for",
    "run_expert",
]

SETTLE_S = 0.5
"""The still frames an episode ends with (the arm done, the block let go)."""


@dataclass(frozen=True)
class EpisodeTask:
    """One episode to record (sent to a worker process)."""

    index: int
    task: str
    seed: int
    fps: int
    intrinsics: Path
    hand_eye: Path


@dataclass
class Episode:
    """What one episode gave: its frames, its words, and its truth."""

    spec: EpisodeTask
    text: str
    states: npt.NDArray[np.float32] = field(repr=False)
    actions: npt.NDArray[np.float32] = field(repr=False)
    task_state: npt.NDArray[np.float32] = field(repr=False)
    success: bool
    why: str
    sim_s: float
    wall_s: float

    @property
    def frames(self) -> int:
        return len(self.states)


def first_look(robot: Robot, sorter: PickSorter) -> Sighting | None:
    """The block the expert would take first, from one survey at the look pose (the
    nearest reachable one with a bin); None if none is seen."""
    seen = [s for s in sorter.survey() if s.reachable and s.color in sorter.bins]
    if not seen:
        return None
    return min(seen, key=lambda s: s.location.x_mm ** 2 + s.location.y_mm ** 2)


def robot_for(task: str, seed: int, intrinsics: Path, hand_eye: Path) -> Robot:
    """The twin robot on ``task``'s table ``seed``, with the camera calibration given."""
    return Robot.open(RobotConfig(TwinSpec(scene=task_scene(task, seed)),
                                  camera=CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye)))


def run_expert(spec: EpisodeTask) -> Episode:
    """Record one expert episode of ``spec`` on a twin of its own (in this process)."""
    wall = time.monotonic()
    with robot_for(spec.task, spec.seed, spec.intrinsics, spec.hand_eye) as robot:
        twin = robot.twin
        assert twin is not None
        sorter = PickSorter(robot)
        target = first_look(robot, sorter)
        state = task_state(target, sorter.bins)
        text = task_text(spec.task, target.color if target is not None
                         else twin.blocks()[0].color)
        why = "" if target is not None else "no block seen"
        with ServoTap(twin, robot.arm, spec.fps) as tap:
            if target is not None:
                try:
                    _work(sorter, spec.task, target)
                except BusArmError as exc:  # a failed episode is a result too
                    why = f"{type(exc).__name__}: {exc}"
                robot.clock.sleep(SETTLE_S)
        ok = is_done(twin, robot.bins)
        if not ok and not why:
            why = "a block is not in its bin (the twin's truth)"
        return Episode(spec, text, tap.states, tap.actions, state, ok and not why, why,
                       twin.sim_time_s, time.monotonic() - wall)


def _work(sorter: PickSorter, task: str, target: Sighting) -> None:
    if task == "one-block":
        sorter.pick_and_place(target)
    else:
        sorter.run()
