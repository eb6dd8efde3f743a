"""What every command shares: the global settings, parameter types, consoles, the arm
and robot options, rich tables and progress bars. Command modules import shared helpers
from here only.

Parameter types check values (IDs, angles, times) while argv is parsed, so bad
input fails before any port is opened and nothing reaches the bus.
"""

from __future__ import annotations

import math
import os
import re
import signal
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any, TypeVar

import click
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from busarm.arm.arm import Arm
from busarm.arm.calibration import Calibration, load_calibration
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bus.board import BoardLink
from busarm.bus.driver import DEFAULT_RETRIES, DEFAULT_TIMEOUT_MARGIN_S, ScanResult, ServoBus
from busarm.bus.transport import DEFAULT_BAUDRATE, open_transport
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
from busarm.cli.live_robot import open_live_robot, realtime_twin, twin_store_port
from busarm.cli.mobile_common import arena_from_spec, mobile_options, open_mobile_robot
from busarm.cli.sessions import Session, announced, find_session, running_sessions
from busarm.cli.stopping import (
    add_detail,
    halt_motor,
    marking_the_stop,
    no_servos,
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
    ProtocolError,
    TransportError,
    UnreliableLineError,
)
from busarm.fileio import robot_folder
from busarm.protocol import MAX_SERVO_ID, AlarmFlag, check_servo_id
from busarm.twin.scene import MAX_BLOCKS, Scene
from busarm.units import (
    MOVE_TIME_MAX_MS,
    POSITION_MAX_DEG,
    POSITION_MIN_DEG,
    check_range,
    parse_ids,
    range_text,
)

if TYPE_CHECKING:
    from busarm.base.odometry import Pose2D
    from busarm.robot import Robot
    from busarm.robot.calibration_store import CalibrationStore
    from busarm.sim.pty import PtyServer

T = TypeVar("T")

NO_REPLY = "no reply"
BAD_REPLY = "bad reply"
NOT_HERE = "n/a (the controller board cannot read it)"

SIM_NOTE = ("note: no --port given: using a simulated arm that lives for this one command "
            "(it starts straight up every time); to keep one between commands, run "
            "`busarm sim serve` in another terminal")
"""What a command without --port says when no `busarm sim serve`/`twin serve` runs."""
# Names commands import from here that live elsewhere (mypy: explicit re-exports).
# What the stop says (busarm.cli.stopping).
__all__ = ["add_detail", "halt_motor", "marking_the_stop", "no_servos", "report_line",
           "stop_and_read_back",
           "stop_motors", "torque_text", "unwritten_text"]
# What the arm commands take (busarm.cli.arm_inputs).
__all__ += ["check_gap_mm", "gap_report", "joints_in", "joints_to_move",
            "parse_gripper_target", "robot_folder", "target_in"]
__all__ += ["announced", "find_session"]  # running `sim serve`/`twin serve` (cli.sessions)
__all__ += ["arena_from_spec", "mobile_options", "open_mobile_robot"]  # cli.mobile_common
__all__ += ["open_live_robot", "realtime_twin", "twin_store_port"]  # cli.live_robot
__all__ += ["JobNotDone", "metavar_from_help"]  # exit codes, help style (cli.exits, help_style)


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

    def robot_port(self) -> str:
        """The port the robot's kept files (poses, calibrations) are named after: a
        running `sim serve`/`twin serve` is its kind (``sim``, ``twin``) whether it is
        reached by default or by its pty, so that both find the same files."""
        port = self.port if self.port_given else self.default_port(say=False)
        served = next((s for s in running_sessions() if s.port == port), None)
        return served.kind if served is not None else port

    @contextmanager
    def open_bus(
        self, port: str | None = None, check_ids: Iterable[int] = (),
        check: Callable[[ServoBus, int], object] | None = None,
    ) -> Iterator[ServoBus]:
        """Open the bus on ``port`` (default: ``--port``): ``with settings.open_bus() as bus``.

        Each of ``check_ids`` must answer ``check(bus, sid)`` (default: ID_READ) before
        the body runs; if one does not (or ``check`` raises), the bus is closed with
        nothing written. An exception leaving the body after a write stops every servo
        and carries their torque, read back, for the message (``marking_the_stop``).
        """
        check_ids = list(check_ids)
        if port is None:
            port = self.port if self.port_given else self.default_port()
        with self._port_named():
            bus = ServoBus.open(port, baudrate=self.baudrate, echo=self.echo,
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
        port = self.port if self.port_given else self.default_port()
        with self._port_named():
            transport = open_transport(port, baudrate=self.baudrate)
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
    def open_robot(self, *, default: str = "sim", **options: Any) -> Iterator[Robot]:
        """The robot on ``--port`` (``default`` when none was given; for ``sim``, the
        running server of default_port(), with a twin's camera): ``Robot.open`` with
        the bus settings and ``options``. An exception leaving the body after a write stops
        the arm and carries each servo's torque, read back, for the message."""
        from busarm.robot import Robot  # MuJoCo and OpenCV load only for commands that use it

        port = self.port
        if not self.port_given:  # the default "sim" is a running server if there is one
            port = self.default_port() if default == "sim" else default
            if self.session is not None and options.get("camera") is None:
                options["camera"] = self.session.camera
        with self._port_named():
            robot = Robot.open(port, baudrate=self.baudrate, echo=self.echo,
                               timeout_margin_s=self.timeout_margin_ms / 1000.0,
                               retries=self.retries, **options)
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


def _ping(bus: ServoBus, sid: int) -> None:
    bus.read_id(sid)


def _check_answering(bus: ServoBus, ids: list[int],
                     check: Callable[[ServoBus, int], object]) -> None:
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


class CheckedType(click.ParamType):
    """A parameter type whose converter raises ConfigError; shown as a usage error."""

    def parse(self, text: str) -> Any:
        raise NotImplementedError

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not isinstance(value, str):
            return value
        try:
            return self.parse(value)
        except ConfigError as exc:
            self.fail(str(exc), param, ctx)


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{text!r} is not a number ({what})") from None
    if not math.isfinite(value):
        raise ConfigError(f"{text!r} is not a finite number ({what})")
    return value


def parse_float_list(text: str, what: str) -> list[float]:
    """Finite numbers separated by commas or spaces (``0,60,0`` or ``"0 60 0"``: lists are
    written either way everywhere); ConfigError naming ``what`` and the bad one."""
    return [_number(t, what) for t in re.split(r"[,\s]+", text.strip())]


def parse_pose(text: str, option: str) -> Pose2D:
    """``X,Y,YAW`` (m, m, deg) -> a Pose2D; ConfigError naming ``option`` otherwise."""
    from busarm.base.odometry import Pose2D

    values = parse_float_list(text, f"{option} X,Y,YAW (m, m, deg)")
    if len(values) != 3:
        raise ConfigError(f"{option} {text!r}: expected X,Y,YAW (m, m, deg), e.g. 0.5,-1.2,90")
    return Pose2D(values[0], values[1], math.radians(values[2]))


def angle_list(kind: RangeType) -> Callable[[click.Context, click.Parameter, tuple[str, ...]],
                                            tuple[float, ...]]:
    """A callback for an ``nargs=-1`` argument of angles: ``0 60 0`` or ``0,60,0``, each
    checked as ``kind``."""
    def convert(ctx: click.Context, param: click.Parameter,
                values: tuple[str, ...]) -> tuple[float, ...]:
        text = " ".join(values).strip()
        return tuple(kind.parse(str(v)) for v in parse_float_list(text, kind.name)) if text \
            else ()
    return convert


def parse_int(text: str, what: str) -> int:
    """An integer from decimal (or 0x/0b/0o) text; ConfigError naming ``what`` if not."""
    t = text.strip()
    try:
        return int(t, 0) if t[:2].lower() in ("0x", "0b", "0o") else int(t)
    except ValueError:
        raise ConfigError(f"{text!r} is not an integer ({what})") from None


class ServoIdType(CheckedType):
    """A servo ID, 0..253 (or 254, broadcast, where allowed)."""

    name = "id"

    def __init__(self, allow_broadcast: bool = False) -> None:
        self.allow_broadcast = allow_broadcast

    def get_metavar(self, param: click.Parameter) -> str:
        return "ID"

    def parse(self, text: str) -> int:
        hi = MAX_SERVO_ID + 1 if self.allow_broadcast else MAX_SERVO_ID
        return check_servo_id(parse_int(text, f"servo ID 0..{hi}"),
                              allow_broadcast=self.allow_broadcast)


class AngleType(CheckedType):
    """An angle in degrees from the servo's mid-point, within ``lo..hi``."""

    name = "deg"

    def __init__(self, lo: float = POSITION_MIN_DEG, hi: float = POSITION_MAX_DEG) -> None:
        self.lo, self.hi = lo, hi

    def parse(self, text: str) -> float:
        value = _number(text, f"an angle in deg, {range_text(self.lo, self.hi)}")
        return check_range("angle", value, self.lo, self.hi, "deg")


class RangeType(CheckedType):
    """A number within ``lo..hi`` of the given unit."""

    def __init__(self, name: str, lo: float, hi: float, unit: str) -> None:
        self.name, self.lo, self.hi, self.unit = name, lo, hi, unit

    def get_metavar(self, param: click.Parameter) -> str | None:
        if isinstance(param, click.Argument):
            return None  # an argument is shown by its own name (X Y Z)
        # One word (it is one argument): its unit, as for every number option.
        return unit_metavar(self.unit) or self.name.upper().replace(" ", "_")

    def parse(self, text: str) -> float:
        value = _number(text, f"{self.name} in {self.unit}, {range_text(self.lo, self.hi)}")
        return check_range(self.name, value, self.lo, self.hi, self.unit)


class IdListType(CheckedType):
    """Servo IDs such as ``1,2,3`` or ``0-20,100``."""

    name = "ids"

    def parse(self, text: str) -> list[int]:
        return list(dict.fromkeys(parse_ids(text)))


class PoseType(CheckedType):
    """Targets such as ``1=0,2=-30,3=45`` (servo ID = angle in deg)."""

    name = "pose"

    def parse(self, text: str) -> dict[int, float]:
        pose: dict[int, float] = {}
        for part in text.split(","):
            if not part.strip():
                continue
            sid_text, sep, angle_text = part.partition("=")
            if not sep:
                raise ConfigError(f"pose {text!r}: {part.strip()!r} is not ID=ANGLE")
            sid = ServoIdType().parse(sid_text)
            if sid in pose:
                raise ConfigError(f"pose {text!r}: servo {sid} is given twice")
            pose[sid] = AngleType().parse(angle_text)
        if not pose:
            raise ConfigError(f"pose {text!r}: no ID=ANGLE given")
        return pose


SERVO_ID = ServoIdType()
ANGLE = AngleType()
MOVE_TIME = RangeType("time", 0.0, MOVE_TIME_MAX_MS / 1000.0, "s")
SPEED = RangeType("speed", 0.1, 10000.0, "deg/s")
ID_LIST = IdListType()
POSE = PoseType()


def try_read(read: Callable[[], T]) -> T | str:
    """``read()``, or ``"no reply"`` if the servo did not answer (or ``"bad reply"``)."""
    try:
        return read()
    except BusTimeoutError:
        return NO_REPLY
    except ProtocolError:
        return BAD_REPLY


def fmt(value: object, spec: str = "", unit: str = "") -> str:
    """``value`` formatted with ``spec`` and ``unit``; strings ("no reply") as they are."""
    if isinstance(value, str):
        return value
    text = format(value, spec)
    return f"{text} {unit}" if unit else text


def state_row(bus: ServoBus, sid: int, *, torque: bool = False) -> list[str]:
    """ID, position, temperature and voltage of one servo (and torque); "no reply" per field."""
    row = [
        str(sid),
        fmt(try_read(lambda: bus.read_position_deg(sid)), "+.1f"),
        fmt(try_read(lambda: bus.read_temp_c(sid)), "d"),
        fmt(try_read(lambda: bus.read_vin_v(sid)), ".2f"),
    ]
    if torque:
        loaded = try_read(lambda: bus.read_torque(sid))
        row.append(loaded if isinstance(loaded, str) else ("on" if loaded else "off"))
    return row


def state_table(
    bus: ServoBus, ids: Iterable[int], *, title: str | None = None, torque: bool = False,
    targets: dict[int, float] | None = None,
) -> Table:
    """A table of live readings, one row per servo (optionally with each target)."""
    table = Table(title=title, title_justify="left")
    table.add_column("ID", justify="right")
    if targets is not None:
        table.add_column("target (deg)", justify="right")
    table.add_column("position (deg)", justify="right")
    table.add_column("temp (C)", justify="right")
    table.add_column("voltage (V)", justify="right")
    if torque:
        table.add_column("torque", justify="center")
    for sid in ids:
        row = state_row(bus, sid, torque=torque)
        if targets is not None:
            row.insert(1, f"{targets[sid]:+.1f}" if sid in targets else "")
        style = "red" if NO_REPLY in row else None
        table.add_row(*row, style=style)
    return table


def scan_with_progress(bus: ServoBus, ids: Sequence[int], console: Console) -> ScanResult:
    """``bus.scan(ids)`` behind a progress bar (shown on ``console``, then removed)."""
    with scan_progress(console, len(ids)) as advance:
        return bus.scan(ids, progress=lambda _sid: advance())


@contextmanager
def scan_progress(console: Console, total: int) -> Iterator[Callable[[], None]]:
    """A transient progress bar for a scan of ``total`` IDs; yields its advance()."""
    progress = Progress(
        TextColumn("scanning IDs"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=True,
    )
    with progress:
        task: TaskID = progress.add_task("scan", total=total)
        yield lambda: progress.advance(task, 1)


def scan_report(bus: ServoBus, result: ScanResult, console: Console, asked: int) -> None:
    """Print the servos a scan found (with readings) and any conflicts, in red."""
    console.print(
        f"scanned {asked} ID(s) in {result.duration_s:.2f} s: "
        f"found {len(result.found)} servo(s)"
        + (f": {', '.join(map(str, result.found))}" if result.found else "")
    )
    healthy = [sid for sid in result.found if sid not in result.conflicts]
    if healthy:
        console.print(state_table(bus, healthy))
    for sid in result.conflicts:
        console.print(
            f"[red]conflict: more than one servo answers at ID {sid} (duplicate IDs); "
            "disconnect all but one and renumber with set-id[/red]"
        )


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

    port = settings.robot_port() if settings.port_given or default == "sim" else default
    return CalibrationStore.for_port(port)


def check_writable(path: Path) -> None:
    """Refuse an output file that cannot be written, before any arm motion."""
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ConfigError(f"cannot write {path}: folder {folder} does not exist or is not "
                          "writable")


DEFAULT_COLORS = "red,green,blue"


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


NUMBER_ARGS = {"ignore_unknown_options": True}


def alarm_names(mask: AlarmFlag) -> str:
    """``over-temperature, stalled`` style names of an alarm mask (``none`` if empty)."""
    names = [f.name.lower().replace("_", "-") for f in AlarmFlag if f and f in mask and f.name]
    return ", ".join(names) or "none"


def lidar_port_or_default(given: str | None) -> str:
    """--lidar if given, else the Lidar of a running ``twin serve --arena``, else the
    simulated A1 in this process."""
    from busarm.cli.sessions import running_sessions
    from busarm.lidar.rplidar import SIM_LIDAR

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


def interrupt_on_signals() -> Callable[[], None]:
    """Make SIGINT and SIGTERM raise KeyboardInterrupt (even if SIGINT was inherited as
    ignored, as in background jobs); return a function restoring the old handlers."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    previous = {sig: signal.signal(sig, handler) for sig in (signal.SIGINT, signal.SIGTERM)}

    def restore() -> None:
        for sig, old in previous.items():
            signal.signal(sig, old)

    return restore
