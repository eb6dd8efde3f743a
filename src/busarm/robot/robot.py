"""One robot: the arm, its base and Lidar, its cameras and their calibrations, the block
locator, and the twin when it is one. Every job, benchmark, test and interface builds on it.

``Robot.open(description)`` opens a ``RobotConfig`` (busarm.robot.description): where
the robot is (hardware, the simulator, a MuJoCo twin in this process on a simulated
clock: see ``busarm.clock``, or a robot served on another computer) and what it has. A
port string (``"twin"``, ``"/dev/ttyUSB0"``, ``"board://twin?family=arena"``) is read
into one by ``RobotConfig.from_port``. On a twin the wrist camera is the twin's, the bins
are its trays, and a camera calibration that was not given is made in the twin
(busarm.robot.opening); a calibration store (busarm.robot.calibration_store) keeps a
camera calibration between runs.

The twin is handed out (``robot.twin``) to whoever opened the robot: ground truth for
benchmarks and tests, the overview camera for reports. Nothing else reaches for it.

The mobile robot: ``robot.base`` (busarm.base.Base: the mecanum wheels on the controller
board) and ``robot.lidar`` (a ``LidarSource``), each None when the robot has none. A twin
with an arena behind a board (``board://twin?family=arena&seed=N``) has both.

A robot served on another computer (``ZenohPort``, ``zenoh://HOST``; ``busarm ros
bridge`` there): its servo bus, wrist camera, camera calibration and bins come over the
link (busarm.robot.remote); the arm only, for now (not a base or a Lidar).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from types import TracebackType

from busarm.arm.arm import Arm
from busarm.arm.config import ArmConfig
from busarm.base.base import Base
from busarm.bus.zenoh_link import ZenohPort
from busarm.clock import Clock
from busarm.errors import ConfigError
from busarm.fileio import robot_key
from busarm.lidar.scan import LidarSource
from busarm.lidar.tap import ScanTap
from busarm.perception.locate import NOT_BLOCK_COLORS, BlockLocator
from busarm.progress import Progress, quiet
from busarm.robot.calibration_store import CameraCalibration
from busarm.robot.description import Bins, RobotConfig
from busarm.robot.observation import Action, ActionLike, Observation, observe, send_action
from busarm.robot.opening import (
    NEEDS,
    arm_files,
    closed_on_error,
    given_calibration,
    open_parts,
)
from busarm.robot.sim_handle import SimHandle
from busarm.twin.camera import TwinCamera
from busarm.twin.twin import Twin
from busarm.units import listing
from busarm.vision.camera import CameraSource, open_camera
from busarm.vision.color import ColorDetector
from busarm.vision.color_thresholds import ColorThresholds, default_thresholds

__all__ = [
    "NEEDS",
    "Bins",
    "CameraCalibration",
    "Robot",
]


class Robot:
    """The whole robot; ``with Robot.open(description) as robot: ...``.

    Its parts: ``arm`` (busarm.arm.Arm), ``base`` (busarm.base.Base, or None),
    ``lidar`` (a LidarSource, or None), ``cameras`` (by role: ``wrist``, on a twin
    ``overview``; ``camera`` is the wrist's), ``camera_calibration``, ``bins``, ``clock``
    (the robot's time: wait on it), ``sim`` (what only a twin has, or None) and
    ``description`` (the RobotConfig it was opened from). One state, one action:
    ``get_observation()``, ``send_action(...)``.

    Leaving the ``with`` block by an exception (Ctrl+C included) stops the arm (MOVE_STOP
    to every servo: those with torque on hold) if anything was written to it since its
    last stop, and the wheels, then closes the cameras, the bus and the twin.
    """

    def __init__(self, arm: Arm, *, camera: CameraSource | None = None,
                 calibration: CameraCalibration | None = None, bins: Bins | None = None,
                 twin: Twin | None = None, base: Base | None = None,
                 lidar: LidarSource | None = None) -> None:
        self.arm = arm
        self.twin = twin
        """The twin, when the robot is one (its truth, for benchmarks and tests), else None."""
        self.sim = SimHandle(twin) if twin is not None else None
        """What only a simulated robot has (busarm.robot.sim_handle), else None."""
        self.base = base
        """The mobile base (on a controller board with a chassis config), else None."""
        self.lidar = lidar if lidar is None or isinstance(lidar, ScanTap) else ScanTap(lidar)
        """The 2D Lidar (given, or the twin's in an arena), else None: a ``ScanTap``,
        whose scans also reach its listeners (a dashboard's view, a recorder)."""
        self.port = arm.bus.name
        """What it was opened on, as a person names it."""
        self.description: RobotConfig | None = None
        """What it was opened from (``Robot.open``'s description), if opened that way."""
        self.cameras: dict[str, CameraSource] = {}
        """Every camera by role: ``wrist`` (the arm's), and on a twin ``overview``."""
        if camera is not None:
            self.cameras["wrist"] = camera
        if twin is not None:
            self.cameras["overview"] = TwinCamera(twin, view="overview")
        self.camera_calibration = calibration
        if calibration is not None and camera is not None:
            _check_size(camera, calibration)
        self.bins: Bins = dict(bins) if bins is not None else (
            {b.color: (b.x_mm, b.y_mm) for b in twin.scene.bins} if twin is not None else {})

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(cls, description: RobotConfig | str = "twin", *, needs: Collection[str] = (),
             progress: Progress = quiet) -> Robot:
        """Open the robot ``description`` says (a port string: ``RobotConfig.from_port``).

        ``needs``: what the job cannot do without (``camera``, ``camera_calibration``,
        ``bins``), checked before the port is opened (after a device is checked to exist).
        ``progress`` hears what takes long (a camera calibration made in the twin).
        Everything is checked before the arm moves; a failure closes what was opened.
        """
        config = (description if isinstance(description, RobotConfig)
                  else RobotConfig.from_port(description))
        if isinstance(config.world, ZenohPort):
            return cls._open_remote(config, needs)
        parts = open_parts(config, needs, progress)
        robot = cls(parts.arm, camera=parts.camera, calibration=parts.calibration,
                    bins=dict(config.bins) if config.bins is not None else None,
                    twin=parts.twin, base=parts.base, lidar=parts.lidar)
        robot.description = config
        robot.port = config.world.name
        return robot

    @classmethod
    def _open_remote(cls, config: RobotConfig, needs: Collection[str]) -> Robot:
        """The robot served on another computer (busarm.robot.remote): its config, camera,
        calibration and bins are the served robot's unless the description gives them."""
        from busarm.robot.remote import fetch_info, remote_parts

        world, cam = config.world, config.camera
        transport = world.open(config.arm.line.baudrate)
        with closed_on_error([transport]) as opened:
            parts = remote_parts(transport, fetch_info(transport),  # type: ignore[arg-type]
                                 camera=cam.source is None)
            if parts.camera is not None:
                opened.append(parts.camera)
            source = parts.camera if cam.source is None else open_camera(cam.source)
            if cam.source is not None:
                opened.append(source)
            calibration = parts.calibration
            if cam.intrinsics is not None:
                calibration = given_calibration(cam.intrinsics, cam.hand_eye)
            given, cal = arm_files(config.arm)
            missing = [what for what, have in (("camera", source is not None),
                                               ("camera_calibration", calibration is not None),
                                               ("bins", bool(config.bins or parts.bins)))
                       if what in needs and not have]
            if missing:
                raise ConfigError(f"the robot on {world.name} has no {listing(missing)}: give "
                                  "them here, or serve them with it")
            arm = Arm(config.arm.open_servos(world, transport), given or parts.config, cal)
            robot = cls(arm, camera=source, calibration=calibration,
                        bins=dict(config.bins) if config.bins else parts.bins)
            robot.description = config
            robot.port = world.name
            return robot

    # ------------------------------------------------------------------ parts

    @property
    def config(self) -> ArmConfig:
        return self.arm.config

    @property
    def clock(self) -> Clock:
        """The robot's time: simulated seconds on a twin, the wall clock on hardware."""
        return self.arm.clock

    @property
    def is_twin(self) -> bool:
        return self.twin is not None

    @property
    def robot_key(self) -> str:
        """The folder name of this robot's kept files (calibrations, saved poses)."""
        if self.description is not None:
            return self.description.world.robot_key
        return "twin" if self.twin is not None else robot_key(self.port)

    @property
    def camera(self) -> CameraSource:
        """The wrist camera; ConfigError if the robot was opened without one."""
        source = self.cameras.get("wrist")
        if source is None:
            raise ConfigError("this job needs the wrist camera: give one (--camera "
                              "/dev/video0); only a twin has one by default")
        return source

    @property
    def has_camera(self) -> bool:
        return "wrist" in self.cameras

    def require_camera_calibration(self) -> CameraCalibration:
        """The camera's calibration; ConfigError saying how to make it if there is none."""
        if self.camera_calibration is None:
            raise ConfigError("this job needs the camera's calibration: --intrinsics FILE "
                              "(busarm camera calibrate) and --hand-eye FILE (busarm camera "
                              "handeye), or a calibration_store that keeps them")
        return self.camera_calibration

    def locator(self, colors: Sequence[str] | None = None,
                thresholds: ColorThresholds | None = None,
                block_size_mm: float = 30.0) -> BlockLocator:
        """A block locator for this arm and camera: ``colors`` (default every block colour
        of ``thresholds``, default the shipped ones)."""
        cal = self.require_camera_calibration()
        table = thresholds if thresholds is not None else default_thresholds()
        names = list(colors) if colors is not None else [
            c for c in table.names if c not in NOT_BLOCK_COLORS]
        return BlockLocator(self.arm.kin, cal.intrinsics, cal.hand_eye,
                            ColorDetector(table, colors=names),
                            table_z_mm=self.config.table_z_mm, block_size_mm=block_size_mm)

    # ------------------------------------------------------------------ observe and act

    def get_observation(self, *, cameras: bool | str | Collection[str] = True,
                        scan: bool = True) -> Observation:
        """Every part read once, each stamped on the robot's clock (busarm.robot.observation):
        the arm's joints (rad) and gripper gap (mm), the base's odometry, the Lidar's
        newest revolution (``scan``), a frame from each camera: all (True), none (False: a
        render costs milliseconds), or the roles named."""
        return observe(self, cameras=cameras, scan=scan)

    def send_action(self, action: ActionLike) -> Action:
        """Joint targets (rad), a gripper gap (mm), a base twist (m/s, rad/s): an
        ``Action`` or its flat form (``Action.as_dict``'s keys). Every value is checked
        before anything is sent (ConfigError naming the key, value and range, and nothing
        moves); returns what was sent. Waits for nothing."""
        return send_action(self, action)

    def move_to_pose(self, name: str, **kwargs: float) -> float:
        """The arm to one of its config's named poses (``home``, ``look``...);
        ``Arm.move_to_pose``."""
        return self.arm.move_to_pose(name, **kwargs)

    # ------------------------------------------------------------------ lifecycle

    def close(self) -> None:
        """Close the arm's bus (which closes a twin) and the cameras."""
        self.__exit__(None, None, None)

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if self.base is not None:
                self.base.close()  # the wheels stop, whatever happens next
            self.arm.__exit__(exc_type, exc, tb)  # first stop and hold on an exception
        finally:
            for source in self.cameras.values():
                source.close()
            if self.lidar is not None:
                self.lidar.close()

    def __repr__(self) -> str:
        where = "twin" if self.twin is not None else self.arm.bus.name
        parts = "".join(f", {name}" for name, part in (("base", self.base),
                                                       ("lidar", self.lidar)) if part)
        return (f"Robot({self.config.name!r} on {where}, cameras={sorted(self.cameras)}"
                f"{parts})")


def _check_size(camera: CameraSource, calibration: CameraCalibration) -> None:
    i = calibration.intrinsics
    if (camera.width_px, camera.height_px) != (i.width_px, i.height_px):
        raise ConfigError(f"the camera calibration ({calibration.source}) is for "
                          f"{i.width_px}x{i.height_px} pictures; {camera.name} gives "
                          f"{camera.width_px}x{camera.height_px}")
