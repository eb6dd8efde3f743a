"""busarm in LeRobot: the robot (``--robot.type=busarm``), its teleoperators
(``busarm_leader``, ``busarm_keyboard``, ``busarm_gamepad``) and the twin as an environment
(``--env.type=busarm``, gymnasium ids ``lerobot_robot_busarm/OneBlock-v0`` and
``lerobot_robot_busarm/Table-v0``). LeRobot imports this distribution by its name
(``register_third_party_plugins``); the classes register themselves on import."""

from __future__ import annotations

import gymnasium as gym

from lerobot_robot_busarm.busarm_robot import Busarm
from lerobot_robot_busarm.busarm_teleop import BusarmGamepad, BusarmKeyboard, BusarmLeader
from lerobot_robot_busarm.config_busarm import (
    GYM_PACKAGE,
    BusarmConfig,
    BusarmEnv,
    BusarmGamepadConfig,
    BusarmKeyboardConfig,
    BusarmLeaderConfig,
)

__all__ = [
    "Busarm",
    "BusarmConfig",
    "BusarmEnv",
    "BusarmGamepad",
    "BusarmGamepadConfig",
    "BusarmKeyboard",
    "BusarmKeyboardConfig",
    "BusarmLeader",
    "BusarmLeaderConfig",
]

for _gym_task, _task in (("OneBlock-v0", "one-block"), ("Table-v0", "table")):
    if f"{GYM_PACKAGE}/{_gym_task}" not in gym.registry:
        gym.register(f"{GYM_PACKAGE}/{_gym_task}", entry_point="busarm.learn.env:PickPlaceEnv",
                     kwargs={"task": _task})
