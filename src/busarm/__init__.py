"""busarm: drive a JetAuto Pro style robot (an arm of LX bus servos on a mecanum base with
a 2D Lidar), real or simulated, from Python.

Start with a robot: ``Robot.open("twin")`` is the simulated robot (the MuJoCo twin),
``Robot.open("/dev/ttyUSB0")`` the real arm; ``Robot.open(RobotConfig(...))`` a robot
described in full (its world, arm, base, Lidar, camera: ``RobotConfig``)::

    from busarm import Robot

    with Robot.open("twin") as robot:
        robot.arm.home()
        print(robot.arm.read_pose())

The names below are the ones a program needs; each is loaded on first use, so ``import
busarm`` stays light (no MuJoCo, OpenCV or serial port until they are used).

Units: metres, radians and seconds at the base and the Lidar (``Pose2D``, ``Twist``,
``LaserScan``); millimetres and degrees where the arm's world is a table (``Pose``,
joint angles), named so (``x_mm``, ``pitch_deg``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from busarm.lazy import lazy_exports
from busarm.version import __version__ as __version__

if TYPE_CHECKING:  # the same names, eagerly, for mypy and the API reference
    from busarm.apps.line_follow.job import LineFollowJob, LineFollowReport
    from busarm.apps.navigation.explore import MapRun, build_map
    from busarm.apps.navigation.navigator import Navigator, NavSettings, Trip
    from busarm.apps.pick_sort.sorter import PickSorter
    from busarm.apps.transport.job import TransportJob, TransportReport
    from busarm.arm import Arm, ArmConfig, ArmKinematics, Pose, load_arm_config
    from busarm.arm.arm import GripResult
    from busarm.base.base import Base
    from busarm.base.config import ChassisConfig, load_chassis_config
    from busarm.base.kinematics import Twist
    from busarm.base.odometry import Pose2D
    from busarm.bus.driver import ServoBus
    from busarm.bus.ports import SerialPort
    from busarm.bus.zenoh_link import ZenohPort
    from busarm.clock import WALL_CLOCK, Clock, FrozenClockWarning, SimClock
    from busarm.errors import (
        BusArmError,
        BusTimeoutError,
        CalibrationError,
        CameraError,
        ConfigError,
        ContactError,
        DeviceInUseError,
        HaltedError,
        KinematicsError,
        LimitError,
        MotionError,
        MotionTimeoutError,
        NavigationError,
        ProtocolError,
        ServoFaultError,
        TransportError,
        TwinError,
        UnreachableError,
        VisionError,
    )
    from busarm.lidar.rplidar import RplidarA1, open_lidar
    from busarm.lidar.scan import LaserScan, LidarSource
    from busarm.nav.grid import OccupancyGrid
    from busarm.nav.map_files import load_map, save_map
    from busarm.nav.points import NamedPoint, NamedPoints, load_points, save_points
    from busarm.perception.locate import Sighting
    from busarm.robot import (
        ArmSpec,
        BaseSpec,
        CameraCalibration,
        CameraSpec,
        LidarSpec,
        Robot,
        RobotConfig,
        ServoLine,
    )
    from busarm.robot.calibration_store import CalibrationStore
    from busarm.robot.observation import Action, Observation
    from busarm.robot.robot_file import load_robot_file, save_robot_file
    from busarm.sim.bus import SimBus
    from busarm.sim.spec import BoardSettings, SimLidarSpec, SimSpec
    from busarm.twin.spec import TwinSpec
    from busarm.twin.twin import Twin
    from busarm.vision.camera import CameraFrame, CameraSource
    from busarm.vision.localize import BlockLocation

_SOURCES: dict[str, str] = {
    # the robot
    "Robot": "busarm.robot",
    "CameraCalibration": "busarm.robot",
    # the robot's description: where it is (its world) and what it has
    **dict.fromkeys(("RobotConfig", "ArmSpec", "BaseSpec", "CameraSpec", "LidarSpec",
                     "ServoLine"), "busarm.robot"),
    "load_robot_file": "busarm.robot.robot_file",
    "save_robot_file": "busarm.robot.robot_file",
    "SerialPort": "busarm.bus.ports",
    "ZenohPort": "busarm.bus.zenoh_link",
    "SimSpec": "busarm.sim.spec",
    "BoardSettings": "busarm.sim.spec",
    "SimLidarSpec": "busarm.sim.spec",
    "TwinSpec": "busarm.twin.spec",
    "Observation": "busarm.robot.observation",
    "Action": "busarm.robot.observation",
    # the arm
    "Arm": "busarm.arm",
    "ArmConfig": "busarm.arm",
    "ArmKinematics": "busarm.arm",
    "Pose": "busarm.arm",
    "load_arm_config": "busarm.arm",
    # the base
    "Base": "busarm.base.base",
    "ChassisConfig": "busarm.base.config",
    "load_chassis_config": "busarm.base.config",
    "Pose2D": "busarm.base.odometry",
    "Twist": "busarm.base.kinematics",
    # sensors
    "LaserScan": "busarm.lidar.scan",
    "LidarSource": "busarm.lidar.scan",
    "RplidarA1": "busarm.lidar.rplidar",
    "open_lidar": "busarm.lidar.rplidar",
    "CameraFrame": "busarm.vision.camera",
    "CameraSource": "busarm.vision.camera",
    # maps and navigation
    "OccupancyGrid": "busarm.nav.grid",
    "load_map": "busarm.nav.map_files",
    "save_map": "busarm.nav.map_files",
    "NamedPoint": "busarm.nav.points",
    "NamedPoints": "busarm.nav.points",
    "load_points": "busarm.nav.points",
    "save_points": "busarm.nav.points",
    "build_map": "busarm.apps.navigation.explore",
    "MapRun": "busarm.apps.navigation.explore",
    "Navigator": "busarm.apps.navigation.navigator",
    "NavSettings": "busarm.apps.navigation.navigator",
    "Trip": "busarm.apps.navigation.navigator",
    # jobs
    "PickSorter": "busarm.apps.pick_sort.sorter",
    "TransportJob": "busarm.apps.transport.job",
    "TransportReport": "busarm.apps.transport.job",
    "LineFollowJob": "busarm.apps.line_follow.job",
    "LineFollowReport": "busarm.apps.line_follow.job",
    # the bus, the simulators, time
    "ServoBus": "busarm.bus.driver",
    "SimBus": "busarm.sim.bus",
    "Twin": "busarm.twin.twin",
    "Clock": "busarm.clock",
    "SimClock": "busarm.clock",
    "WALL_CLOCK": "busarm.clock",
    "FrozenClockWarning": "busarm.clock",
    # errors (all are BusArmError)
    **dict.fromkeys((
        "BusArmError", "BusTimeoutError", "CalibrationError", "CameraError", "ConfigError",
        "ContactError", "DeviceInUseError", "HaltedError", "KinematicsError", "LimitError",
        "MotionError", "MotionTimeoutError", "NavigationError", "ProtocolError",
        "ServoFaultError", "TransportError", "TwinError", "UnreachableError",
        "VisionError"), "busarm.errors"),
    "CalibrationStore": "busarm.robot.calibration_store",
    "GripResult": "busarm.arm.arm",
    "Sighting": "busarm.perception.locate",
    "BlockLocation": "busarm.vision.localize",
}
"""Each exported name and the module that defines it."""

__all__ = [
    "WALL_CLOCK",
    "Action",
    "Arm",
    "ArmConfig",
    "ArmKinematics",
    "ArmSpec",
    "Base",
    "BaseSpec",
    "BlockLocation",
    "BoardSettings",
    "BusArmError",
    "BusTimeoutError",
    "CalibrationError",
    "CalibrationStore",
    "CameraCalibration",
    "CameraError",
    "CameraFrame",
    "CameraSource",
    "CameraSpec",
    "ChassisConfig",
    "Clock",
    "ConfigError",
    "ContactError",
    "DeviceInUseError",
    "FrozenClockWarning",
    "GripResult",
    "HaltedError",
    "KinematicsError",
    "LaserScan",
    "LidarSource",
    "LidarSpec",
    "LimitError",
    "LineFollowJob",
    "LineFollowReport",
    "MapRun",
    "MotionError",
    "MotionTimeoutError",
    "NamedPoint",
    "NamedPoints",
    "NavSettings",
    "NavigationError",
    "Navigator",
    "Observation",
    "OccupancyGrid",
    "PickSorter",
    "Pose",
    "Pose2D",
    "ProtocolError",
    "Robot",
    "RobotConfig",
    "RplidarA1",
    "SerialPort",
    "ServoBus",
    "ServoFaultError",
    "ServoLine",
    "Sighting",
    "SimBus",
    "SimClock",
    "SimLidarSpec",
    "SimSpec",
    "TransportError",
    "TransportJob",
    "TransportReport",
    "Trip",
    "Twin",
    "TwinError",
    "TwinSpec",
    "Twist",
    "UnreachableError",
    "VisionError",
    "ZenohPort",
    "build_map",
    "load_arm_config",
    "load_chassis_config",
    "load_map",
    "load_points",
    "load_robot_file",
    "open_lidar",
    "save_map",
    "save_points",
    "save_robot_file",
]


__getattr__, __dir__ = lazy_exports(__name__, _SOURCES, __all__)
