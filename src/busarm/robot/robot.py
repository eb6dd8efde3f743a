"""One robot: the arm, its cameras, their calibrations, the block locator, and the twin
when it is one. Every job, benchmark, test and interface builds on it.

``Robot.open(port)`` makes the one twin-or-hardware decision: ``twin`` or
``twin://?...`` is a MuJoCo twin in this process (on a simulated clock: see
``busarm.clock``), anything else a real bus (``/dev/ttyUSB0``, a pyserial URL, the
``sim`` servo simulator, the pty of ``busarm twin serve``). On a twin the wrist camera
is the twin's, the bins are its trays, and a camera calibration that was not given is
made by our own flows in the twin (``calibrate-if-missing``); on hardware the camera,
its calibration files and the bins come from the user. A ``calibration_store`` (the
robot's folder in the user's configuration directory, busarm.robot.calibration_store)
keeps a camera calibration between runs: used when no files are given, refused when
stale, and on a twin made there when missing or stale.

The twin is handed out (``robot.twin``) to whoever opened the robot: ground truth for
benchmarks and tests, the overview camera for reports. Nothing else reaches for it.

The mobile robot: ``robot.base`` (busarm.base.Base: the mecanum wheels on the controller
board, so only on a ``board://`` port) and ``robot.lidar`` (a ``LidarSource``), each None
when the robot has none. A twin with an arena (``board://twin?family=arena&seed=N``) has
both; on hardware the base comes with a chassis config and the Lidar with its port.

``zenoh://HOST`` is a robot served on another computer (``busarm ros bridge`` there):
its servo bus, wrist camera, camera calibration and bins come over the link
(busarm.robot.remote); the arm only, for now (not a base or a Lidar).
"""

from __future__ import annotations

import tempfile
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any, TypeVar
from urllib.parse import parse_qs, urlsplit

from busarm.arm.arm import Arm
from busarm.arm.calibration import Calibration, load_calibration
from busarm.arm.config import ArmConfig, deck_mounted, load_arm_config
from busarm.base.base import Base
from busarm.base.config import ChassisConfig, load_chassis_config
from busarm.bus.board_bus import BoardServoBus
from busarm.bus.driver import ServoBus, servo_bus_on
from busarm.bus.transport import (
    DEFAULT_BAUDRATE,
    Transport,
    board_target,
    check_device,
    open_transport,
)
from busarm.clock import Clock
from busarm.errors import ConfigError
from busarm.lidar.scan import LidarSource
from busarm.progress import Progress, quiet
from busarm.robot.calibration_store import CalibrationStore, MadeFor, StaleCalibration
from busarm.robot.lidar_port import open_any_lidar, twin_lidar
from busarm.robot.locate import NOT_BLOCK_COLORS, BlockLocator
from busarm.robot.twin_calibration import TwinCalibration, calibrate_twin_camera
from busarm.twin.arena import Arena
from busarm.twin.camera import TwinCamera
from busarm.twin.scene import Scene
from busarm.twin.transport import TwinTransport, is_twin_url, twin_behind_board, twin_from_url
from busarm.twin.twin import Twin
from busarm.units import listing
from busarm.vision.calibration import (
    CameraIntrinsics,
    HandEyeResult,
    load_hand_eye,
    load_intrinsics,
)
from busarm.vision.camera import CameraSource, open_camera
from busarm.vision.color import ColorDetector
from busarm.vision.color_thresholds import ColorThresholds, default_thresholds

__all__ = [
    "NEEDS",
    "ZENOH_PREFIX",
    "Bins",
    "CameraCalibration",
    "Robot",
    "with_board",
]


Bins = dict[str, tuple[float, float]]
_T = TypeVar("_T")
ZENOH_PREFIX = "zenoh://"


@dataclass(frozen=True)
class CameraCalibration:
    """The wrist camera's lens (intrinsics) and where it sits on the arm (hand-eye)."""

    intrinsics: CameraIntrinsics
    hand_eye: HandEyeResult
    source: str
    """Where it came from: the files given, "kept in FOLDER", or "calibrated in the twin"."""
    twin_run: TwinCalibration | None = None
    """When it was made in the twin: what that found (errors against the twin's truth)."""


def with_board(port: str, board: str) -> str:
    """The twin URL ``port`` with calibration ``board`` on its table (unless its scene is
    a file, or it already has that board)."""
    given = parse_qs(urlsplit(port).query).get("board") if "://" in port else None
    if given and given[-1] != board:
        raise ConfigError(f"{port}: this step looks for a {board} board, but the twin's "
                          f"table has a {given[-1]} board (board={board})")
    if given or "scene=" in port:
        return port
    if port == "twin":
        return f"twin://?board={board}"
    return port + ("&" if "?" in port else "?") + f"board={board}"


class Robot:
    """The arm and what it sees with; ``with Robot.open(port) as robot: ...``.

    Leaving the ``with`` block by an exception (Ctrl+C included) stops the arm (MOVE_STOP
    to every servo: those with torque on hold) if anything was written to it since its
    last stop, then closes the cameras, the bus and the twin.
    """

    def __init__(self, arm: Arm, *, camera: CameraSource | None = None,
                 calibration: CameraCalibration | None = None, bins: Bins | None = None,
                 twin: Twin | None = None, base: Base | None = None,
                 lidar: LidarSource | None = None) -> None:
        self.arm = arm
        self.twin = twin
        self.base = base
        """The mobile base (on a controller board with a chassis config), else None."""
        self.lidar = lidar
        """The 2D Lidar (given, or the twin's in an arena), else None."""
        self.port = arm.bus.transport.name
        """What it was opened on (``Robot.open``'s port)."""
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
    def open(cls, port: str = "twin", *, camera: str | None = None,
             config: ArmConfig | str | Path | None = None,
             arm_calibration: Calibration | str | Path | None = None,
             intrinsics: Path | None = None, hand_eye: Path | None = None,
             bins: Bins | None = None, calibrate: bool = True,
             calibration_dir: Path | None = None,
             calibration_store: CalibrationStore | None = None, board: str | None = None,
             scene: Scene | None = None, needs: Collection[str] = (),
             baudrate: int = DEFAULT_BAUDRATE, progress: Progress = quiet,
             chassis: ChassisConfig | str | Path | None = None, lidar: str | None = None,
             arena: Arena | None = None, **bus_options: Any) -> Robot:
        """Open the robot on ``port`` (see the module docstring).

        ``camera``: a camera source (default on a twin: its wrist camera; ``twin`` there
        means the same). ``intrinsics``/``hand_eye``: calibration files; on a twin,
        missing ones are made (``calibrate``), their files kept in ``calibration_dir``
        if given. ``calibration_store``: when neither file is given, the calibration
        kept there (refused if stale; on a twin made into it when missing or stale).
        ``board``: on a twin, lay this calibration board on its table;
        ``scene``: what stands on a twin's table (else the URL's); ``arena``: a twin's
        arena, the mobile robot's world (else the URL's). ``needs``: what the job
        cannot do without (``camera``, ``camera_calibration``, ``bins``), checked before
        the port is opened (after a device path is checked to exist). ``bus_options`` go
        to ``ServoBus`` (echo, retries, timeout_margin_s). Everything is checked before the
        arm moves; a failure closes what was opened.

        The mobile parts: ``chassis`` (a config, its name or file) gives the robot a
        ``base`` on a controller board's port; a twin with an arena has one by itself on
        ``board://twin?family=arena...``. ``lidar``: the Lidar's port; a twin with an arena
        has its own.
        """
        if port.startswith(ZENOH_PREFIX):
            return cls._open_remote(port, camera=camera, config=config,
                                    arm_calibration=arm_calibration, intrinsics=intrinsics,
                                    hand_eye=hand_eye, bins=bins, needs=needs,
                                    baudrate=baudrate, scene=scene, arena=arena,
                                    chassis=chassis, lidar=lidar, **bus_options)
        behind = board_target(port)  # the twin behind a simulated controller board
        twin_port = behind if behind is not None and is_twin_url(behind) else port
        on_twin = is_twin_url(twin_port)
        store = _checked_store(port, on_twin, scene, arena, calibration_store,
                               calibration_dir, intrinsics, hand_eye)
        _check_needs(needs, port, on_twin, camera, intrinsics, hand_eye, bins, store,
                     calibrate)
        given, cal = _arm_files(config, arm_calibration)
        transport, twin, cfg = _arm_transport(port, twin_port, behind, board, baudrate, given,
                                              scene, arena, chassis)
        with _closed_on_error([transport]) as opened:  # a failure: nothing sent, just close
            bus = servo_bus_on(transport, **bus_options)
            arm = Arm(bus, cfg, cal)
            source = _kept(opened, _open_camera(camera, twin))
            made_for = None if store is None or source is None else MadeFor.for_camera(
                store.robot, source, cfg, twin)
            calibration = _camera_calibration(twin, intrinsics, hand_eye, calibrate,
                                              calibration_dir, progress, store, made_for)
            base = _kept(opened, _open_base(bus, twin, chassis))
            lidar_source = _kept(opened, _open_lidar(lidar, twin))
            robot = cls(arm, camera=source, calibration=calibration, bins=bins, twin=twin,
                        base=base, lidar=lidar_source)
            robot.port = port
            return robot

    @classmethod
    def _open_remote(cls, port: str, *, camera: str | None,
                     config: ArmConfig | str | Path | None,
                     arm_calibration: Calibration | str | Path | None,
                     intrinsics: Path | None, hand_eye: Path | None, bins: Bins | None,
                     needs: Collection[str], baudrate: int, scene: Scene | None,
                     arena: Arena | None, chassis: ChassisConfig | str | Path | None,
                     lidar: str | None, **bus_options: Any) -> Robot:
        """The robot served on another computer (busarm.robot.remote): its config, camera,
        calibration and bins are the served robot's unless given here (not its world or
        mobile parts)."""
        if scene is not None or arena is not None or chassis is not None or lidar:
            raise ConfigError(f"{port}: a robot served on Zenoh has what it has where it "
                              "is served (its scene, arena and parts are chosen there)")
        from busarm.robot.remote import fetch_info, remote_parts

        transport = open_transport(port, baudrate=baudrate)
        with _closed_on_error([transport]) as opened:
            parts = remote_parts(transport, fetch_info(transport),  # type: ignore[arg-type]
                                 camera=camera is None)
            if parts.camera is not None:
                opened.append(parts.camera)
            source = parts.camera if camera is None else open_camera(camera)
            if camera is not None:
                opened.append(source)
            calibration = (parts.calibration if intrinsics is None else _camera_calibration(
                None, intrinsics, hand_eye, False, None, quiet))
            given, cal = _arm_files(config, arm_calibration)
            _check_needs(needs, port, True, camera, None, None, None, None, True)  # known
            missing = [what for what, have in (("camera", source is not None),
                                               ("camera_calibration", calibration is not None),
                                               ("bins", bool(bins or parts.bins)))
                       if what in needs and not have]
            if missing:
                raise ConfigError(f"the robot on {port} has no {listing(missing)}: give them "
                                  "here, or serve them with it")
            arm = Arm(servo_bus_on(transport, **bus_options), given or parts.config, cal)
            robot = cls(arm, camera=source, calibration=calibration, bins=bins or parts.bins)
            robot.port = port
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
        where = "twin" if self.twin is not None else self.arm.bus.transport.name
        parts = "".join(f", {name}" for name, part in (("base", self.base),
                                                       ("lidar", self.lidar)) if part)
        return (f"Robot({self.config.name!r} on {where}, cameras={sorted(self.cameras)}"
                f"{parts})")


NEEDS = {"camera": "the wrist camera (--camera)",
         "camera_calibration": "the camera's calibration files (--intrinsics from busarm "
                               "camera calibrate, --hand-eye from busarm camera handeye)",
         "bins": "where the bins are (--bins COLOUR=X,Y;...)"}


def _checked_store(port: str, on_twin: bool, scene: Scene | None, arena: Arena | None,
                   calibration_store: CalibrationStore | None, calibration_dir: Path | None,
                   intrinsics: Path | None, hand_eye: Path | None) -> CalibrationStore | None:
    """The calibration store to use (none when calibration files are given), after the
    checks that come before anything is opened."""
    if (scene is not None or arena is not None) and not on_twin:
        raise ConfigError(f"{'a scene' if scene is not None else 'an arena'} is for the "
                          f"twin; {port} is not one (use --port twin, or no --port)")
    if calibration_store is not None and calibration_dir is not None:
        raise ConfigError("give a calibration_store or a calibration_dir, not both")
    if not on_twin:  # a missing adapter first: it is what to fix first
        check_device(port)
    return calibration_store if intrinsics is None and hand_eye is None else None


def _arm_files(config: ArmConfig | str | Path | None,
               arm_calibration: Calibration | str | Path | None,
               ) -> tuple[ArmConfig | None, Calibration | None]:
    """The arm config and calibration given, loaded from their files if named."""
    given = config if isinstance(config, ArmConfig | None) else load_arm_config(config)
    cal = (arm_calibration if isinstance(arm_calibration, Calibration | None)
           else load_calibration(arm_calibration))
    return given, cal


def _arm_transport(port: str, twin_port: str, behind: str | None, board: str | None,
                   baudrate: int, given: ArmConfig | None, scene: Scene | None,
                   arena: Arena | None, chassis: ChassisConfig | str | Path | None,
                   ) -> tuple[Transport, Twin | None, ArmConfig]:
    """The arm's transport, the twin when it is one, and the arm's config: the twin's (its
    URL's config=, if the program gave none), else the one given or the default."""
    if not is_twin_url(twin_port):
        cfg = given or load_arm_config()
        if chassis is not None:  # the arm stands on the mobile base's deck
            cfg = deck_mounted(cfg)
        return open_transport(port, baudrate=baudrate), None, cfg
    url = with_board(twin_port, board) if board else twin_port
    transport: Transport
    if twin_port is behind:
        transport = twin_behind_board(url, baudrate, config=given, scene=scene, arena=arena)
        twin = transport.twin
    else:
        twin = twin_from_url(url, baudrate, config=given, scene=scene, arena=arena)
        transport = TwinTransport(twin)
    return transport, twin, twin.config


@contextmanager
def _closed_on_error(opened: list[Any]) -> Iterator[list[Any]]:
    """``opened``, whose things (each with ``close()``) are closed, newest first, if the
    block fails."""
    try:
        yield opened
    except BaseException:
        for thing in reversed(opened):
            thing.close()
        raise


def _kept(opened: list[Any], thing: _T) -> _T:
    """``thing``, added to ``opened`` unless it is None."""
    if thing is not None:
        opened.append(thing)
    return thing


def _open_lidar(lidar: str | None, twin: Twin | None) -> LidarSource | None:
    """The Lidar on the port given, else an arena twin's own, else None."""
    return (twin_lidar(twin) if lidar is None and twin is not None and twin.arena is not None
            else open_any_lidar(lidar) if lidar is not None else None)


def _open_base(bus: ServoBus, twin: Twin | None,
               chassis: ChassisConfig | str | Path | None) -> Base | None:
    """The base on a controller board's wheels: with a chassis config given, or the
    twin's chassis; None without one. A chassis needs a board (the wheels are on it)."""
    config = (chassis if isinstance(chassis, ChassisConfig | None)
              else load_chassis_config(chassis))
    if config is None and twin is not None and twin.mobile is not None and isinstance(
            bus, BoardServoBus):
        config = twin.chassis  # on twin://?family=arena (no board) the base stands still
    if config is None:
        return None
    if not isinstance(bus, BoardServoBus):
        raise ConfigError(f"a base drives its wheels through the controller board: open "
                          f"the robot on a board:// port (e.g. board:///dev/ttyACM0, or "
                          f"board://twin?family=arena), not {bus.transport.name}")
    return Base(bus.link, config)


def _check_needs(needs: Collection[str], port: str, on_twin: bool, camera: str | None,
                 intrinsics: Path | None, hand_eye: Path | None, bins: Bins | None,
                 store: CalibrationStore | None, calibrate: bool) -> None:
    unknown = set(needs) - set(NEEDS)
    if unknown:
        raise ConfigError(f"needs {listing(sorted(unknown))}; allowed: {listing(NEEDS)}")
    if hand_eye is not None and intrinsics is None:  # it was solved with those intrinsics
        raise ConfigError("a hand-eye calibration needs the intrinsics it was made with: "
                          "give --intrinsics too")
    if intrinsics is not None and hand_eye is None and not on_twin:
        raise ConfigError("give both camera calibration files: --intrinsics and --hand-eye "
                          "(only a twin can make the hand-eye one itself)")
    kept = store is not None and store.has_calibration()
    if on_twin:  # the twin has them all (its camera, calibration made in it, its trays)
        if "camera_calibration" in needs and not calibrate and intrinsics is None and not kept:
            raise ConfigError(store.missing() if store is not None else
                              "this job needs the camera's calibration: " + NEEDS[
                                  "camera_calibration"])
        return
    given = {"camera": camera is not None, "bins": bins is not None,
             "camera_calibration": (intrinsics is not None and hand_eye is not None) or kept}
    missing = [(f"the camera's calibration: {store.missing()}"
                if n == "camera_calibration" and store is not None else NEEDS[n])
               for n in NEEDS if n in needs and not given[n]]
    if missing:
        raise ConfigError(f"on {port} this job needs " + "; ".join(missing)
                          + " (only a twin, --port twin, has them all by default)")


def _open_camera(camera: str | None, twin: Twin | None) -> CameraSource | None:
    if twin is not None and camera in (None, "twin"):
        return TwinCamera(twin)
    return open_camera(camera) if camera is not None else None


def _check_size(camera: CameraSource, calibration: CameraCalibration) -> None:
    i = calibration.intrinsics
    if (camera.width_px, camera.height_px) != (i.width_px, i.height_px):
        raise ConfigError(f"the camera calibration ({calibration.source}) is for "
                          f"{i.width_px}x{i.height_px} pictures; {camera.name} gives "
                          f"{camera.width_px}x{camera.height_px}")


def _camera_calibration(twin: Twin | None, intrinsics: Path | None, hand_eye: Path | None,
                        calibrate: bool, out_dir: Path | None, progress: Progress,
                        store: CalibrationStore | None = None,
                        made_for: MadeFor | None = None) -> CameraCalibration | None:
    """The files given; else the calibration kept in ``store`` for ``made_for`` (stale:
    refused, or on a twin made again); else on a twin made there (into ``store`` if
    given); None on hardware without any."""
    if intrinsics is not None and hand_eye is not None:
        intr = load_intrinsics(intrinsics)
        return CameraCalibration(intr, load_hand_eye(hand_eye, intrinsics=intr),
                                 f"{intrinsics}, {hand_eye}")
    making = twin is not None and calibrate
    if store is not None and made_for is not None:
        try:
            kept = store.load(made_for)
        except StaleCalibration as exc:
            if not making:
                raise
            progress(f"{exc.why}: calibrating the twin's camera again")
        else:
            if kept is not None:
                again = "; delete the folder to calibrate again" if making else ""
                progress(f"using the camera calibration kept in {store.folder}/ (made "
                         f"{kept[2]}{again})")
                return CameraCalibration(kept[0], kept[1], f"kept in {store.folder}/")
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
