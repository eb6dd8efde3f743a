"""The arm: configuration, kinematics, motion, calibration, action groups.

``Arm.open(SimSpec())`` gives the simulated JetAuto Pro arm (``Arm.open("/dev/ttyUSB0")``
the real one); ``ArmKinematics`` is the pure model (no bus); ``load_arm_config`` reads
an arm description.

The names below are loaded on first use, so ``import busarm.arm.kinematics`` (or
``busarm.arm.config``) loads neither the bus driver nor the rest of the arm:
``from busarm.arm import Arm`` still works, and imports the driver then.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the layer contract
    from busarm.arm.actions import ActionFrame, ActionGroup, read_d6a, write_d6a
    from busarm.arm.arm import Arm, GripResult, MotionRecord
    from busarm.arm.calibration import Calibration, load_calibration, save_calibration
    from busarm.arm.chain import Pose
    from busarm.arm.config import ArmConfig, load_arm_config
    from busarm.arm.gripper import GripperState, gripper_state
    from busarm.arm.kinematics import ArmKinematics

__all__ = [
    "ActionFrame",
    "ActionGroup",
    "Arm",
    "ArmConfig",
    "ArmKinematics",
    "Calibration",
    "GripResult",
    "GripperState",
    "MotionRecord",
    "Pose",
    "gripper_state",
    "load_arm_config",
    "load_calibration",
    "read_d6a",
    "save_calibration",
    "write_d6a",
]

_SOURCES: dict[str, str] = {
    "ActionFrame": ".actions",
    "ActionGroup": ".actions",
    "read_d6a": ".actions",
    "write_d6a": ".actions",
    "Arm": ".arm",
    "GripResult": ".arm",
    "MotionRecord": ".arm",
    "Calibration": ".calibration",
    "load_calibration": ".calibration",
    "save_calibration": ".calibration",
    "ArmConfig": ".config",
    "load_arm_config": ".config",
    "GripperState": ".gripper",
    "gripper_state": ".gripper",
    "ArmKinematics": ".kinematics",
    "Pose": ".chain",
}
"""Each exported name and the submodule that defines it."""


__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
