"""busarm's teleoperators for LeRobot: a leader arm of LX servos (torque off), the keyboard
of a terminal and a gamepad (busarm.learn.leader, busarm.learn.keyboard,
busarm.learn.gamepad)."""

from __future__ import annotations

import os
from typing import Any

from lerobot.teleoperators.teleoperator import Teleoperator

from busarm.arm.config import load_arm_config
from busarm.learn.features import motor_names
from busarm.learn.gamepad import GamepadJog
from busarm.learn.keyboard import KeyboardJog
from busarm.learn.leader import LeaderArm
from busarm.robot import ServoLine
from lerobot_robot_busarm.config_busarm import (
    BusarmGamepadConfig,
    BusarmKeyboardConfig,
    BusarmLeaderConfig,
)

__all__ = ["BusarmGamepad", "BusarmKeyboard", "BusarmLeader"]


class BusarmLeader(Teleoperator):  # type: ignore[misc]
    """``--teleop.type=busarm_leader --teleop.port=/dev/ttyUSB1``."""

    config_class = BusarmLeaderConfig
    name = "busarm_leader"

    def __init__(self, config: BusarmLeaderConfig) -> None:
        super().__init__(config)
        self.config = config
        self.leader = LeaderArm(config.port, config=config.arm_config, background=True,
                                line=ServoLine(timeout_margin_s=config.timeout_margin_s))
        self.motors = motor_names(load_arm_config(config.arm_config)
                                  if config.arm_config else load_arm_config())

    @property
    def action_features(self) -> dict[str, type]:
        return {name: float for name in self.motors}

    @property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self.leader.robot is not None

    def connect(self, calibrate: bool = True) -> None:
        self.leader.open()

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """busarm's joint calibration is its own (``busarm arm calibrate`` on the leader)."""

    def configure(self) -> None:
        """Nothing to set: the leader is opened limp."""

    def get_action(self) -> dict[str, float]:
        return self.leader.read()

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        """A leader arm has no feedback to give."""

    def disconnect(self) -> None:
        self.leader.close()


class BusarmKeyboard(Teleoperator):  # type: ignore[misc]
    """``--teleop.type=busarm_keyboard``: keys of the terminal (busarm.learn.keyboard)."""

    config_class = BusarmKeyboardConfig
    name = "busarm_keyboard"

    def __init__(self, config: BusarmKeyboardConfig) -> None:
        super().__init__(config)
        self.config = config
        self._fd: int | None = None
        self.jog: KeyboardJog | None = None
        self.arm_config = (load_arm_config(config.arm_config) if config.arm_config
                           else load_arm_config())

    @property
    def action_features(self) -> dict[str, type]:
        return {name: float for name in motor_names(self.arm_config)}

    @property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self.jog is not None

    def connect(self, calibrate: bool = True) -> None:
        if self.config.tty:
            self._fd = os.open(self.config.tty, os.O_RDONLY | os.O_NOCTTY)
        self.jog = KeyboardJog(self.arm_config, fd=self._fd, step_deg=self.config.step_deg,
                               gripper_step_mm=self.config.gripper_step_mm).open()

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """A keyboard needs none."""

    def configure(self) -> None:
        """Nothing to set."""

    def get_action(self) -> dict[str, float]:
        if self.jog is None:
            raise ConnectionError("the keyboard is not connected")
        return self.jog.read()

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        """A keyboard has no feedback to give."""

    def disconnect(self) -> None:
        if self.jog is not None:
            self.jog.close()
            self.jog = None
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


class BusarmGamepad(Teleoperator):  # type: ignore[misc]
    """``--teleop.type=busarm_gamepad --teleop.device=/dev/input/js0``."""

    config_class = BusarmGamepadConfig
    name = "busarm_gamepad"

    def __init__(self, config: BusarmGamepadConfig) -> None:
        super().__init__(config)
        self.config = config
        self.arm_config = (load_arm_config(config.arm_config) if config.arm_config
                           else load_arm_config())
        self.pad: GamepadJog | None = None

    @property
    def action_features(self) -> dict[str, type]:
        return {name: float for name in motor_names(self.arm_config)}

    @property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self.pad is not None

    def connect(self, calibrate: bool = True) -> None:
        self.pad = GamepadJog(self.arm_config, device=self.config.device,
                              speed_deg_s=self.config.speed_deg_s).open()

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """A gamepad needs none (its dead zone is busarm's)."""

    def configure(self) -> None:
        """Nothing to set."""

    def get_action(self) -> dict[str, float]:
        if self.pad is None:
            raise ConnectionError("the gamepad is not connected")
        return self.pad.read()

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        """No rumble: nothing to give."""

    def disconnect(self) -> None:
        if self.pad is not None:
            self.pad.close()
            self.pad = None
