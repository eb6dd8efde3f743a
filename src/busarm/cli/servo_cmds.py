"""Commands on servos: ``info``, ``move``, ``stop``, ``torque``, ``set-id``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click
from rich.table import Table

from busarm.arm.config import DEFAULT_ARM, ArmConfig, load_arm_config
from busarm.bus.lx_port import LxServoPort
from busarm.cli.common import (
    ANGLE,
    BAD_REPLY,
    MOVE_TIME,
    NO_REPLY,
    NOT_HERE,
    NUMBER_ARGS,
    POSE,
    SERVO_ID,
    SPEED,
    Settings,
    alarm_names,
    pass_settings,
    scan_with_progress,
    stop_motors,
    torque_text,
)
from busarm.errors import (
    BusArmError,
    BusConflictError,
    BusTimeoutError,
    ConfigError,
    EchoMismatchError,
    LimitError,
    ProtocolError,
    UnsupportedError,
)
from busarm.protocol import (
    BROADCAST_ID,
    MAX_SERVO_ID,
    Command,
    ServoMode,
)
from busarm.protocol.lx_units import pulses_from_deg

__all__ = [
    "COMMANDS",
    "DEFAULT_MOVE_TIME_S",
    "INFO_FIELDS",
    "WAIT_SLACK_S",
    "info",
    "info_rows",
    "move",
    "set_id",
    "stop",
    "torque",
]


DEFAULT_MOVE_TIME_S = 1.0
WAIT_SLACK_S = 2.0
"""--wait allows the move's duration plus this before giving up."""

# Negative numbers (angles, offsets) must reach the arguments, not the option parser.
def _move(r: Any) -> str:
    return f"{r.position_deg:+.1f} deg ({r.position_pulses} pulses), {r.time_s:g} s"


# (field, read command, how to show its typed reply)
INFO_FIELDS: list[tuple[str, Command, Callable[[Any], str]]] = [
    ("position", Command.POS_READ,
     lambda r: f"{r.position_deg:+.1f} deg ({r.position_pulses} pulses)"),
    ("last move (target, time)", Command.MOVE_TIME_READ, _move),
    ("waiting move (target, time)", Command.MOVE_TIME_WAIT_READ, _move),
    ("angle offset", Command.ANGLE_OFFSET_READ,
     lambda r: f"{r.offset_deg:+.2f} deg ({r.offset_pulses} pulses)"),
    ("angle limits", Command.ANGLE_LIMIT_READ,
     lambda r: f"{r.min_deg:+.1f}..{r.max_deg:+.1f} deg ({r.min_pulses}..{r.max_pulses} pulses)"),
    ("voltage limits", Command.VIN_LIMIT_READ, lambda r: f"{r.min_v:.2f}..{r.max_v:.2f} V"),
    ("temperature limit", Command.TEMP_MAX_LIMIT_READ, lambda r: f"{r.temp_max_c} C"),
    ("temperature", Command.TEMP_READ, lambda r: f"{r.temp_c} C"),
    ("voltage", Command.VIN_READ, lambda r: f"{r.vin_v:.2f} V"),
    ("mode", Command.OR_MOTOR_MODE_READ,
     lambda r: "position" if r.mode is ServoMode.POSITION else f"motor, speed {r.motor_speed}"),
    ("torque", Command.LOAD_OR_UNLOAD_READ,
     lambda r: "on (loaded)" if r.is_loaded else "off (unloaded)"),
    ("LED", Command.LED_CTRL_READ, lambda r: "off" if r.is_led_off else "on"),
    ("LED alarms", Command.LED_ERROR_READ, lambda r: alarm_names(r.alarm_mask)),
]


def info_rows(
    bus: LxServoPort, sid: int, errors: list[BusTimeoutError | ProtocolError] | None = None,
) -> list[tuple[str, str]]:
    """Every readable field of servo ``sid``, as (name, value) text; "no reply" (or "bad
    reply") per field that could not be read, whose error goes to ``errors`` if given."""
    rows: list[tuple[str, str]] = []
    for name, command, show in INFO_FIELDS:
        try:
            rows.append((name, show(bus.query(sid, command))))
        except UnsupportedError:
            rows.append((name, NOT_HERE))
        except (BusTimeoutError, ProtocolError) as exc:
            rows.append((name, NO_REPLY if isinstance(exc, BusTimeoutError) else BAD_REPLY))
            if errors is not None:
                errors.append(exc)
    return rows


def _nothing_read(sid: int, errors: list[BusTimeoutError | ProtocolError]) -> BusArmError:
    """The error of an ``info`` that read no field: why, as far as the replies tell."""
    for exc in errors:
        if isinstance(exc, EchoMismatchError):
            return exc
    garbled = [exc for exc in errors if isinstance(exc, ProtocolError)]
    if garbled:
        return ProtocolError(f"servo {sid}: no field could be read: {garbled[0]}")
    return BusTimeoutError(f"servo {sid} does not answer", servo_id=sid)


@click.command(context_settings=NUMBER_ARGS)
@click.argument("servo_id", metavar="ID", type=SERVO_ID)
@pass_settings
def info(settings: Settings, servo_id: int) -> None:
    """Every readable field of servo ID (0..253): position, limits, offset, mode, LED...

    A field the servo does not answer shows "no reply" (a garbled answer "bad reply");
    when no field can be read, the command fails (exit code 1) saying why.
    """
    errors: list[BusTimeoutError | ProtocolError] = []
    with settings.open_bus() as bus:
        rows = info_rows(bus, servo_id, errors)
    if len(errors) == len(rows):  # raised here, outside the bus: nothing to stop
        raise _nothing_read(servo_id, errors)
    table = Table(title=f"servo {servo_id}", title_justify="left")
    table.add_column("field")
    table.add_column("value")
    for name, value in rows:
        table.add_row(name, f"[red]{value}[/red]" if value in (NO_REPLY, BAD_REPLY) else value)
    settings.out.print(table)


@click.command(context_settings=NUMBER_ARGS)
@click.argument("servo_id", type=SERVO_ID, required=False)
@click.argument("angle_deg", type=ANGLE, required=False)
@click.option(
    "--pose", type=POSE, metavar="ID=DEG,...",
    help="Move several servos together: ID=DEG pairs, e.g. '1=0,2=-30,3=45'.",
)
@click.option(
    "--time", "duration", type=MOVE_TIME, metavar="S",
    help=f"Move time in s, 0..30  [default: {DEFAULT_MOVE_TIME_S:g}]",
)
@click.option(
    "--speed", type=SPEED, metavar="DEG_S",
    help="Instead of --time: top speed in deg/s of the joint that moves furthest.",
)
@click.option("--wait", is_flag=True, help="Block until the servos are within 1 deg of the target.")
@click.option(
    "--config", "config_name", envvar="BUSARM_ARM", default=DEFAULT_ARM, show_default=True,
    show_envvar=True, help="The arm whose joint limits apply: a shipped name or a TOML file.",
)
@click.option(
    "--ignore-arm-limits", is_flag=True,
    help="Move a servo of the arm past its joint's limits (it may hit the arm or the table).",
)
@pass_settings
def move(
    settings: Settings, servo_id: int | None, angle_deg: float | None,
    pose: dict[int, float] | None,
    duration: float | None, speed: float | None, wait: bool, config_name: str,
    ignore_arm_limits: bool,
) -> None:
    """Move servo ID to ANGLE_DEG (-120..120 from its mid-point), or several with --pose.

    Poses start together (MOVE_TIME_WAIT_WRITE to each, then one MOVE_START; through a
    controller board, one multi-servo frame) and arrive together. Negative angles work
    as plain arguments: `busarm move 2 -30`.
    A servo that is one of the arm's joints (or its gripper) is kept within that joint's
    limits, as servo angles (uncalibrated; see `busarm arm` for joint angles), unless
    --ignore-arm-limits.
    """
    if pose is not None and servo_id is not None:
        raise click.UsageError("give either ID ANGLE_DEG or --pose, not both")
    if pose is None:
        if servo_id is None or angle_deg is None:
            raise click.UsageError("give ID and ANGLE_DEG, or --pose ID=DEG,...")
        pose = {servo_id: angle_deg}
    if duration is not None and speed is not None:
        raise click.UsageError("give either --time or --speed, not both")
    if not ignore_arm_limits:
        _check_arm_limits(pose, load_arm_config(config_name))
    targets_by_id = pose

    def within_limits(bus: LxServoPort, sid: int) -> None:
        lo, hi = bus.read_angle_limits_deg(sid)  # doubles as the presence check
        target = targets_by_id[sid]
        if not pulses_from_deg(lo) <= pulses_from_deg(target) <= pulses_from_deg(hi):
            raise ConfigError(
                f"target {target:+.1f} deg for servo {sid} is outside its angle limits "
                f"{lo:+.1f}..{hi:+.1f} deg (see: busarm limits {sid})"
            )

    with settings.open_bus(check_ids=pose, check=within_limits) as bus:
        if speed is not None:
            if len(pose) == 1:
                ((sid, target),) = pose.items()
                duration = bus.move_at_speed_deg(sid, target, speed)
            else:
                duration = bus.sync_move_deg(pose, speed_deg_s=speed)
        else:
            duration = DEFAULT_MOVE_TIME_S if duration is None else duration
            if len(pose) == 1:
                ((sid, target),) = pose.items()
                bus.move_deg(sid, target, duration)
            else:
                duration = bus.sync_move_deg(pose, duration)
        targets = ", ".join(f"{sid} -> {a + 0.0:+.1f} deg".replace("-0.0 ", "+0.0 ")
                            for sid, a in pose.items())
        settings.out.print(f"moving {targets} over {duration:.2f} s")
        if wait:
            reached = bus.wait_until_reached(pose, timeout_s=duration + WAIT_SLACK_S)
            settings.out.print(
                "reached: " + ", ".join(f"{sid} at {a:+.1f} deg" for sid, a in reached.items())
            )


def _check_arm_limits(pose: dict[int, float], config: ArmConfig) -> None:
    """Refuse (LimitError, before anything is sent) a target outside the arm's limits for
    a servo that is one of its joints or its gripper."""
    for sid, target in pose.items():
        part = config.servo_range_deg(sid)
        if part is None:
            continue
        name, lo, hi = part
        what = "the gripper" if name == "gripper" else f"joint {name}"
        if not lo - 1e-6 <= target <= hi + 1e-6:
            raise LimitError(
                f"servo {sid} is {what} of the {config.name}: {target:+.1f} deg is "
                f"outside its limits {lo:+.1f}..{hi:+.1f} deg (servo angle); "
                "--ignore-arm-limits moves it anyway"
            )


@click.command(context_settings=NUMBER_ARGS)
@click.argument("ids", nargs=-1, type=SERVO_ID)
@pass_settings
def stop(settings: Settings, ids: tuple[int, ...]) -> None:
    """Stop moving now (MOVE_STOP); no ID = every servo (broadcast). Servos with torque
    on hold position; the torque of each servo given is read back and said.

    A servo given by ID that turns in motor mode (which MOVE_STOP does not stop) is
    stopped too: speed 0, back in position mode.
    """
    with settings.open_bus(check_ids=ids) as bus:
        bus.stop(ids or None)
        # Torque off stays off: a limp servo is not holding anything.
        motors = stop_motors(bus, ids)
        said = ("stopped (MOVE_STOP): " + "; ".join(t for t in (motors, torque_text(bus, ids))
                                                     if t) if ids else
                "stopped all servos (MOVE_STOP): those in position mode with torque on hold "
                "position; one turning in motor mode does not stop so (give its ID, or "
                "`busarm motor ID stop`)")
    settings.out.print(said, highlight=False)


@click.command(context_settings=NUMBER_ARGS)
@click.argument("state", type=click.Choice(["on", "off"]))
@click.argument("ids", nargs=-1, type=SERVO_ID)
@pass_settings
def torque(settings: Settings, state: str, ids: tuple[int, ...]) -> None:
    """Torque on (hold position) or off (limp, move by hand); no ID = every servo."""
    with settings.open_bus(check_ids=ids) as bus:
        for sid in ids or (BROADCAST_ID,):
            bus.set_torque(sid, state == "on")
    settings.out.print(f"torque {state} for {_which(ids)}")


def _which(ids: tuple[int, ...]) -> str:
    return "servo(s) " + ", ".join(map(str, ids)) if ids else "all servos"


@click.command("set-id", context_settings=NUMBER_ARGS)
@click.argument("ids", metavar="[OLD] NEW", nargs=-1, type=SERVO_ID)
@pass_settings
def set_id(settings: Settings, ids: tuple[int, ...]) -> None:
    """Give a servo a new ID (0..253, stored in the servo).

    `set-id NEW` needs exactly one servo on the bus (it scans first) and refuses
    otherwise. `set-id OLD NEW` needs exactly one servo answering at OLD and none
    at NEW. The ID write is never broadcast.
    """
    if len(ids) not in (1, 2):
        raise click.UsageError("give NEW, or OLD NEW")
    new_id = ids[-1]
    if len(ids) == 2 and ids[0] == new_id:
        raise click.UsageError(f"OLD and NEW are both {new_id}")
    with settings.open_bus() as bus:
        if len(ids) == 2:
            old_id = ids[0]
        else:
            result = scan_with_progress(bus, range(MAX_SERVO_ID + 1), settings.err)
            if result.conflicts:
                raise BusConflictError(
                    f"more than one servo answers at ID(s) {_list(result.conflicts)}; "
                    "connect only the servo to renumber"
                )
            if not result.found:
                raise BusTimeoutError("no servo answers on the bus")
            if len(result.found) > 1:
                raise BusConflictError(
                    f"{len(result.found)} servos on the bus (IDs {_list(result.found)}); "
                    "connect only the servo to renumber, or use: set-id OLD NEW"
                )
            old_id = result.found[0]
            if old_id == new_id:
                settings.out.print(f"the servo already has ID {new_id}")
                return
        bus.set_id(old_id, new_id)
    settings.out.print(f"servo {old_id} is now ID {new_id}")


def _list(ids: list[int]) -> str:
    return ", ".join(map(str, ids))


COMMANDS = [info, move, stop, torque, set_id]
