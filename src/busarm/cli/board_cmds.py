"""``board info | beep | pwm``: the vendor's controller board itself (``--port board://...``).

The servos behind the board are driven by every other command with the same port; these
commands show and use what is the board's own: its battery sense, its IMU, its buttons,
its buzzer and its four PWM servo headers.
"""

from __future__ import annotations

import math

import click
from rich.table import Table

from busarm.bus.board import PWM_MAX_US, PWM_MIN_US, BoardLink
from busarm.cli.common import RangeType, Settings, pass_settings
from busarm.errors import ConfigError
from busarm.protocol.board import ImuSample
from busarm.units import check_int_range, fixed_number

__all__ = [
    "COMMANDS",
    "SAMPLE_S",
    "beep",
    "board",
    "info",
    "parse_pwm_targets",
    "pwm",
]


SAMPLE_S = 1.0
"""How long `board info` listens to the board's reports (to measure their rate)."""


@click.group()
def board() -> None:
    """The vendor's controller board: battery, IMU, buttons, buzzer, PWM servos
    (--port board://...).

    Every servo command works through the board with the same port (e.g. `busarm --port
    board:///dev/ttyACM0 arm pose`); `busarm sim serve --board` simulates one.

    Coming from the vendor's Python SDK: its bus_servo_enable_torque(id, 1) sends
    sub-command 0x0B, which the firmware runs as "unload" (serial_servo_load_unload(...,
    0)): it switches the servo's torque OFF; 0x0C switches it on. busarm names them by
    what the firmware does (`busarm torque off` sends 0x0B). See docs/board.md.
    """


@board.command()
@click.option("--time", "sample_s", type=RangeType("time", 0.1, 60.0, "s"), default=SAMPLE_S,
              show_default=True, help="How long to listen to the board's reports, in s.")
@pass_settings
def info(settings: Settings, sample_s: float) -> None:
    """What the board reports on its own: battery voltage, IMU, button presses, and how
    often it sends them."""
    with settings.open_board() as link:
        battery_v = link.read_battery_v()
        link.read_imu()
        start_reports, start_s = link.readings.reports, link.clock.now()
        samples: list[ImuSample] = []
        while link.clock.now() - start_s < sample_s:
            samples += [r for r in link.poll(0.05) if isinstance(r, ImuSample)]
        elapsed_s = link.clock.now() - start_s
        keys = link.key_events()
        pressed = ", ".join(f"key {k.key_id} {k.event.name}" for k in keys)
        table = _table(link, battery_v, samples, elapsed_s, pressed)
        reports = link.readings.reports - start_reports
    settings.out.print(table)
    settings.out.print(f"{reports} reports in {elapsed_s:.1f} s on {link.transport.name}")


def _table(link: BoardLink, battery_v: float, samples: list[ImuSample], elapsed_s: float,
           keys: str) -> Table:
    table = Table("reading", "value", title=f"controller board on {link.transport.name}")
    table.add_row("battery", f"{battery_v:.2f} V")
    if samples:
        n = len(samples)
        accel = [sum(s.accel_mps2[i] for s in samples) / n for i in range(3)]
        gyro = [sum(s.gyro_rad_s[i] for s in samples) / n for i in range(3)]
        table.add_row("IMU rate", f"{n / elapsed_s:.0f} Hz")
        table.add_row("acceleration (mean)", "  ".join(
            f"{axis} {fixed_number(a, 2)}" for axis, a in zip("xyz", accel, strict=True))
            + " m/s^2")
        table.add_row("angular rate (mean)", "  ".join(
            f"{axis} {fixed_number(math.degrees(g), 2)}" for axis, g in zip("xyz", gyro,
                                                                              strict=True))
            + " deg/s")
        roll = math.degrees(math.atan2(accel[1], accel[2]))
        pitch = math.degrees(math.atan2(-accel[0], math.hypot(accel[1], accel[2])))
        table.add_row("tilt (from gravity)",
                      f"roll {fixed_number(roll, 1)}  pitch {fixed_number(pitch, 1)} deg")
    else:
        table.add_row("IMU", f"no sample in {elapsed_s:.1f} s")
    table.add_row("buttons", keys or "no press")
    return table


@board.command()
@click.option("--freq", "freq_hz", type=RangeType("frequency", 20, 20000, "Hz"), default=2400,
              metavar="HZ", show_default=True, help="Tone in Hz.")
@click.option("--time", "on_s", type=RangeType("time", 0.01, 10.0, "s"), default=0.1,
              show_default=True, help="How long it sounds, in s.")
@pass_settings
def beep(settings: Settings, freq_hz: float, on_s: float) -> None:
    """Sound the board's buzzer once."""
    with settings.open_board() as link:
        link.beep(round(freq_hz), on_s)
    settings.out.print(f"sent the board a {round(freq_hz)} Hz beep of {on_s:g} s (it does not "
                       "acknowledge it)")


def parse_pwm_targets(texts: tuple[str, ...]) -> dict[int, int]:
    """``PORT=US`` pairs (``1=1500``) as {port: pulse us}, each checked: ConfigError naming
    the bad one and its range."""
    if not texts:
        raise ConfigError("give at least one PORT=US pair, e.g. 1=1500 (ports 1..4, "
                          f"{PWM_MIN_US}..{PWM_MAX_US} us)")
    out: dict[int, int] = {}
    for text in texts:
        port_text, sep, us_text = text.partition("=")
        if not sep or not port_text.strip().isdigit() or not us_text.strip().lstrip(
                "-").isdigit():
            raise ConfigError(f"{text!r} is not PORT=US (e.g. 1=1500: port 1..4, pulse "
                              f"{PWM_MIN_US}..{PWM_MAX_US} us)")
        port = check_int_range("PWM port", int(port_text), 1, 4)
        out[port] = check_int_range(f"PWM port {port} pulse_us", int(us_text), PWM_MIN_US,
                                    PWM_MAX_US, "us")
    return out


@board.command()
@click.argument("targets", nargs=-1, metavar="[PORT=US]...")
@click.option("--time", "time_s", type=RangeType("time", 0.0, 30.0, "s"), default=0.5,
              show_default=True, help="How long the move takes, in s.")
@pass_settings
def pwm(settings: Settings, targets: tuple[str, ...], time_s: float) -> None:
    """Hobby (PWM) servos on the board's headers 1..4: move them (`busarm board pwm
    1=1500 3=2000`: port=pulse in us, 500..2500), wait out the move, and show the
    pulse each port is driven with; with no PORT=US, only show the four."""
    wanted = parse_pwm_targets(targets) if targets else {}  # checked before the board opens
    with settings.open_board() as link:
        if wanted:
            link.pwm_move(wanted, time_s)
            link.clock.sleep(time_s)
        pulses = {port: link.pwm_read_us(port) for port in (sorted(wanted) or range(1, 5))}
    for port, pulse_us in pulses.items():
        settings.out.print(f"PWM port {port}: {pulse_us} us")


COMMANDS = [board]
