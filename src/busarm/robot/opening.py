"""Opening a described robot (``Robot.open``): the one twin-or-hardware decision.

On a twin the wrist camera is the twin's, the bins are its trays, and a camera calibration
that was not given is made by our own flows in the twin (``calibrate``); on hardware the
camera, its calibration files and the bins come from the description. Everything is
checked before the arm moves; a failure closes what was opened.
"""

from __future__ import annotations

import tempfile
from collections.abc import Collection, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

from busarm.arm.arm import Arm
from busarm.arm.calibration import Calibration, load_calibration
from busarm.arm.config import ArmConfig, deck_mounted, load_arm_config
from busarm.base.base import Base
from busarm.base.config import ChassisConfig, load_chassis_config
from busarm.bus.board_bus import BoardServoBus
from busarm.bus.ports import SerialPort
from busarm.bus.servo_port import ServoPort
from busarm.bus.transport import Transport
from busarm.errors import ConfigError
from busarm.lidar.scan import LidarSource
from busarm.lidar.sources import open_lidar_source
from busarm.progress import Progress
from busarm.robot.calibration_store import (
    CalibrationStore,
    CameraCalibration,
    MadeFor,
    StaleCalibration,
)
from busarm.robot.description import ArmSpec, BaseSpec, LidarSpec, RobotConfig
from busarm.robot.lidar_port import open_lidar_port
from busarm.robot.twin_calibration import calibrate_twin_camera
from busarm.twin.camera import TwinCamera
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin
from busarm.units import listing
from busarm.vision.calibration import load_hand_eye, load_intrinsics
from busarm.vision.camera import CameraSource, open_camera

__all__ = [
    "NEEDS",
    "Parts",
    "arm_files",
    "check_needs",
    "closed_on_error",
    "given_calibration",
    "kept",
    "open_parts",
]

_T = TypeVar("_T")

NEEDS = {"camera": "the wrist camera (--camera)",
         "camera_calibration": "the camera's calibration files (--intrinsics from busarm "
                               "camera calibrate, --hand-eye from busarm camera handeye)",
         "bins": "where the bins are (--bins COLOUR=X,Y;...)"}


@dataclass(frozen=True)
class Parts:
    """What ``open_parts`` opened, for the Robot to hold."""

    arm: Arm
    camera: CameraSource | None
    calibration: CameraCalibration | None
    twin: Twin | None
    base: Base | None
    lidar: LidarSource | None


def open_parts(config: RobotConfig, needs: Collection[str], progress: Progress) -> Parts:
    """Open what ``config`` describes (not a robot served on Zenoh: busarm.robot.remote)."""
    world = config.world
    cam = config.camera
    store = cam.kept_in(world)
    world.check()  # a missing adapter first: it is what to fix first
    check_needs(needs, config, store)
    given, cal = arm_files(config.arm)
    transport, twin, arm_config = _arm_transport(config, given)
    with closed_on_error([transport]) as opened:  # a failure: nothing sent, just close
        bus = config.arm.open_servos(config.world, transport)
        arm = Arm(bus, arm_config, cal)
        source = kept(opened, _open_camera(cam.source, twin))
        made_for = None if store is None or source is None else MadeFor.for_camera(
            store.robot, source, arm_config, twin)
        calibration = _camera_calibration(twin, cam.intrinsics, cam.hand_eye, cam.calibrate,
                                          cam.folder, progress, store, made_for)
        base = kept(opened, _open_base(bus, twin, config.base))
        lidar = kept(opened, _open_lidar(config.lidar, twin))
        return Parts(arm, source, calibration, twin, base, lidar)


def arm_files(arm: ArmSpec) -> tuple[ArmConfig | None, Calibration | None]:
    """The arm config and calibration given, loaded from their files if named."""
    given = (arm.config if isinstance(arm.config, ArmConfig | None)
             else load_arm_config(arm.config))
    cal = (arm.calibration if isinstance(arm.calibration, Calibration | None)
           else load_calibration(arm.calibration))
    return given, cal


def _arm_transport(config: RobotConfig, given: ArmConfig | None,
                   ) -> tuple[Transport, Twin | None, ArmConfig]:
    """The arm's transport, the twin when it is one, and the arm's config: the twin's
    (its own config, if the description gave none), else the one given or the default."""
    world, baudrate = config.world, config.arm.line.baudrate
    if isinstance(world, TwinSpec):
        transport = world.open(baudrate, config=given)
        return transport, transport.twin, transport.twin.config
    arm_config = given or load_arm_config()
    if config.base is not None:  # the arm stands on the mobile base's deck
        arm_config = deck_mounted(arm_config)
    return world.open(baudrate), None, arm_config


@contextmanager
def closed_on_error(opened: list[Any]) -> Iterator[list[Any]]:
    """``opened``, whose things (each with ``close()``) are closed, newest first, if the
    block fails."""
    try:
        yield opened
    except BaseException:
        for thing in reversed(opened):
            thing.close()
        raise


def kept(opened: list[Any], thing: _T) -> _T:
    """``thing``, added to ``opened`` unless it is None."""
    if thing is not None:
        opened.append(thing)
    return thing


def _open_lidar(lidar: LidarSpec | None, twin: Twin | None) -> LidarSource | None:
    """The Lidar described (by its model, busarm.lidar.sources), else an arena twin's
    own, else None."""
    if lidar is None:
        return (open_lidar_source("twin", twin) if twin is not None and twin.arena is not None
                else None)
    port = lidar.port
    if isinstance(port, TwinSpec):  # a twin made for the Lidar alone
        return open_lidar_port(port)
    where = port.device if isinstance(port, SerialPort) else port.open()
    return open_lidar_source(lidar.model, where)


def _open_base(bus: ServoPort, twin: Twin | None, base: BaseSpec | None) -> Base | None:
    """The base on a controller board's wheels: the one described, or a twin's chassis
    behind its board; None without one (a twin's arena without a board stands still)."""
    chassis: ChassisConfig | None = None
    if base is not None:
        chassis = (base.chassis if isinstance(base.chassis, ChassisConfig)
                   else load_chassis_config(base.chassis))
    elif twin is not None and twin.mobile is not None and isinstance(bus, BoardServoBus):
        chassis = twin.chassis
    if chassis is None:
        return None
    if not isinstance(bus, BoardServoBus):  # RobotConfig refuses it; a guard all the same
        raise ConfigError(f"a base drives its wheels through the controller board, not "
                          f"{bus.name}")
    return Base(bus.link, chassis)


def check_needs(needs: Collection[str], config: RobotConfig,
                store: CalibrationStore | None) -> None:
    """What the job cannot do without is there (or, on a twin, will be made)."""
    unknown = set(needs) - set(NEEDS)
    if unknown:
        raise ConfigError(f"needs {listing(sorted(unknown))}; allowed: {listing(NEEDS)}")
    cam = config.camera
    kept_there = store is not None and store.has_calibration()
    if config.is_twin:  # the twin has them all (its camera, calibration made in it, trays)
        if ("camera_calibration" in needs and not cam.calibrate and cam.intrinsics is None
                and not kept_there):
            raise ConfigError(store.missing() if store is not None else
                              "this job needs the camera's calibration: " + NEEDS[
                                  "camera_calibration"])
        return
    given = {"camera": cam.source is not None, "bins": config.bins is not None,
             "camera_calibration": (cam.intrinsics is not None and cam.hand_eye is not None)
             or kept_there}
    missing = [(f"the camera's calibration: {store.missing()}"
                if n == "camera_calibration" and store is not None else NEEDS[n])
               for n in NEEDS if n in needs and not given[n]]
    if missing:
        raise ConfigError(f"on {config.world.name} this job needs " + "; ".join(missing)
                          + " (only a twin, --port twin, has them all by default)")


def _open_camera(camera: str | None, twin: Twin | None) -> CameraSource | None:
    if twin is not None and camera in (None, "twin"):
        return TwinCamera(twin)
    return open_camera(camera) if camera is not None else None


def given_calibration(intrinsics: Path, hand_eye: Path | None) -> CameraCalibration:
    """The camera calibration in the files given (both needed off a twin)."""
    if hand_eye is None:
        raise ConfigError("give both camera calibration files: --intrinsics and --hand-eye")
    intr = load_intrinsics(intrinsics)
    return CameraCalibration(intr, load_hand_eye(hand_eye, intrinsics=intr),
                             f"{intrinsics}, {hand_eye}")


def _camera_calibration(twin: Twin | None, intrinsics: Path | None, hand_eye: Path | None,
                        calibrate: bool, out_dir: Path | None, progress: Progress,
                        store: CalibrationStore | None = None,
                        made_for: MadeFor | None = None) -> CameraCalibration | None:
    """The files given; else the calibration kept in ``store`` for ``made_for`` (stale:
    refused, or on a twin made again); else on a twin made there (into ``store`` if
    given); None on hardware without any."""
    if intrinsics is not None and hand_eye is not None:
        return given_calibration(intrinsics, hand_eye)
    making = twin is not None and calibrate
    if store is not None and made_for is not None:
        try:
            kept_cal = store.load(made_for)
        except StaleCalibration as exc:
            if not making:
                raise
            progress(f"{exc.why}: calibrating the twin's camera again")
        else:
            if kept_cal is not None:
                again = "; delete the folder to calibrate again" if making else ""
                progress(f"using the camera calibration kept in {store.folder}/ (made "
                         f"{kept_cal[2]}{again})")
                return CameraCalibration(kept_cal[0], kept_cal[1], f"kept in {store.folder}/")
        out_dir = store.make_folder() if making else out_dir
    if twin is None or not calibrate:
        return None
    progress("calibrating the twin's camera (" + ("hand-eye" if intrinsics else
                                                  "intrinsics, then hand-eye") + ")...")
    with tempfile.TemporaryDirectory(prefix="busarm-twin-calibration-") as tmp:
        run = calibrate_twin_camera(twin, out_dir or Path(tmp), intrinsics=intrinsics,
                                    progress=progress, made_for=made_for)
        intr = load_intrinsics(run.intrinsics_path)
        he = load_hand_eye(run.hand_eye_path, intrinsics=intr)
    kept_in = f", kept in {store.folder}/" if store is not None else ""
    return CameraCalibration(intr, he, "calibrated in the twin" + kept_in, run)
