"""The mobile base: the mecanum chassis, its kinematics and odometry, and ``Base``, which
drives it through the controller board. Metres, radians and seconds throughout.

``from busarm.base import Base, Pose2D, Twist``. The names are loaded on first use, so
``busarm.base.kinematics`` and ``busarm.base.odometry`` (pure) load no bus driver.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.base.base import Base, BaseOdometry
    from busarm.base.config import ChassisConfig, Mount, WheelMotor, load_chassis_config
    from busarm.base.kinematics import MecanumKinematics, Twist
    from busarm.base.odometry import Odometry, Pose2D

__all__ = [
    "Base",
    "BaseOdometry",
    "ChassisConfig",
    "MecanumKinematics",
    "Mount",
    "Odometry",
    "Pose2D",
    "Twist",
    "WheelMotor",
    "load_chassis_config",
]

_SOURCES: dict[str, str] = {
    "Base": ".base",
    "BaseOdometry": ".base",
    "ChassisConfig": ".config",
    "Mount": ".config",
    "WheelMotor": ".config",
    "load_chassis_config": ".config",
    "MecanumKinematics": ".kinematics",
    "Twist": ".kinematics",
    "Odometry": ".odometry",
    "Pose2D": ".odometry",
}
"""Each exported name and the submodule that defines it."""


__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
