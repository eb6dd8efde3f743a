"""The learning tasks on the twin: their seeded tables, their words, what the camera sees
of them before they begin, and their success, judged on the twin's truth.

``one-block``: one cube somewhere the arm reaches, three trays; put it in its colour's
tray. ``table``: three to five cubes; sort them all by colour. Scene ``seed`` is the
twin's ``random_scene`` with that seed; seeds from ``HELD_OUT_SEED`` on are kept for
evaluation (``busarm record`` refuses them), so a policy is judged on tables it never saw.
"""

from __future__ import annotations

import random
from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.bins import in_tray
from busarm.errors import ConfigError
from busarm.perception.locate import Sighting
from busarm.twin.scene import REACH_RADIUS_MM, Scene, random_scene
from busarm.twin.twin import BlockState, Twin

__all__ = [
    "COLORS",
    "HELD_OUT_SEED",
    "TASKS",
    "check_task",
    "is_done",
    "placed",
    "task_scene",
    "task_state",
    "task_text",
]

TASKS = ("one-block", "table")
COLORS = ("red", "green", "blue")
HELD_OUT_SEED = 1_000_000
"""Scene seeds from here on are for evaluation only."""
TABLE_BLOCKS = (3, 5)
LET_GO_MM = 4.0
"""The fingers this much wider apart than a block have let go of it."""
RESTING_MM = 5.0
"""A block's centre at most this far above where it would rest on the table (a tray's
floor is 2 mm up) counts as lying there."""


def check_task(task: str) -> str:
    """``task`` if it is one of ``TASKS``; ConfigError naming them otherwise."""
    if task not in TASKS:
        raise ConfigError(f"task = {task!r}; allowed: {', '.join(TASKS)}")
    return task


def task_scene(task: str, seed: int) -> Scene:
    """The seeded table of ``task``."""
    check_task(task)
    rng = random.Random(seed)
    if task == "one-block":  # random_scene gives one block its first colour: any of them
        scene = random_scene(seed, 1, COLORS, radius_mm=REACH_RADIUS_MM)
        return scene.with_blocks([replace(scene.blocks[0], color=rng.choice(COLORS))])
    blocks = rng.randint(*TABLE_BLOCKS)
    return random_scene(seed, blocks, COLORS, radius_mm=REACH_RADIUS_MM)


def task_text(task: str, color: str | None = None) -> str:
    """The task in words, as a dataset names it."""
    if task == "one-block":
        return f"put the {color} block in the {color} bin"
    return "sort the blocks into the bins of their colours"


def task_state(target: Sighting | None, bins: Mapping[str, tuple[float, float]]
               ) -> npt.NDArray[np.float32]:
    """``observation.environment_state`` (busarm.learn.features.TASK_STATE_NAMES): the
    block to move and its colour's bin; zeros when none was seen."""
    if target is None or target.color not in bins:
        return np.zeros(5, np.float32)
    loc = target.location
    bx, by = bins[target.color]
    return np.array([loc.x_mm, loc.y_mm, loc.yaw_deg % 90.0, bx, by],
                    np.float32)


def placed(truth: Sequence[BlockState], bins: Mapping[str, tuple[float, float]]
           ) -> list[bool]:
    """Whether each block lies in its colour's tray: its centre over the tray's inside,
    resting there (its centre within ``RESTING_MM`` of half its size above the table: on
    the tray's floor, not held above it). The twin's truth."""
    return [t.color in bins and in_tray(t.x_mm, t.y_mm, bins[t.color])
            and t.z_mm < t.size_mm / 2 + RESTING_MM for t in truth]


def is_done(twin: Twin, bins: Mapping[str, tuple[float, float]]) -> bool:
    """The task is done: every block lies in its colour's tray (``placed``) and the
    fingers have let go (open wider than the widest block by ``LET_GO_MM``). The twin's
    truth."""
    blocks = twin.blocks()
    widest = max((b.size_mm for b in blocks), default=0.0)
    return all(placed(blocks, bins)) and twin.finger_gap_mm() > widest + LET_GO_MM
