"""The robot layer: one object holding the arm, its base, Lidar and cameras, their
calibrations, the block locator and the twin when it is one (``Robot.open(description)``),
and the robot's description (``RobotConfig``).

The names below are loaded on first use, so ``busarm.robot.description`` (or
``busarm.robot.port_url``) loads neither MuJoCo nor OpenCV.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.robot.calibration_store import CameraCalibration
    from busarm.robot.description import (
        ArmSpec,
        BaseSpec,
        CameraSpec,
        LidarSpec,
        RobotConfig,
        ServoLine,
    )
    from busarm.robot.robot import Robot

__all__ = [
    "ArmSpec",
    "BaseSpec",
    "CameraCalibration",
    "CameraSpec",
    "LidarSpec",
    "Robot",
    "RobotConfig",
    "ServoLine",
]

_SOURCES = {
    "CameraCalibration": ".calibration_store",
    **{name: ".description" for name in ("ArmSpec", "BaseSpec", "CameraSpec", "LidarSpec",
                                         "RobotConfig", "ServoLine")},
    "Robot": ".robot",
}

__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
