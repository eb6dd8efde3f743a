"""The robot layer: one object holding the arm, its cameras, their calibrations, the block
locator and the twin when it is one (``Robot.open(port)``)."""

from busarm.robot.robot import CameraCalibration, Robot

__all__ = ["CameraCalibration", "Robot"]
