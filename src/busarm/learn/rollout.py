"""``busarm rollout``: a trained policy drives a robot, one frame at a time at the rate it
was trained at, every action clipped to the limits (busarm.learn.frames); on a twin its
success is judged on the twin's truth.

The robot is looked at first, as a recorded episode begins (the arm at its look pose,
the block found: ``observation.environment_state``); then the policy acts until the task
is done (on a twin: every block in its bin), ``seconds`` are up, or the robot is stopped
(a dashboard's Stop or e-stop halts the bus: the next action is refused, HaltedError,
and the rollout ends there, the robot left stopped).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from busarm.apps.pick_sort.sorter import PickSorter
from busarm.errors import HaltedError
from busarm.learn.expert import first_look
from busarm.learn.frames import FrameRobot, next_frame
from busarm.learn.policy import LoadedPolicy
from busarm.learn.tasks import is_done, task_state
from busarm.progress import Progress, quiet
from busarm.units import check_range

__all__ = [
    "RolloutReport",
    "rollout",
]


@dataclass
class RolloutReport:
    """What a rollout did: frames acted, seconds of the robot's time, values clipped, how
    it ended, and on a twin whether every block lies in its bin (the twin's truth)."""

    policy: str
    frames: int = 0
    seconds: float = 0.0
    clipped: int = 0
    ended: str = ""
    success: bool | None = None
    """The twin's truth at the end; None on hardware (no truth to judge by)."""
    wall_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def text(self) -> str:
        verdict = ("" if self.success is None else
                   " - every block in its bin (the twin's truth)" if self.success else
                   " - not done: a block is not in its bin (the twin's truth)")
        return (f"{self.policy}: {self.frames} frames in {self.seconds:.1f} s, "
                f"{self.clipped} values clipped to the limits, {self.ended}{verdict}")


def rollout(frames: FrameRobot, policy: LoadedPolicy, *, seconds: float = 15.0,
            progress: Progress = quiet) -> RolloutReport:
    """Look, then let ``policy`` act on ``frames``' robot (opened here if it is not)."""
    check_range("seconds", seconds, 0.1, 3600.0, "s")
    policy.check_motors(frames.motors)
    robot = frames.open()
    twin = robot.twin
    report = RolloutReport(f"{policy.type} policy from {policy.path}")
    wall = time.monotonic()
    sorter = PickSorter(robot)
    target = first_look(robot, sorter)
    progress("looked: " + ("nothing to pick" if target is None else
                           f"{target.color} block at ({target.location.x_mm:.0f}, "
                           f"{target.location.y_mm:.0f}) mm"))
    env_state = task_state(target, sorter.bins).astype(np.float64)
    policy.reset()
    start = t_next = robot.clock.now()
    clipped0 = frames.clipped
    report.ended = f"{seconds:g} s were up"
    try:
        while robot.clock.now() - start < seconds:
            seen = frames.observe()
            obs: dict[str, Any] = {"agent_pos": np.array([seen[m] for m in frames.motors]),
                                   "environment_state": env_state}
            if frames.cameras:
                obs["pixels"] = {role: seen[role] for role in frames.cameras}
            action = policy.act(obs)
            frames.act(dict(zip(frames.motors, action.tolist(), strict=True)))
            report.frames += 1
            if twin is not None and is_done(twin, robot.bins):
                report.ended = "done"
                break
            t_next = next_frame(t_next, frames.limits.frame_s, robot.clock)
    except HaltedError as exc:
        report.ended = f"stopped: {exc}"
    report.seconds = robot.clock.now() - start
    report.clipped = frames.clipped - clipped0
    if twin is not None:
        report.success = is_done(twin, robot.bins)
    report.wall_s = time.monotonic() - wall
    return report
