"""busarm's robot as a LeRobot ``Robot``: any busarm robot (hardware, a served twin, a twin
in this process) through ``busarm.learn.frames.FrameRobot``, whose every action is clipped
to the limits and checked again by busarm before it is sent."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from lerobot.robots.robot import Robot

from busarm.learn.frames import FrameRobot
from busarm.robot import RobotConfig
from busarm.robot.robot_file import load_robot_file
from busarm.twin.spec import TwinSpec
from lerobot_robot_busarm.config_busarm import BusarmConfig

__all__ = ["Busarm", "description_of"]


def description_of(config: BusarmConfig) -> RobotConfig:
    """The busarm robot description a LeRobot config names."""
    if config.robot_file:
        description, _name = load_robot_file(config.robot_file)
    else:
        description = RobotConfig.from_port(config.port)
    world = description.world
    if isinstance(world, TwinSpec) and config.realtime and not world.realtime:
        description = replace(description, world=replace(world, realtime=True))
    if config.timeout_margin_s is not None:
        arm = description.arm
        description = replace(description, arm=replace(arm, line=replace(
            arm.line, timeout_margin_s=config.timeout_margin_s)))
    return description


class Busarm(Robot):  # type: ignore[misc]
    """``--robot.type=busarm --robot.port=twin``."""

    config_class = BusarmConfig
    name = "busarm"

    def __init__(self, config: BusarmConfig) -> None:
        super().__init__(config)
        self.config = config
        self.frames = FrameRobot(description_of(config), fps=config.fps,
                                 cameras=config.camera_roles,
                                 camera_size=(config.camera_height, config.camera_width))
        # lerobot-record sizes its image writers by the cameras.
        self.cameras = {role: role for role in config.camera_roles}

    @property
    def observation_features(self) -> dict[str, Any]:
        return self.frames.observation_features

    @property
    def action_features(self) -> dict[str, Any]:
        return self.frames.action_features

    @property
    def is_connected(self) -> bool:
        return self.frames.robot is not None

    def connect(self, calibrate: bool = True) -> None:
        self.frames.open()

    @property
    def is_calibrated(self) -> bool:
        return True  # busarm's joint calibration is its own (busarm arm calibrate)

    def calibrate(self) -> None:
        """Nothing here: ``busarm arm calibrate`` makes a joint calibration, and the
        robot description (a robot file) names it."""

    def configure(self) -> None:
        """Nothing to set: busarm's drivers set up the servos when they open them."""

    def get_observation(self) -> dict[str, Any]:
        return self.frames.observe()

    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        return self.frames.act({k: float(v) for k, v in action.items()})

    def disconnect(self) -> None:
        self.frames.close()
