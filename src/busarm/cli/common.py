"""What every command shares: the global settings, consoles, the arm and robot options,
the scene options. Command modules import shared helpers from here only: the ones that
live in other modules (parameter types, servo tables, what the stop says...) are
re-exported here.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable, Collection, Iterable, Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

import click
from rich.console import Console

from busarm.arm.arm import Arm
from busarm.arm.calibration import Calibration, load_calibration
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bus.board import BoardLink
from busarm.bus.driver import DEFAULT_RETRIES, DEFAULT_TIMEOUT_MARGIN_S, ServoBus
from busarm.bus.lx_port import LxServoPort
from busarm.bus.ports import PortSpec, open_transport
from busarm.bus.transport import DEFAULT_BAUDRATE
from busarm.cli.arm_inputs import (
    check_gap_mm,
    gap_report,
    joints_in,
    joints_to_move,
    parse_gripper_target,
    target_in,
)
from busarm.cli.exits import JobNotDone
from busarm.cli.help_style import metavar_from_help, unit_metavar
from busarm.cli.job_view import (
    explore_hook,
    line_follow_hook,
    navigation_hook,
    need_view,
    say_view_errors,
    start_view,
    view_options,
    watching,
)
from busarm.cli.live_robot import open_live_robot
from busarm.cli.mobile_common import (
    arena_from_spec,
    keeping_what_was_done,
    mobile_options,
    open_mobile_robot,
    stop_wheels,
)
from busarm.cli.param_types import (
    ANGLE,
    ID_LIST,
    MOVE_TIME,
    NUMBER_ARGS,
    POSE,
    SERVO_ID,
    SPEED,
    AngleType,
    CheckedType,
    IdListType,
    PoseType,
    RangeType,
    ServoIdType,
    angle_list,
    parse_float_list,
    parse_int,
    parse_pose,
)
from busarm.cli.robot_options import (
    camera_from_text,
    describe_robot,
    from_robot_file,
    with_realtime,
)
from busarm.cli.servo_tables import (
    BAD_REPLY,
    NO_REPLY,
    NOT_HERE,
    alarm_names,
    fmt,
    scan_progress,
    scan_report,
    scan_with_progress,
    state_row,
    state_table,
    try_read,
)
from busarm.cli.sessions import Session, announced, find_session, running_sessions
from busarm.cli.stopping import (
    Terminated,
    add_detail,
    halt_motor,
    marking_the_stop,
    no_servos,
    note_the_stop,
    report_line,
    stop_and_read_back,
    stop_motors,
    torque_text,
    unwritten_text,
)
from busarm.errors import (
    BusArmError,
    BusTimeoutError,
    ConfigError,
    TransportError,
    UnreliableLineError,
)
from busarm.fileio import robot_folder
from busarm.progress import Progress, quiet
from busarm.robot.port_url import parse_port
from busarm.twin.scene import MAX_BLOCKS, Scene

if TYPE_CHECKING:
    from busarm.robot import Robot
    from busarm.robot.calibration_store import CalibrationStore
    from busarm.robot.description import RobotConfig, ServoLine
    from busarm.sim.pty import PtyServer

SIM_NOTE = ("note: no --port given: using a simulated arm that lives for this one command "
            "(it starts straight up every time); to keep one between commands, run "
            "`busarm sim serve` in another terminal")
"""What a command without --port says when no `busarm sim serve`/`twin serve` runs."""
# Names commands import from here that live elsewhere (mypy: explicit re-exports).
# What the stop says (busarm.cli.stopping).
__all__ = [
    "ArmContext",
    "Settings",
    "Terminated",
    "add_detail",
    "arm_options",
    "calibration_options",
    "calibration_store",
    "check_writable",
    "halt_motor",
    "hold_where_it_stands",
    "interrupt_on_signals",
    "lidar_port_or_default",
    "make_console",
    "make_scene",
    "marking_the_stop",
    "no_servos",
    "note_the_stop",
    "report_line",
    "scene_options",
    "serve_until_stopped",
    "stop_and_read_back",
    "stop_motors",
    "torque_text",
    "unwritten_text",
]
# What the arm commands take (busarm.cli.arm_inputs).
__all__ += ["check_gap_mm", "gap_report", "joints_in", "joints_to_move",
            "parse_gripper_target", "robot_folder", "target_in"]
__all__ += ["announced", "find_session"]  # running `sim serve`/`twin serve` (cli.sessions)
__all__ += ["arena_from_spec", "keeping_what_was_done", "mobile_options",  # cli.mobile_common
            "open_mobile_robot", "stop_wheels"]
__all__ += ["open_live_robot"]  # cli.live_robot
__all__ += ["explore_hook", "line_follow_hook", "navigation_hook", "need_view",  # job_view
            "say_view_errors", "start_view", "view_options", "watching"]
__all__ += ["camera_from_text", "describe_robot", "from_robot_file",  # cli.robot_options
            "with_realtime"]
__all__ += ["JobNotDone", "metavar_from_help",  # exit codes, help style (cli.exits, help_style)
            "unit_metavar"]
# Values checked while argv is parsed (busarm.cli.param_types).
__all__ += ["ANGLE", "ID_LIST", "MOVE_TIME", "NUMBER_ARGS", "POSE", "SERVO_ID", "SPEED",
            "AngleType", "CheckedType", "IdListType", "PoseType", "RangeType", "ServoIdType",
            "angle_list", "parse_float_list", "parse_int", "parse_pose"]
# Live readings, scans (busarm.cli.servo_tables).
__all__ += ["BAD_REPLY", "NOT_HERE", "NO_REPLY", "alarm_names", "fmt", "scan_progress",
            "scan_report", "scan_with_progress", "state_row", "state_table", "try_read"]


PIPE_WIDTH = 1000
"""Columns of output that is not a terminal: no table is cut to fit 80 columns."""


def make_console(*, stderr: bool = False) -> Console:
    """A console for stdout (or stderr). On a terminal rich wraps to its width; piped or
    redirected, a line is never broken (``soft_wrap``) and tables keep their whole
    headers, up to PIPE_WIDTH columns or $COLUMNS if it is set: the reader is a program,
    a file or a pager, not an 80-column screen."""
    console = Console(stderr=stderr)
    if console.is_terminal:
        return console
    width = PIPE_WIDTH if "COLUMNS" not in os.environ else None
    return Console(stderr=stderr, soft_wrap=True, width=width)


@dataclass
class Settings:
    """The global options, and the consoles commands print to."""

    port: str = "sim"
    baudrate: int = DEFAULT_BAUDRATE
    echo: str = "auto"
    timeout_margin_ms: float = DEFAULT_TIMEOUT_MARGIN_S * 1000.0
    retries: int = DEFAULT_RETRIES
    out: Console = field(default_factory=make_console)
    err: Console = field(default_factory=lambda: make_console(stderr=True))
    port_given: bool = True
    """False when neither --port nor BUSARM_PORT was given (the default simulator)."""
    port_from_env: bool = False
    """True when the port is $BUSARM_PORT's (said with an error opening it)."""
    robot_file: Path | None = None
    """--robot FILE: the robot described by a robot file (busarm.robot.robot_file)."""
    session: Session | None = field(default=None, init=False, repr=False)
    """The running `sim serve`/`twin serve` the default port is (after default_port())."""
    _default_resolved: bool = field(default=False, init=False, repr=False)
    _default_said: bool = field(default=False, init=False, repr=False)

    def default_port(self, *, say: bool = True) -> str:
        """The port of a command without --port: the newest running `busarm sim serve` or
        `twin serve` (so that commands build on each other), else the in-process
        simulator. Which one is said once, on stderr (not if ``say`` is False: for a
        command that only names the robot's files by it, and opens no bus)."""
        if not self._default_resolved:
            self._default_resolved = True
            self.session = find_session()
        if say and not self._default_said:
            self._default_said = True
            note = SIM_NOTE if self.session is None else (
                f"note: no --port given: using {self.session.describe()} "
                "(--port sim for a fresh simulated arm)")
            self.err.print(note, highlight=False, markup=False, soft_wrap=True)
        return self.session.port if self.session is not None else self.port

    def robot_key(self) -> str:
        """The name of the robot's kept files (poses, calibrations): a running `sim
        serve`/`twin serve` is its kind (``sim``, ``twin``) whether it is reached by
        default or by its pty, so that both find the same files."""
        if self.on_robot_file:
            return self.robot_description().world.robot_key
        port = self.port if self.port_given else self.default_port(say=False)
        served = next((s for s in running_sessions() if s.port == port), None)
        return served.kind if served is not None else parse_port(port).robot_key

    def world(self, port: str | None = None) -> PortSpec:
        """``port`` (default: --port, else the default port) read into a typed port: the
        one place the command line's port string is parsed."""
        if port is None:
            if self.on_robot_file:
                return self.robot_description().world
            port = self.port if self.port_given else self.default_port()
        with self._port_named():
            return parse_port(port)

    @property
    def on_robot_file(self) -> bool:
        """Whether the robot is --robot FILE's (which beats $BUSARM_PORT); ConfigError
        when --port is given with it."""
        if self.robot_file is None:
            return False
        if self.port_given and not self.port_from_env:
            raise ConfigError(f"give --robot {self.robot_file} or --port {self.port}, not "
                              "both: the robot file names its port")
        return True

    def robot_description(self) -> RobotConfig:
        """The robot of --robot FILE."""
        from busarm.robot.robot_file import load_robot_file

        if self.robot_file is None:
            raise ConfigError("no --robot FILE was given")
        return load_robot_file(self.robot_file)[0]

    def line(self) -> ServoLine:
        """How the arm's servo line is driven (--baudrate, --echo, --retries...)."""
        from busarm.robot.description import ServoLine

        return ServoLine(self.baudrate, self.echo, self.retries,
                         self.timeout_margin_ms / 1000.0)

    @contextmanager
    def open_bus(
        self, port: str | None = None, check_ids: Iterable[int] = (),
        check: Callable[[LxServoPort, int], object] | None = None,
    ) -> Iterator[LxServoPort]:
        """Open the bus on ``port`` (default: ``--port``): ``with settings.open_bus() as bus``.

        Each of ``check_ids`` must answer ``check(bus, sid)`` (default: ID_READ) before
        the body runs; if one does not (or ``check`` raises), the bus is closed with
        nothing written. An exception leaving the body after a write stops every servo
        and carries their torque, read back, for the message (``marking_the_stop``).
        """
        check_ids = list(check_ids)
        world = self.world(port)
        with self._port_named():
            bus = ServoBus.open(world, baudrate=self.baudrate, echo=self.echo,
                                timeout_margin_s=self.timeout_margin_ms / 1000.0,
                                retries=self.retries)
        try:
            _check_answering(bus, check_ids, check or _ping)
        except BaseException:
            bus.close()  # nothing was written: no emergency stop
            raise
        with marking_the_stop(bus, bus, check_ids):
            yield bus

    @contextmanager
    def open_board(self) -> Iterator[BoardLink]:
        """The controller board on ``--port`` (a ``board://`` port): its link, closed after
        the body, which stops its wheel motors on the way out by an exception."""
        world = self.world()
        with self._port_named():
            transport = open_transport(world, baudrate=self.baudrate)
        try:
            link = BoardLink(transport, timeout_margin_s=self.timeout_margin_ms / 1000.0,
                             retries=self.retries)
            link.check_talking()
        except BaseException:
            transport.close()
            raise
        try:
            yield link
        except BaseException:
            with suppress(BusArmError):
                link.stop_motors()
            raise
        finally:
            link.close()

    @contextmanager
    def open_robot(self, *, default: str = "sim", needs: Collection[str] = (),
                   progress: Progress = quiet, world: PortSpec | None = None,
                   **options: Any) -> Iterator[Robot]:
        """The robot on ``world`` (default: --port, else ``default``; for ``sim``, the
        running server of default_port(), with a twin's camera), described by the bus
        settings and ``options`` (busarm.cli.robot_options.describe_robot). An exception
        leaving the body after a write stops the arm and carries each servo's torque,
        read back, for the message."""
        from busarm.robot import Robot  # MuJoCo and OpenCV load only for commands that use it

        if world is None and self.on_robot_file:
            description = from_robot_file(self.robot_description(), options)
            with self._port_named():
                robot = Robot.open(description, needs=needs, progress=progress)
            with marking_the_stop(robot, robot.arm.bus, robot.config.servo_ids):
                yield robot
            return
        if world is None:
            port = self.port
            if not self.port_given:  # the default "sim" is a running server if there is one
                port = self.default_port() if default == "sim" else default
                if self.session is not None and options.get("camera") is None:
                    options["camera"] = self.session.camera
            world = self.world(port)
        description = describe_robot(world, self.line(), **options)
        with self._port_named():
            robot = Robot.open(description, needs=needs, progress=progress)
        with marking_the_stop(robot, robot.arm.bus, robot.config.servo_ids):
            yield robot

    @contextmanager
    def _port_named(self) -> Iterator[None]:
        """A port that cannot be opened is said to come from $BUSARM_PORT, if it does."""
        try:
            yield
        except TransportError as exc:
            if self.port_from_env:
                add_detail(exc, "the port came from $BUSARM_PORT")
            raise


def _ping(bus: LxServoPort, sid: int) -> None:
    bus.read_id(sid)


def _check_answering(bus: LxServoPort, ids: list[int],
                     check: Callable[[LxServoPort, int], object]) -> None:
    """Each of ``ids`` answers ``check``. One that is silent is asked again once the
    others after it have been: if their replies came late or damaged, the driver's error
    then says the line is unreliable, rather than "no servo answers" of a servo that may
    be there."""
    silent = []
    for sid in ids:
        try:
            check(bus, sid)
        except UnreliableLineError:
            raise
        except BusTimeoutError:
            silent.append(sid)
    for sid in silent:
        if sid != ids[-1]:
            try:
                check(bus, sid)
                continue  # it answers now: a bad line, which later reads will say
            except UnreliableLineError:
                raise
            except BusTimeoutError:
                pass
        raise BusTimeoutError(f"no servo answers at ID {sid}", servo_id=sid) from None


pass_settings = click.make_pass_decorator(Settings, ensure=True)


class ArmContext:
    """The arm options of the ``arm`` and ``actions`` groups, loaded on first use."""

    def __init__(self, settings: Settings, config: str, calibration: str | None) -> None:
        self.settings = settings
        self._config_name = config
        self._calibration_path = calibration
        self._config: ArmConfig | None = None

    def override(self, config: str | None = None, calibration: str | None = None) -> None:
        """Use these arm options instead (given after the subcommand, or before the group)."""
        if config is not None:
            self._config_name, self._config = config, None
        if calibration is not None:
            self._calibration_path = calibration

    @property
    def config(self) -> ArmConfig:
        if self._config is None:
            self._config = load_arm_config(self._config_name)
        return self._config

    @property
    def kin(self) -> ArmKinematics:
        return ArmKinematics.from_config(self.config)

    def calibration(self) -> Calibration | None:
        if self._calibration_path is None:
            return None
        return load_calibration(self._calibration_path)

    @contextmanager
    def open(self, *, check: bool = True, port: str | None = None) -> Iterator[Arm]:
        """The arm on ``port`` (default ``--port``): every servo must answer first (nothing
        is written if one does not); an exception in the body after a write stops the arm
        (see ``Settings.open_bus``)."""
        calibration = self.calibration()
        with self.settings.open_bus(port, check_ids=self.config.servo_ids) as bus:
            yield Arm(bus, self.config, calibration, check=check)


def hold_where_it_stands(arm: Arm, settings: Settings) -> None:
    """Torque on where the arm stands (after a limp spell: calibration, teaching); servos
    outside their limits are left limp, with a warning."""
    limp = arm.hold_here()
    if limp:
        settings.err.print(f"warning: servos {limp} are outside their limits: left limp "
                           "(torque off); move them back by hand", highlight=False)


pass_arm = click.make_pass_decorator(ArmContext)

_CONFIG_HELP = "Arm description: a shipped name (jetauto_pro) or a TOML file."
_CAL_HELP = "Calibration file from `busarm arm calibrate`  [default: none, nominal zeros]"


def arm_options(f: Callable[..., Any]) -> Callable[..., Any]:
    f = click.option("--calibration", envvar="BUSARM_CALIBRATION", show_envvar=True,
                     type=click.Path(dir_okay=False), help=_CAL_HELP)(f)
    return click.option("--config", "config", envvar="BUSARM_ARM", default="jetauto_pro",
                        show_default=True, show_envvar=True, help=_CONFIG_HELP)(f)


def calibration_store(settings: Settings, default: str = "sim") -> CalibrationStore:
    """Where the robot that ``settings.open_robot(default=default)`` opens keeps its
    camera calibration (busarm.robot.calibration_store)."""
    from busarm.robot.calibration_store import CalibrationStore

    if settings.port_given or default == "sim":
        return CalibrationStore.for_robot(settings.robot_key(), settings.port
                                          if settings.port_given
                                          else settings.default_port(say=False))
    return CalibrationStore.for_port(parse_port(default))


def check_writable(path: Path) -> None:
    """Refuse an output file that cannot be written, before any arm motion."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ConfigError(f"cannot write {path}: folder {folder} does not exist or is not "
                          "writable")


DEFAULT_COLORS = "red,green,blue"


def calibration_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--intrinsics and --hand-eye: the wrist camera's calibration files (the robot's kept
    ones by default; on the twin made first if there are none)."""
    func = click.option("--hand-eye", "hand_eye",
                        type=click.Path(dir_okay=False, exists=True, path_type=Path),
                        default=None, help="Hand-eye calibration  [default: the one kept for "
                                           "this robot; on the twin made first if there is "
                                           "none]")(func)
    func = click.option("--intrinsics",
                        type=click.Path(dir_okay=False, exists=True, path_type=Path),
                        default=None, help="Camera intrinsics  [default: the ones kept for "
                                           "this robot; on the twin made first if there are "
                                           "none]")(func)
    return func


def scene_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--scene FILE or --seed/--blocks/--colors: what stands on the twin's table."""
    func = click.option("--colors", default=None,
                        help=f"Block colours of a random scene, comma separated "
                             f"[default: {DEFAULT_COLORS}].")(func)
    func = click.option("--blocks", type=click.IntRange(0, MAX_BLOCKS), default=None,
                        help="How many blocks in a random scene  [default: 5]")(func)
    func = click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=None,
                        help="Seed of a random scene  [default: 0]")(func)
    func = click.option("--scene", "scene_file",
                        type=click.Path(dir_okay=False, path_type=Path),
                        help="A scene file (busarm twin scene writes one to edit).")(func)
    return func


def make_scene(scene_file: Path | None, seed: int | None, blocks: int | None,
               colors: str | None) -> Scene:
    """The scene the options ask for (a file, or a seeded random scene)."""
    from busarm.twin.scene import load_scene, random_scene

    if scene_file is not None:
        if seed is not None or blocks is not None or colors is not None:
            raise ConfigError("give either --scene or --seed/--blocks/--colors, not both")
        return load_scene(scene_file)
    names = [c.strip() for c in (colors or DEFAULT_COLORS).split(",") if c.strip()]
    return random_scene(seed or 0, 5 if blocks is None else blocks, names)


def lidar_port_or_default(given: str | None) -> str:
    """--lidar if given, else the Lidar of a running ``twin serve --arena``, else the
    simulated A1 in this process."""
    from busarm.cli.sessions import running_sessions
    from busarm.robot.port_url import SIM_LIDAR

    if given:
        return given
    session = next((s for s in running_sessions() if s.lidar), None)
    if session is None or session.lidar is None:
        return SIM_LIDAR
    click.echo(f"note: no --lidar given: using the Lidar of `busarm {session.kind} serve` "
               f"(pid {session.pid}) on {session.lidar}", err=True)
    return session.lidar


def serve_until_stopped(server: PtyServer) -> None:
    """Serve until SIGINT or SIGTERM, then stop the server (which powers the servos off)."""
    restore = interrupt_on_signals()
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        restore()
        server.stop()


def interrupt_on_signals(signals: tuple[signal.Signals, ...] = (
        signal.SIGINT, signal.SIGTERM, signal.SIGHUP)) -> Callable[[], None]:
    """Make ``signals`` (SIGINT, SIGTERM and SIGHUP) raise KeyboardInterrupt (even if
    SIGINT was inherited as ignored, as in background jobs): a server stops cleanly on
    each; return a function restoring the old handlers. (Left out, SIGTERM and SIGHUP
    raise ``Terminated``, as for every command: exit 143 or 129.)"""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    previous = {sig: signal.signal(sig, handler) for sig in signals}

    def restore() -> None:
        for sig, old in previous.items():
            signal.signal(sig, old)

    return restore
