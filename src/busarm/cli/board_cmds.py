"""``board info | beep``: the vendor's controller board itself (``--port board://...``).

The servos behind the board are driven by every other command with the same port; these
commands show and use what is the board's own: its battery sense, its IMU, its buttons
and its buzzer.
"""

from __future__ import annotations

import math

import click
from rich.table import Table

from busarm.bus.board import BoardLink
from busarm.cli.common import RangeType, Settings, pass_settings
from busarm.protocol.board import ImuSample
from busarm.units import fixed_number

__all__ = [
    "COMMANDS",
    "SAMPLE_S",
    "beep",
    "board",
    "info",
]


SAMPLE_S = 1.0
"""How long `board info` listens to the board's reports (to measure their rate)."""


@click.group()
def board() -> None:
    """The vendor's controller board: battery, IMU, buttons, buzzer (--port board://...).

    Every servo command works through the board with the same port (e.g. `busarm --port
    board:///dev/ttyACM0 arm pose`); `busarm sim serve --board` simulates one.
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


COMMANDS = [board]
