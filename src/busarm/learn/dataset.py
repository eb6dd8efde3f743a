"""Writing episodes as a LeRobotDataset (v3: parquet, ``meta/info.json``, videos), through
LeRobot's own dataset API, so that LeRobot loads what busarm wrote as its own.

LeRobot is not part of busarm's install (docs/lerobot.md: its own virtual environment,
``make lerobot``); ``DatasetWriter`` says how to get it when it is missing.
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.learn.features import Features

__all__ = [
    "LEROBOT_MISSING",
    "DatasetWriter",
    "lerobot_dataset_class",
]

LEROBOT_MISSING = ("LeRobot is not installed here: `make lerobot` makes .venv-lerobot with "
                   "it (docs/lerobot.md); run busarm from there (.venv-lerobot/bin/busarm)")


def lerobot_dataset_class() -> Any:
    """LeRobot's ``LeRobotDataset``; ConfigError saying how to install it if missing."""
    try:
        import datasets
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
    except ImportError as exc:
        raise ConfigError(f"{LEROBOT_MISSING} ({exc})") from None
    datasets.disable_progress_bars()  # a bar per episode's table: ours says how far it got
    return LeRobotDataset


class DatasetWriter:
    """A new dataset at ``root`` (which must not exist): ``add`` an episode's frames,
    ``close`` to finish its files (``with`` does). It is written in ``ROOT.part`` and
    takes its name when finished; closed with no episode in it, it leaves nothing."""

    def __init__(self, root: Path, features: Features, *, repo_id: str = "local/busarm",
                 robot_type: str = "busarm") -> None:
        self.root, self.part = root, root.with_name(root.name + ".part")
        for path in (root, self.part):
            if path.exists():
                raise ConfigError(f"{path} exists: a dataset is written to a new folder")
        cls = lerobot_dataset_class()
        self.features = features
        self.dataset = cls.create(repo_id=repo_id, fps=features.fps, root=self.part,
                                  features=features.as_lerobot(), robot_type=robot_type,
                                  use_videos=bool(features.cameras))
        self.episodes = 0
        self.frames = 0

    def __repr__(self) -> str:
        return f"DatasetWriter({self.root}, {self.episodes} episodes)"

    def add(self, text: str, states: npt.NDArray[np.float32], actions: npt.NDArray[np.float32],
            *, task_state: npt.NDArray[np.float32] | None = None, success: bool = True,
            images: dict[str, list[npt.NDArray[np.uint8]]] | None = None) -> None:
        """One episode: ``states`` and ``actions`` (frames x motors), the task's state
        (the same on every frame), each camera's RGB frames by role; ``success`` is marked
        on its last frame (``next.success``)."""
        n = len(states)
        if n == 0 or len(actions) != n:
            raise ConfigError(f"an episode needs frames, as many actions as states "
                              f"({n} states, {len(actions)} actions)")
        for k in range(n):
            frame: dict[str, Any] = {
                "observation.state": states[k], "action": actions[k], "task": text,
                "next.success": np.array([success and k == n - 1], bool)}
            if self.features.task_state:
                frame["observation.environment_state"] = (
                    task_state if task_state is not None else np.zeros(5, np.float32))
            for role, pictures in (images or {}).items():
                frame[f"observation.images.{role}"] = pictures[k]
            self.dataset.add_frame(frame)
        with warnings.catch_warnings():  # LeRobot's stats take next.success as a number
            warnings.filterwarnings("ignore", "Converting input from bool", RuntimeWarning)
            self.dataset.save_episode()
        self.episodes += 1
        self.frames += n

    def close(self) -> None:
        """Finish the files; the dataset takes its name (with no episode: removed)."""
        if not self.part.exists():
            return
        try:
            self.dataset.finalize()
        finally:
            if self.episodes:
                self.part.rename(self.root)
            else:
                shutil.rmtree(self.part, ignore_errors=True)

    def __enter__(self) -> DatasetWriter:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
