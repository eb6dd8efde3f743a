"""What a learning robot's frame holds: the names, units and shapes of busarm's state,
action and task state, in the form LeRobot's datasets declare them.

``observation.state`` and ``action`` are the flat form of ``Robot.get_observation`` and
``Robot.send_action`` (busarm.robot.observation): each joint's angle in rad
(``NAME.pos``) and the gripper's gap in mm (``gripper.gap_mm``). An action is where the
servos are to be taken next (a move of one frame's time). ``observation.environment_state``
is what the camera saw of the task before it began, in the table's units (mm, deg):
the block to move and the bin it goes to, as busarm's locator found them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from busarm.arm.config import ArmConfig
from busarm.robot.observation import GRIPPER_KEY, JOINT_SUFFIX

__all__ = [
    "DEFAULT_FPS",
    "TASK_STATE_NAMES",
    "Features",
    "motor_names",
]

DEFAULT_FPS = 20
"""Frames a second of a recorded episode and of a policy's actions: a move of 50 ms is
what the servos' own interpolation follows smoothly (their moves are 20 ms and longer)."""
TASK_STATE_NAMES = ("block.x_mm", "block.y_mm", "block.yaw_deg", "bin.x_mm", "bin.y_mm")
"""``observation.environment_state``: the block and its bin as the camera found them
(base frame, mm; the block's yaw folded into 0..90 deg, a cube's faces being alike)."""


def motor_names(config: ArmConfig) -> list[str]:
    """The state's and the action's names, in order: each joint (rad), the gripper (mm)."""
    return [f"{j.name}{JOINT_SUFFIX}" for j in config.joints] + [GRIPPER_KEY]


@dataclass(frozen=True)
class Features:
    """The features of busarm's learning frames for an arm config, ``fps`` and cameras
    (role -> (height, width)); ``as_lerobot()`` is LeRobot's ``features`` dict."""

    motors: tuple[str, ...]
    fps: int = DEFAULT_FPS
    cameras: tuple[tuple[str, int, int], ...] = ()
    task_state: bool = True

    @classmethod
    def of(cls, config: ArmConfig, *, fps: int = DEFAULT_FPS,
           cameras: Sequence[tuple[str, int, int]] = (), task_state: bool = True) -> Features:
        """The features of ``config``'s arm: ``cameras`` as (role, height, width),
        ``task_state`` with the task's state (the expert's and the environment's)."""
        return cls(tuple(motor_names(config)), fps, tuple(cameras), task_state)

    def as_lerobot(self, *, videos: bool = True) -> dict[str, dict[str, Any]]:
        """LeRobot's ``features``: dtype, shape and names of each key of a frame."""
        n = len(self.motors)
        out: dict[str, dict[str, Any]] = {
            "observation.state": {"dtype": "float32", "shape": (n,), "names": list(self.motors)},
            "action": {"dtype": "float32", "shape": (n,), "names": list(self.motors)},
        }
        if self.task_state:
            out["observation.environment_state"] = {
                "dtype": "float32", "shape": (len(TASK_STATE_NAMES),),
                "names": list(TASK_STATE_NAMES)}
        for role, height, width in self.cameras:
            out[f"observation.images.{role}"] = {
                "dtype": "video" if videos else "image", "shape": (height, width, 3),
                "names": ["height", "width", "channels"]}
        out["next.success"] = {"dtype": "bool", "shape": (1,), "names": None}
        return out
