"""The twin as a gymnasium environment: a seeded table, a task, the arm moved one frame at
a time by joint targets, success judged on the twin's truth.

``PickPlaceEnv(task="one-block")``; ``reset(seed=s)`` opens the twin on table ``s`` of
the task (busarm.learn.tasks; seeds from ``HELD_OUT_SEED`` are the evaluation tables),
brings the arm to its look pose and looks, as a recorded episode begins
(busarm.learn.expert). ``step(action)``: the joints' targets (rad) and the gripper's
gap (mm), the state's order; clipped to the limits (busarm.learn.limits), sent as a move
of one frame, and one frame of the twin's time later observed. The observation:
``agent_pos`` (the state), ``environment_state`` (what the look found: the block and its
bin), with ``obs_type="pixels_agent_pos"`` also ``pixels`` (the wrist camera, RGB).
``reward`` is 1 and the episode ends when every block lies in its bin (the twin's truth,
``info["is_success"]``). ``render()`` is the twin's overview camera, RGB.

gymnasium is installed with busarm's ``learn`` extra (``pip install busarm[learn]``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from busarm.apps.pick_sort.sorter import PickSorter
from busarm.errors import ConfigError
from busarm.learn.expert import first_look
from busarm.learn.features import DEFAULT_FPS, TASK_STATE_NAMES
from busarm.learn.frames import FrameRobot
from busarm.learn.limits import ActionLimits
from busarm.learn.tasks import HELD_OUT_SEED, check_task, is_done, task_scene, task_state
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.lens import lens_by_name
from busarm.twin.spec import TwinSpec

__all__ = [
    "EPISODE_S",
    "OBS_TYPES",
    "PickPlaceEnv",
]

OBS_TYPES = ("state", "pixels_agent_pos")
EPISODE_S = 15.0
"""A task's time (the expert's one block takes about 4.5 s)."""


class PickPlaceEnv(gym.Env[dict[str, Any], npt.NDArray[np.float32]]):
    """busarm's twin as a gymnasium environment (the module docstring says how)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": DEFAULT_FPS}  # noqa: RUF012

    def __init__(self, task: str = "one-block", *, obs_type: str = "state",
                 fps: int = DEFAULT_FPS, render_mode: str | None = "rgb_array",
                 camera: CameraSpec | None = None) -> None:
        self.task = check_task(task)
        if obs_type not in OBS_TYPES:
            raise ConfigError(f"obs_type = {obs_type!r}; allowed: {', '.join(OBS_TYPES)}")
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode = {render_mode!r}; allowed: rgb_array, None")
        self.obs_type, self.fps, self.render_mode = obs_type, fps, render_mode
        self.camera = camera or CameraSpec()  # a twin's calibration, made once and kept
        self.robot: Robot | None = None
        self.frames: FrameRobot | None = None
        self.config = TwinSpec().arm_config()
        self.limits = ActionLimits.of(self.config, fps)
        self._next_seed = HELD_OUT_SEED
        self._task_state: npt.NDArray[np.float32] = np.zeros(len(TASK_STATE_NAMES), np.float32)
        self._t_frame = 0.0
        self.clipped = 0
        """Action values clipped to the limits in this episode."""
        n = len(self.limits.names)
        self.action_space = spaces.Box(np.asarray(self.limits.low, np.float32),
                                       np.asarray(self.limits.high, np.float32), (n,),
                                       np.float32)
        obs: dict[str, spaces.Space[Any]] = {
            "agent_pos": spaces.Box(-np.inf, np.inf, (n,), np.float64),
            "environment_state": spaces.Box(-np.inf, np.inf, (len(TASK_STATE_NAMES),),
                                            np.float64)}
        if obs_type == "pixels_agent_pos":
            lens = lens_by_name(TwinSpec().lens)
            h, w = lens.height_px, lens.width_px
            obs["pixels"] = spaces.Dict({"wrist": spaces.Box(0, 255, (h, w, 3), np.uint8)})
        self.observation_space = spaces.Dict(obs)
        self._max_episode_steps = round(EPISODE_S * fps)

    def __repr__(self) -> str:
        return f"PickPlaceEnv({self.task!r}, {self.obs_type}, {self.fps} fps)"

    # ------------------------------------------------------------------ gymnasium

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None
              ) -> tuple[dict[str, Any], dict[str, Any]]:
        """A new twin on table ``seed`` of the task (None: the next held-out one), the
        arm at its look pose, the table looked at; the first observation."""
        super().reset(seed=seed)
        if seed is None:
            seed, self._next_seed = self._next_seed, self._next_seed + 1
        self.close()
        pixels = self.obs_type == "pixels_agent_pos"
        self.frames = FrameRobot(RobotConfig(TwinSpec(scene=task_scene(self.task, seed)),
                                             camera=self.camera), fps=self.fps,
                                 cameras=("wrist",) if pixels else ())
        self.robot = robot = self.frames.open()
        sorter = PickSorter(robot)
        self._task_state = task_state(first_look(robot, sorter), sorter.bins)
        self.clipped = 0
        self._t_frame = robot.clock.now()
        return self._observe(), {"is_success": False, "seed": seed}

    def step(self, action: npt.ArrayLike
             ) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """One frame: ``action`` clipped and sent (busarm.learn.frames), the twin's time
        moved on a frame, the observation; reward 1 and the end once the task is done."""
        robot = self._robot()
        assert self.frames is not None
        values = np.asarray(action, np.float64).reshape(-1)
        if values.shape != (len(self.limits.names),):
            raise ConfigError(f"an action has {len(self.limits.names)} values "
                              f"({', '.join(self.limits.names)}); got {values.shape[0]}")
        self.frames.act(dict(zip(self.limits.names, values.tolist(), strict=True)))
        self.clipped = self.frames.clipped
        self._t_frame += 1.0 / self.fps
        robot.clock.sleep(max(0.0, self._t_frame - robot.clock.now()))
        success = self.is_success()
        return (self._observe(), float(success), success, False,
                {"is_success": success, "clipped": self.clipped})

    def render(self) -> npt.NDArray[np.uint8]:
        frame = self._robot().cameras["overview"].read().image
        return np.ascontiguousarray(frame[..., ::-1])

    def close(self) -> None:
        if self.robot is not None:
            self.robot = None
        if self.frames is not None:
            frames, self.frames = self.frames, None
            frames.close()

    # ------------------------------------------------------------------ the task

    def is_success(self) -> bool:
        """Every block in its colour's tray (the twin's truth)."""
        robot = self._robot()
        assert robot.twin is not None
        return is_done(robot.twin, robot.bins)

    def _robot(self) -> Robot:
        if self.robot is None:
            raise ConfigError("the environment is not reset: call reset() first")
        return self.robot

    def _observe(self) -> dict[str, Any]:
        assert self.frames is not None
        seen = self.frames.observe()
        out: dict[str, Any] = {
            "agent_pos": np.array([seen[n] for n in self.limits.names]),
            "environment_state": self._task_state.astype(np.float64)}
        if "wrist" in seen:
            out["pixels"] = {"wrist": seen["wrist"]}
        return out
