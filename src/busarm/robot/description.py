"""A robot described once, typed and checked: ``RobotConfig``, opened by ``Robot.open``.

A ``RobotConfig`` says where the robot is (``world``: its hardware port, the simulator,
the twin with its table or arena, a robot served on another computer), its arm (config,
joint calibration, how its servo line is driven), its base and Lidar (or none), its wrist
camera and that camera's calibration, and where the bins are. Each part checks its own
values when made; the whole checks how they fit. It comes from Python, from a robot file
(``busarm.robot.robot_file``: ``busarm robot init`` writes one, ``--robot FILE`` reads it)
or from the command line's ``--port`` (``RobotConfig.from_port``, read once by
``busarm.robot.port_url``); nothing below reads a port string again.

    RobotConfig()                                        # the twin: an arm on a table
    RobotConfig(TwinSpec(family="arena", seed=3, controller=BoardSettings()))
    RobotConfig(SerialPort("/dev/ttyUSB0"), camera=CameraSpec("/dev/video0", ...))
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from busarm.arm.calibration import Calibration
from busarm.arm.config import ArmConfig
from busarm.base.config import ChassisConfig
from busarm.bus.driver import DEFAULT_RETRIES, DEFAULT_TIMEOUT_MARGIN_S, EchoMode
from busarm.bus.ports import PortSpec, SerialPort
from busarm.bus.transport import DEFAULT_BAUDRATE, Transport, check_baudrate
from busarm.bus.zenoh_link import ZenohPort
from busarm.errors import ConfigError
from busarm.sim.spec import SimLidarSpec, check_flag
from busarm.twin.spec import TwinSpec
from busarm.units import check_int_range, check_range, short_repr

if TYPE_CHECKING:
    from busarm.bus.servo_port import ServoPort
    from busarm.robot.calibration_store import CalibrationStore

__all__ = [
    "ArmSpec",
    "BaseSpec",
    "Bins",
    "CameraSpec",
    "LidarPort",
    "LidarSpec",
    "RobotConfig",
    "ServoLine",
]

Bins = dict[str, tuple[float, float]]
"""Where each colour's bin is on the table: colour -> (x_mm, y_mm) in the arm's frame."""

LidarPort = SerialPort | SimLidarSpec | TwinSpec
"""Where a Lidar is: its serial device, the simulated A1, or an arena twin's own."""

@dataclass(frozen=True)
class ServoLine:
    """How the arm's servo line is driven: its baud rate (a controller board's link is
    always 1,000,000), the adapter's echo (``auto`` finds out), retries of a failed
    exchange, and the margin added to every reply's deadline."""

    __repr__ = short_repr

    baudrate: int = DEFAULT_BAUDRATE
    echo: str = "auto"
    retries: int = DEFAULT_RETRIES
    timeout_margin_s: float = DEFAULT_TIMEOUT_MARGIN_S

    def __post_init__(self) -> None:
        check_baudrate(self.baudrate)
        if self.echo not in {m.value for m in EchoMode}:
            raise ConfigError(f"arm line: echo = {self.echo!r}; allowed: "
                              f"{', '.join(m.value for m in EchoMode)}")
        check_int_range("arm line: retries", self.retries, 0, 10)
        check_range("arm line: timeout_margin_s", self.timeout_margin_s, 0.0, 5.0, "s")

    def options(self) -> dict[str, Any]:
        """The servo driver's keywords."""
        return {"echo": self.echo, "retries": self.retries,
                "timeout_margin_s": self.timeout_margin_s}


@dataclass(frozen=True)
class ArmSpec:
    """The arm: its config (an ArmConfig, a shipped name or a file; default: the world's,
    else the JetAuto Pro), its joint calibration (or none), its servos' kind (``servo``:
    a name in busarm.bus.servo_port's table, ``lx``, ``board``, ``zenoh`` or a plugin's;
    default: the world's, ``board`` behind a controller board, ``zenoh`` for a robot
    served elsewhere, else ``lx``) and its servo line."""

    __repr__ = short_repr

    config: ArmConfig | str | Path | None = None
    calibration: Calibration | str | Path | None = None
    line: ServoLine = field(default_factory=ServoLine)
    servo: str | None = None

    def __post_init__(self) -> None:
        if self.servo is not None:
            from busarm.bus.servo_port import servo_port_kinds  # reads the entry points

            kinds = servo_port_kinds()
            if self.servo not in kinds:
                raise ConfigError(f"arm: servo = {self.servo!r}; allowed: "
                                  f"{', '.join(sorted(kinds))}")

    def servo_kind(self, world: PortSpec) -> str:
        """The servos' kind on ``world``: the one given, else the world's."""
        if self.servo is not None:
            return self.servo
        if isinstance(world, ZenohPort):
            return "zenoh"
        return "board" if world.through_board else "lx"

    def open_servos(self, world: PortSpec, transport: Transport) -> ServoPort:
        """The arm's servo port on ``world``'s open ``transport``: its kind's backend, the
        LX kinds given the line's settings (a plugin's kind takes its own defaults)."""
        from busarm.bus.servo_port import SERVO_PORTS, open_servo_port

        kind = self.servo_kind(world)
        return open_servo_port(kind, transport,
                               **(self.line.options() if kind in SERVO_PORTS else {}))


@dataclass(frozen=True)
class BaseSpec:
    """The mobile base on the controller board's wheels: its chassis config (a
    ChassisConfig, a shipped name or a file)."""

    __repr__ = short_repr

    chassis: ChassisConfig | str | Path = "jetauto"


@dataclass(frozen=True)
class LidarSpec:
    """The 2D Lidar: its model (busarm.lidar.sources' table: ``rplidar-a1`` or a
    plugin's) and where it is."""

    __repr__ = short_repr

    port: LidarPort
    model: str = "rplidar-a1"

    def __post_init__(self) -> None:
        from busarm.lidar.sources import lidar_models  # reads the entry points

        if not isinstance(self.port, SerialPort | SimLidarSpec | TwinSpec):
            raise ConfigError(f"lidar: port must be a SerialPort(\"/dev/ttyUSB1\"), a "
                              f"SimLidarSpec() or a TwinSpec with an arena, got {self.port!r} "
                              "(busarm.robot.port_url.parse_lidar_port reads a port string)")

        models = lidar_models()
        if self.model not in models or self.model == "twin":
            raise ConfigError(f"lidar: model = {self.model!r}; allowed: "
                              f"{', '.join(sorted(set(models) - {'twin'}))} (a twin's "
                              "own Lidar comes with its arena)")
        if isinstance(self.port, TwinSpec) and not self.port.mobile:
            raise ConfigError("lidar: this twin is an arm on a table, with no Lidar; give a "
                              "twin with an arena (family arena, or an arena file)")


@dataclass(frozen=True)
class CameraSpec:
    """The wrist camera and its calibration.

    ``source``: a camera (``/dev/video0``, an index, a stream URL; ``busarm.vision.camera``);
    on a twin, None or ``twin`` is the twin's own. ``intrinsics``/``hand_eye``: calibration
    files; else the calibration kept in ``store`` (refused if stale), by default (``keep``)
    the robot's own folder in the user's configuration, as the command line keeps it
    (busarm.robot.calibration_store); on a twin a missing one is made there (``calibrate``:
    a few seconds, once), into that store, or into ``folder`` if given instead."""

    __repr__ = short_repr

    source: str | None = None
    intrinsics: Path | None = None
    hand_eye: Path | None = None
    calibrate: bool = True
    store: CalibrationStore | None = None
    folder: Path | None = None
    keep: bool = True

    def __post_init__(self) -> None:
        check_flag("camera: calibrate", self.calibrate)
        check_flag("camera: keep", self.keep)
        if self.store is not None and self.folder is not None:
            raise ConfigError("camera: give a calibration store or a folder, not both")
        if self.hand_eye is not None and self.intrinsics is None:  # solved with those
            raise ConfigError("a hand-eye calibration needs the intrinsics it was made with: "
                              "give --intrinsics too")

    @property
    def files_given(self) -> bool:
        return self.intrinsics is not None or self.hand_eye is not None

    def kept_in(self, world: PortSpec) -> CalibrationStore | None:
        """Where the calibration is kept for the robot in ``world``: the store given, else
        (``keep``, no folder) the robot's own; None when files are given."""
        if self.files_given:
            return None
        if self.store is None and self.keep and self.folder is None:
            from busarm.robot.calibration_store import CalibrationStore

            return CalibrationStore.for_port(world)
        return self.store


@dataclass(frozen=True)
class RobotConfig:
    """The whole robot (see the module docstring); checked when made."""

    __repr__ = short_repr

    world: PortSpec = field(default_factory=TwinSpec)
    """Where the robot is: a ``SerialPort`` (hardware, alone or behind the controller
    board), a ``SimSpec``, a ``TwinSpec``, or a ``ZenohPort`` (served elsewhere)."""
    arm: ArmSpec = field(default_factory=ArmSpec)
    base: BaseSpec | None = None
    """The base, on hardware; a twin with an arena behind a board has its own."""
    lidar: LidarSpec | None = None
    """The Lidar, on hardware (or the simulated A1); a twin with an arena has its own."""
    camera: CameraSpec = field(default_factory=CameraSpec)
    bins: Mapping[str, tuple[float, float]] | None = None
    """Where the bins are (colour -> x_mm, y_mm); a twin's are its trays."""

    def __post_init__(self) -> None:
        if not isinstance(self.world, PortSpec):
            raise ConfigError(f"world: a SerialPort, SimSpec, TwinSpec or ZenohPort, got "
                              f"{self.world!r} (RobotConfig.from_port reads a port string)")
        for key, kind, value in (("arm", ArmSpec, self.arm), ("camera", CameraSpec, self.camera),
                                 ("base", BaseSpec | None, self.base),
                                 ("lidar", LidarSpec | None, self.lidar)):
            if not isinstance(value, kind):
                raise ConfigError(f"{key}: a {kind.__name__ if isinstance(kind, type) else kind}"
                                  f", got {value!r}" + (" (CameraSpec() is none given)"
                                                        if key == "camera" else ""))
        if self.bins is not None:
            _check_bins(self.bins)
        if self.camera.source == "twin" and not self.is_twin:
            raise ConfigError(f"camera: source 'twin' is a twin's own camera; {self.world.name} "
                              "is not a twin")
        if isinstance(self.world, ZenohPort) and (self.base or self.lidar):
            raise ConfigError(f"{self.world.name}: a robot served on Zenoh has what it has "
                              "where it is served (its base and Lidar are chosen there)")
        if self.base is not None and not self.world.through_board:
            raise ConfigError(f"a base drives its wheels through the controller board: open "
                              f"the robot on a board:// port (e.g. board:///dev/ttyACM0, or "
                              f"board://twin?family=arena), not {self.world.name}")
        if self.base is not None and isinstance(self.world, TwinSpec):
            raise ConfigError("a twin's base is its own: give its chassis in the twin "
                              "(chassis=) rather than a base")
        if (self.camera.intrinsics is not None and self.camera.hand_eye is None
                and not self.is_twin):
            raise ConfigError("give both camera calibration files: --intrinsics and "
                              "--hand-eye (only a twin can make the hand-eye one itself)")

    @property
    def is_twin(self) -> bool:
        """Whether the robot is a twin in this process."""
        return isinstance(self.world, TwinSpec)

    @classmethod
    def from_port(cls, port: str, **parts: Any) -> RobotConfig:
        """The robot on the command line's ``port`` string (``busarm.robot.port_url``),
        with ``parts`` (this class's other fields) beside it."""
        from busarm.robot.port_url import parse_port  # the one place a port is read

        return cls(parse_port(port), **parts)


def _check_bins(bins: Mapping[str, tuple[float, float]]) -> None:
    """Each bin a colour and a place on the table: (x_mm, y_mm), finite numbers."""
    if not isinstance(bins, Mapping):
        raise ConfigError(f"bins: colour -> (x_mm, y_mm), got {bins!r}")
    for colour, where in bins.items():
        if (not isinstance(colour, str) or not isinstance(where, tuple | list)
                or len(where) != 2):
            raise ConfigError(f"bins: {colour!r} -> {where!r}; each bin is a colour and "
                              "(x_mm, y_mm)")
        check_range(f"bins: {colour} x_mm", where[0], -1000.0, 1000.0, "mm")
        check_range(f"bins: {colour} y_mm", where[1], -1000.0, 1000.0, "mm")
