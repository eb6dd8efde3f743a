"""The arm: configuration, kinematics, motion, calibration, action groups.

``Arm.open("sim")`` gives the simulated JetAuto Pro arm; ``ArmKinematics`` is the pure
model (no bus); ``load_arm_config`` reads an arm description.
"""

from busarm.arm.actions import ActionFrame, ActionGroup, read_d6a, write_d6a
from busarm.arm.arm import Arm, GripResult, MotionRecord
from busarm.arm.calibration import Calibration, load_calibration, save_calibration
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics, Pose

__all__ = [
    "ActionFrame",
    "ActionGroup",
    "Arm",
    "ArmConfig",
    "ArmKinematics",
    "Calibration",
    "GripResult",
    "MotionRecord",
    "Pose",
    "load_arm_config",
    "load_calibration",
    "read_d6a",
    "save_calibration",
    "write_d6a",
]
