"""Recording a person's demonstrations: a leader arm, the keyboard or the dashboard's jog
drive the robot while every frame's observation and action are kept, episode by episode,
in a LeRobotDataset (busarm.learn.dataset).

``record_teleop(frames, source, writer, ...)``: each frame the robot is observed, then
``source()`` gives the action (a leader's joints, the keyboard's target), which is
clipped and sent (``FrameRobot.act``) and kept as sent; a source that gives None drives
nothing itself (the dashboard's jog moves the arm): the action kept is then where the
arm was last told to go (``FrameRobot.commanded``). The frames are paced on the robot's
clock: the wall clock on hardware and a real-time twin, simulated time on a twin in this
process (whose physics runs while the recorder waits).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.learn.dataset import DatasetWriter
from busarm.learn.frames import FrameRobot, next_frame
from busarm.progress import Progress, quiet
from busarm.units import check_int_range, check_range

__all__ = [
    "ActionSource",
    "TeleopEpisode",
    "record_episode",
    "record_teleop",
]

ActionSource = Callable[[], "dict[str, float] | None"]
"""What drives the robot each frame: an action, or None (something else drives it)."""


@dataclass
class TeleopEpisode:
    """One recorded episode's frames (state order), RGB pictures by camera, and how late
    the frames were (s past their time on the robot's clock, the worst)."""

    states: npt.NDArray[np.float32]
    actions: npt.NDArray[np.float32]
    images: dict[str, list[npt.NDArray[np.uint8]]]
    worst_late_s: float


def record_episode(frames: FrameRobot, source: ActionSource, *, episode_s: float
                   ) -> TeleopEpisode:
    """One episode of ``episode_s`` at the robot's rate (``frames.limits.frame_s``)."""
    check_range("episode_s", episode_s, 0.1, 3600.0, "s")
    robot = frames.open()
    clock, period = robot.clock, frames.limits.frame_s
    states, actions = [], []
    images: dict[str, list[npt.NDArray[np.uint8]]] = {c: [] for c in frames.cameras}
    worst = 0.0
    t_next = clock.now()
    for _ in range(max(1, round(episode_s / period))):
        seen = frames.observe()
        asked = source()
        sent = frames.act(asked) if asked is not None else frames.commanded()
        states.append([seen[m] for m in frames.motors])
        actions.append([sent[m] for m in frames.motors])
        for role in frames.cameras:
            images[role].append(seen[role])
        worst = max(worst, clock.now() - (t_next + period))
        t_next = next_frame(t_next, period, clock)
    return TeleopEpisode(np.asarray(states, np.float32), np.asarray(actions, np.float32),
                         images, worst)


def record_teleop(frames: FrameRobot, source: ActionSource, writer: DatasetWriter, *,
                  episodes: int, episode_s: float, text: str,
                  between: Callable[[int], None] | None = None,
                  progress: Progress = quiet) -> list[TeleopEpisode]:
    """``episodes`` episodes of ``episode_s`` each, written to ``writer`` as the task
    ``text``; ``between(k)`` runs before episode ``k`` (k >= 1: a reset, a pause)."""
    check_int_range("episodes", episodes, 1, 10_000)
    out = []
    for k in range(episodes):
        if k and between is not None:
            between(k)
        progress(f"episode {k + 1}/{episodes}: recording {episode_s:g} s")
        e = record_episode(frames, source, episode_s=episode_s)
        writer.add(text, e.states, e.actions, images=e.images)
        out.append(e)
        progress(f"episode {k + 1}/{episodes}: {len(e.states)} frames kept (at most "
                 f"{1000 * e.worst_late_s:.0f} ms late)")
    return out
