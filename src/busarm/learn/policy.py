"""A policy trained by LeRobot (``lerobot-train``), loaded to act on busarm's observations.

``LoadedPolicy(path)`` reads a pretrained policy folder (``.../checkpoints/last/
pretrained_model``: its config, weights and the processors that normalise its inputs and
outputs); ``act(observation)`` takes an observation in the environment's form
(busarm.learn.env: ``agent_pos``, ``environment_state``, ``pixels``) and gives the next
action (the state's order). PyTorch and LeRobot are needed (``make lerobot``).
"""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.learn.dataset import LEROBOT_MISSING

__all__ = [
    "LoadedPolicy",
    "policy_fps",
]


def policy_fps(path: Path, default: int) -> int:
    """The rate a policy was trained at: its training's dataset's (``train_config.json``
    beside the weights), else ``default``."""
    for folder in (path, path.parent):
        config = folder / "train_config.json"
        if config.is_file():
            data = json.loads(config.read_text())
            root = (data.get("dataset") or {}).get("root")
            info = Path(root) / "meta" / "info.json" if root else None
            if info is not None and info.is_file():
                return int(json.loads(info.read_text())["fps"])
            fps = (data.get("env") or {}).get("fps")
            if fps:
                return int(fps)
    return default


class LoadedPolicy:
    """A LeRobot policy from ``path``, on the CPU."""

    def __init__(self, path: Path) -> None:
        if not (path / "config.json").is_file():
            raise ConfigError(f"{path} holds no policy (no config.json): give a pretrained "
                              "policy folder, e.g. OUTPUT/checkpoints/last/pretrained_model")
        try:
            import torch
            from lerobot.configs.policies import PreTrainedConfig
            from lerobot.envs.utils import preprocess_observation
            from lerobot.policies.factory import get_policy_class, make_pre_post_processors
        except ImportError as exc:
            raise ConfigError(f"{LEROBOT_MISSING} ({exc})") from None
        self._torch, self._preprocess = torch, preprocess_observation
        config = PreTrainedConfig.from_pretrained(path)
        config.device = "cpu"
        self.type = config.type
        with contextlib.redirect_stdout(sys.stderr):  # LeRobot says what it loads on stdout
            self.policy = get_policy_class(config.type).from_pretrained(path, config=config)
            self.policy.eval()
            self.pre, self.post = make_pre_post_processors(config, pretrained_path=str(path))
        self.path = path

    def __repr__(self) -> str:
        return f"LoadedPolicy({self.type} from {self.path})"

    @property
    def cameras(self) -> list[str]:
        """The cameras its inputs name (``observation.images.ROLE``), by role."""
        prefix = "observation.images."
        return [k[len(prefix):] for k in self.policy.config.input_features
                if k.startswith(prefix)]

    def check_motors(self, motors: Sequence[str]) -> None:
        """ConfigError unless its actions are as long as ``motors`` (the robot's)."""
        action = self.policy.config.output_features.get("action")
        size = int(action.shape[0]) if action is not None else -1
        if size != len(motors):
            raise ConfigError(f"the policy at {self.path} acts on {size} values; this robot "
                              f"takes {len(motors)} ({', '.join(motors)})")

    def reset(self) -> None:
        """A new episode: forget the actions queued from the last one."""
        self.policy.reset()

    def act(self, observation: dict[str, Any]) -> npt.NDArray[np.float64]:
        """The next action for ``observation`` (the environment's form)."""
        torch = self._torch
        batch = self._preprocess({k: (v if isinstance(v, dict) else np.asarray(v)[None])
                                  if k != "pixels" else {r: np.asarray(i)[None]
                                                         for r, i in v.items()}
                                  for k, v in observation.items()})
        batch = self.pre(batch)
        with torch.inference_mode():
            action = self.policy.select_action(batch)
        action = self.post(action)
        return np.asarray(action.detach().cpu().numpy(), np.float64).reshape(-1)
