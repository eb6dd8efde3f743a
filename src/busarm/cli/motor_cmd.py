"""``motor``: a servo in motor (continuous rotation) mode, for wheels and conveyors.

By default the command stays with the motor: it turns until Ctrl+C (exit code 130) or
``--time``, and on the way out (an error too) it sets speed 0 and puts the servo back in
position mode, holding where it stopped. ``--keep-turning`` leaves it turning; ``motor ID
stop`` ends it (without energising a servo whose torque was turned off).
"""

from __future__ import annotations

import contextlib

import click

from busarm.arm.config import DEFAULT_ARM, load_arm_config
from busarm.bus.board_bus import unsupported
from busarm.bus.lx_port import LxServoPort
from busarm.cli.common import (
    NUMBER_ARGS,
    SERVO_ID,
    CheckedType,
    RangeType,
    Settings,
    halt_motor,
    parse_int,
    pass_settings,
)
from busarm.errors import LimitError
from busarm.protocol import Command
from busarm.protocol.lx_units import MOTOR_SPEED_MAX
from busarm.units import check_int_range

__all__ = [
    "COMMANDS",
    "POLL_S",
    "MotorSpeedType",
    "motor",
]


POLL_S = 0.2
"""While it turns, the servo is asked for its mode this often: one that stops answering
ends the command (with an error, and the stop)."""


class MotorSpeedType(CheckedType):
    """A motor speed -1000..1000, or ``"stop"`` (None would read as a missing argument)."""

    name = "speed"

    def parse(self, text: str) -> int | str:
        if text.strip().lower() == "stop":
            return "stop"
        what = f"motor speed -{MOTOR_SPEED_MAX}..{MOTOR_SPEED_MAX}, or stop"
        return check_int_range("motor speed", parse_int(text, what),
                               -MOTOR_SPEED_MAX, MOTOR_SPEED_MAX)


@click.command(context_settings=NUMBER_ARGS)
@click.argument("servo_id", metavar="ID", type=SERVO_ID)
@click.argument("speed", metavar="SPEED|stop", type=MotorSpeedType())
@click.option("--time", "duration_s", type=RangeType("time", 0.0, 86400.0, "s"), metavar="S",
              help="Turn for S seconds, then stop  [default: until Ctrl+C]")
@click.option("--keep-turning", is_flag=True,
              help="Leave the motor turning and exit; stop it later with `busarm motor ID stop`.")
@click.option("--config", "config_name", envvar="BUSARM_ARM", default=DEFAULT_ARM,
              show_default=True, show_envvar=True,
              help="The arm whose servos are refused: a shipped name or a TOML file.")
@click.option("--arm-servo", "arm_servo", is_flag=True,
              help="Turn a servo of the arm anyway (it turns past its joint's limits).")
@pass_settings
def motor(settings: Settings, servo_id: int, speed: int | str, duration_s: float | None,
          keep_turning: bool, config_name: str, arm_servo: bool) -> None:
    """Turn servo ID continuously (motor mode) at SPEED, or `stop` it.

    SPEED is -1000..1000: the power the servo drives its motor with, not a rate (1000 =
    full power one way, -1000 the other, 0 = stopped); how fast it turns depends on the
    servo, the supply and the load. It turns until Ctrl+C (exit code 130) or --time, then
    stops (speed 0) and goes back to position mode, holding where it stopped; an error
    stops it too. `busarm motor ID stop` does the same for a motor left turning (a servo
    made limp with `torque off` stays limp). Not for a servo of the arm: in motor mode it
    turns past its joint limits.
    """
    if speed == "stop" and (keep_turning or duration_s is not None):
        raise click.UsageError("`stop` takes neither --time nor --keep-turning")
    if keep_turning and duration_s is not None:
        raise click.UsageError("give --time or --keep-turning, not both")
    port = settings.port if settings.port_given else settings.default_port(say=False)
    if settings.world(port).through_board:  # first: --arm-servo would not make it possible
        raise unsupported(Command.OR_MOTOR_MODE_WRITE)
    part = load_arm_config(config_name).servo_range_deg(servo_id)
    if isinstance(speed, int) and part is not None and not arm_servo:
        raise LimitError(f"servo {servo_id} is {part[0]} of the arm: in motor mode it would "
                         "turn past its joint's limits; --arm-servo turns it anyway")
    with settings.open_bus(check_ids=[servo_id]) as bus:
        if not isinstance(speed, int):  # stop
            settings.out.print(_stop(bus, servo_id), highlight=False, soft_wrap=True)
            return
        bus.set_motor_speed(servo_id, speed)
        if keep_turning:
            settings.out.print(f"servo {servo_id} turning at speed {speed} (motor mode); stop "
                               f"it with `busarm motor {servo_id} stop`", highlight=False,
                               soft_wrap=True)
            return
        try:  # from the start: a Ctrl+C as it is said is a stop like any other
            settings.err.print(f"servo {servo_id} turning at speed {speed} (motor mode): "
                               + ("Ctrl+C stops it" if duration_s is None
                                  else f"for {duration_s:g} s, Ctrl+C stops it"),
                               highlight=False, soft_wrap=True)
            _turn(bus, servo_id, duration_s)
        except KeyboardInterrupt as exc:  # stopped, said, and exit code 130
            settings.out.print(_stop(bus, servo_id), highlight=False, soft_wrap=True)
            raise click.Abort("interrupted") from exc
        except BaseException:
            _try_stop(bus, servo_id)  # then the error (the bus's exit sends speed 0 too)
            raise
        settings.out.print(_stop(bus, servo_id), highlight=False, soft_wrap=True)


def _turn(bus: LxServoPort, servo_id: int, duration_s: float | None) -> None:
    """Wait while the motor turns (``duration_s``, or for ever), checking the servo."""
    clock = bus.clock
    end = None if duration_s is None else clock.now() + duration_s
    while end is None or clock.now() < end:
        clock.sleep(POLL_S if end is None else max(0.0, min(POLL_S, end - clock.now())))
        bus.read_mode(servo_id)


def _stop(bus: LxServoPort, servo_id: int) -> str:
    """Out of motor mode (a limp servo is not energised: ``halt_motor``); what is true now,
    read back: where it is, whether it holds, and whether that is outside its limits."""
    halt_motor(bus, servo_id)
    at_deg = bus.read_position_deg(servo_id)
    said = (f"servo {servo_id} stopped: back in position mode, holding at {at_deg:+.1f} deg"
            if bus.read_torque(servo_id) else
            f"servo {servo_id} stopped: back in position mode at {at_deg:+.1f} deg, limp "
            f"(torque off, left off; `busarm torque on {servo_id}` makes it hold)")
    lo_deg, hi_deg = bus.read_angle_limits_deg(servo_id)
    if not lo_deg <= at_deg <= hi_deg:  # motor mode turns past them; moves cannot
        said += (f"; that is outside its angle limits {lo_deg:+.1f}..{hi_deg:+.1f} deg: a "
                 f"move within them brings it back (`busarm move {servo_id} 0`)")
    return said


def _try_stop(bus: LxServoPort, servo_id: int) -> None:
    # The bus may be what failed: the error that did is the one raised.
    with contextlib.suppress(Exception):
        bus.stop_motor(servo_id)
        bus.set_position_mode(servo_id)


COMMANDS = [motor]
