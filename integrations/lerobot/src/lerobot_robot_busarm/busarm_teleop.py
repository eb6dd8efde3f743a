"""busarm's teleoperators for LeRobot: a leader arm of LX servos (torque off), the keyboard
of a terminal and a gamepad (busarm.learn.leader, busarm.learn.keyboard,
busarm.learn.gamepad). Each gives the robot's motors in the state's form; none gives or
takes feedback, and none has a calibration of LeRobot's (busarm's are its own)."""

from __future__ import annotations

import os
from typing import Any, Protocol

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


class _Source(Protocol):
    def read(self) -> dict[str, float]: ...

    def close(self) -> None: ...


class _BusarmTeleop(Teleoperator):  # type: ignore[misc]
    """What busarm's teleoperators share: the arm's motors as the action, no feedback, no
    calibration of LeRobot's; ``_open`` gives what is read each frame."""

    def __init__(self, config: Any) -> None:
        super().__init__(config)
        self.config = config
        self.arm_config = (load_arm_config(config.arm_config) if config.arm_config
                           else load_arm_config())
        self.source: _Source | None = None

    def _open(self) -> _Source:
        raise NotImplementedError

    @property
    def action_features(self) -> dict[str, type]:
        return {name: float for name in motor_names(self.arm_config)}

    @property
    def feedback_features(self) -> dict[str, type]:
        return {}

    @property
    def is_connected(self) -> bool:
        return self.source is not None

    def connect(self, calibrate: bool = True) -> None:
        self.source = self._open()

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """Nothing of LeRobot's: a leader's joint calibration is busarm's own (``busarm
        arm calibrate``), a keyboard or gamepad needs none."""

    def configure(self) -> None:
        """Nothing to set."""

    def get_action(self) -> dict[str, float]:
        if self.source is None:
            raise ConnectionError(f"{self.name} is not connected")
        return self.source.read()

    def send_feedback(self, feedback: dict[str, Any]) -> None:
        """Nothing to give feedback to."""

    def disconnect(self) -> None:
        if self.source is not None:
            source, self.source = self.source, None
            source.close()


class BusarmLeader(_BusarmTeleop):
    """``--teleop.type=busarm_leader --teleop.port=/dev/ttyUSB1``: opened limp, read in the
    background."""

    config_class = BusarmLeaderConfig
    name = "busarm_leader"

    def _open(self) -> _Source:
        return LeaderArm(self.config.port, config=self.config.arm_config, background=True,
                         line=ServoLine(timeout_margin_s=self.config.timeout_margin_s)).open()


class _Terminal:
    """The keyboard on a terminal device of its own (``tty``) or this one's."""

    def __init__(self, config: BusarmKeyboardConfig, arm_config: Any) -> None:
        self.fd = (os.open(config.tty, os.O_RDONLY | os.O_NOCTTY) if config.tty else None)
        self.jog = KeyboardJog(arm_config, fd=self.fd, step_deg=config.step_deg,
                               gripper_step_mm=config.gripper_step_mm).open()

    def read(self) -> dict[str, float]:
        return self.jog.read()

    def close(self) -> None:
        self.jog.close()
        if self.fd is not None:
            os.close(self.fd)


class BusarmKeyboard(_BusarmTeleop):
    """``--teleop.type=busarm_keyboard``: keys of the terminal (busarm.learn.keyboard)."""

    config_class = BusarmKeyboardConfig
    name = "busarm_keyboard"

    def _open(self) -> _Source:
        return _Terminal(self.config, self.arm_config)


class BusarmGamepad(_BusarmTeleop):
    """``--teleop.type=busarm_gamepad --teleop.device=/dev/input/js0``."""

    config_class = BusarmGamepadConfig
    name = "busarm_gamepad"

    def _open(self) -> _Source:
        return GamepadJog(self.arm_config, device=self.config.device,
                          speed_deg_s=self.config.speed_deg_s).open()
