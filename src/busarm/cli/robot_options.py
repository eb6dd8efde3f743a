"""The command line's robot options made into one ``RobotConfig``: the edge where a port
string is read (``busarm.robot.port_url``) and every option finds its place."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.arm.calibration import Calibration
    from busarm.arm.config import ArmConfig
    from busarm.base.config import ChassisConfig
    from busarm.bus.ports import PortSpec
    from busarm.robot.calibration_store import CalibrationStore
    from busarm.robot.description import RobotConfig, ServoLine
    from busarm.twin.arena import Arena
    from busarm.twin.scene import Scene
    from busarm.vision.camera import CameraSource

__all__ = [
    "camera_from_text",
    "describe_robot",
    "from_robot_file",
    "with_realtime",
]


def describe_robot(
    world: PortSpec, line: ServoLine, *, camera: str | None = None,
    config: ArmConfig | str | Path | None = None,
    arm_calibration: Calibration | str | Path | None = None,
    intrinsics: Path | None = None, hand_eye: Path | None = None,
    bins: Mapping[str, tuple[float, float]] | None = None, calibrate: bool = True,
    calibration_dir: Path | None = None, calibration_store: CalibrationStore | None = None,
    board: str | None = None, scene: Scene | None = None, arena: Arena | None = None,
    chassis: ChassisConfig | str | Path | None = None, lidar: str | None = None,
) -> RobotConfig:
    """The robot the command's options describe, in ``world`` (the parsed --port)."""
    from busarm.robot.description import (
        ArmSpec,
        BaseSpec,
        CameraSpec,
        LidarSpec,
        RobotConfig,
    )
    from busarm.robot.port_url import parse_lidar_port
    from busarm.twin.spec import TwinSpec

    if scene is not None or arena is not None:
        if not isinstance(world, TwinSpec):
            what = "a scene" if scene is not None else "an arena"
            raise ConfigError(f"{what} is for the twin; {world.name} is not one (use --port "
                              "twin, or no --port)")
        world = world.placed(scene=scene, arena=arena)
    if board is not None and isinstance(world, TwinSpec):  # on hardware, a person lays it
        world = world.with_board(board)
    base = BaseSpec(chassis) if chassis is not None and not isinstance(world, TwinSpec) else None
    if chassis is not None and isinstance(world, TwinSpec):
        world = replace(world, chassis=chassis)
    return RobotConfig(
        world, ArmSpec(config, arm_calibration, line), base=base,
        lidar=LidarSpec(parse_lidar_port(lidar)) if lidar is not None else None,
        # The commands say which store they use (calibration_store), or none (those
        # that make a calibration): never the default one behind their back.
        camera=CameraSpec(camera, intrinsics, hand_eye, calibrate, calibration_store,
                          calibration_dir, keep=False),
        bins=bins)


def with_realtime(world: PortSpec) -> PortSpec:
    """A twin or simulator in this process that follows the wall clock (in-process
    simulations otherwise run as fast as they compute, which no person can watch or stop
    in time); any other port as it is."""
    from busarm.sim.spec import SimSpec
    from busarm.twin.spec import TwinSpec

    if not isinstance(world, SimSpec | TwinSpec):
        return world
    if world.pace is not None:
        raise ConfigError(f"--port {world.name}: the dashboard runs the robot in real time; "
                          "leave out pace=")
    return replace(world, realtime=True)


def from_robot_file(file: RobotConfig, options: dict[str, Any]) -> RobotConfig:
    """The robot of a robot file (``--robot FILE``), with what the command's own options
    give (a camera, calibration files, bins, a Lidar, a scene on a twin) over it."""
    from busarm.robot.description import CameraSpec

    cam = file.camera
    options = {k: v for k, v in options.items() if v is not None}
    given_config = options.pop("config", None)
    camera = CameraSpec(options.pop("camera", cam.source),
                        options.pop("intrinsics", cam.intrinsics),
                        options.pop("hand_eye", cam.hand_eye),
                        options.pop("calibrate", cam.calibrate),
                        options.pop("calibration_store", cam.store),
                        options.pop("calibration_dir", cam.folder), keep=False)
    described = describe_robot(file.world, file.arm.line,
                               config=file.arm.config or given_config,
                               arm_calibration=options.pop("arm_calibration",
                                                           file.arm.calibration),
                               bins=options.pop("bins", file.bins), **options)
    return replace(described, camera=camera,
                   base=described.base or file.base, lidar=described.lidar or file.lidar)


def camera_from_text(spec: str) -> CameraSource:
    """The camera ``--camera`` names: a twin port (``twin://?board=tags``) is a twin of its
    own, read here, at the edge; anything else is the camera table's
    (busarm.vision.camera)."""
    from busarm.robot.port_url import parse_port
    from busarm.twin.camera import TwinCamera
    from busarm.twin.spec import TwinSpec
    from busarm.vision.camera import open_camera

    if spec.startswith("twin://?"):
        world = parse_port(spec)
        if isinstance(world, TwinSpec) and world.controller is None:
            return TwinCamera(world.build(), owns_twin=True)
    return open_camera(spec)
