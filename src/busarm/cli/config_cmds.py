"""Commands on a servo's settings: ``offset``, ``limits``, ``led``."""

from __future__ import annotations

from functools import partial

import click
from rich.table import Table

from busarm.bus.lx_port import LxServoPort
from busarm.cli.common import (
    ANGLE,
    NUMBER_ARGS,
    SERVO_ID,
    AngleType,
    CheckedType,
    RangeType,
    Settings,
    alarm_names,
    fmt,
    pass_settings,
    try_read,
)
from busarm.errors import ConfigError
from busarm.protocol import AlarmFlag
from busarm.protocol.lx_units import (
    DEG_PER_PULSE,
    OFFSET_MAX_PULSES,
    OFFSET_MIN_PULSES,
    pulses_from_deg,
)
from busarm.units import mv_from_v

__all__ = [
    "COMMANDS",
    "OFFSET",
    "VOLTAGE",
    "AlarmsType",
    "led",
    "limits",
    "offset",
]


OFFSET = AngleType(OFFSET_MIN_PULSES * DEG_PER_PULSE, OFFSET_MAX_PULSES * DEG_PER_PULSE)
VOLTAGE = RangeType("voltage", 4.5, 12.0, "V")


class AlarmsType(CheckedType):
    """Faults that make the LED flash: ``over-temperature,over-voltage,stalled`` or ``none``."""

    name = "alarms"

    def parse(self, text: str) -> AlarmFlag:
        mask = AlarmFlag.NONE
        for part in text.split(","):
            key = part.strip().lower().replace("_", "-")
            if key in ("", "none"):
                continue
            if key.isdigit() and 0 <= int(key) <= 7:
                mask |= AlarmFlag(int(key))
                continue
            names = {alarm_names(f): f for f in AlarmFlag if f}
            if key not in names:
                raise ConfigError(
                    f"unknown alarm {part.strip()!r}; allowed: {', '.join(names)}, none or 0..7"
                )
            mask |= names[key]
        return mask


@click.command(context_settings=NUMBER_ARGS)
@click.argument("servo_id", metavar="ID", type=SERVO_ID)
@click.argument("offset_deg", metavar="[DEG]", type=OFFSET, required=False)
@click.option("--save", is_flag=True, help="Store the offset so that it survives power off.")
@pass_settings
def offset(settings: Settings, servo_id: int, offset_deg: float | None, save: bool) -> None:
    """Show servo ID's angle offset, or set it to DEG (-30..30, steps of 0.24 deg).

    A new offset applies at once (the servo moves) but is lost at power off unless
    --save is given; --save alone stores the current offset.
    """
    writes = offset_deg is not None or save
    with settings.open_bus(check_ids=[servo_id] if writes else []) as bus:
        if offset_deg is not None:
            bus.adjust_offset_deg(servo_id, offset_deg)
        if save:
            bus.save_offset(servo_id)
        now = bus.read_offset_deg(servo_id)
    stored = "saved" if save else "not saved: lost at power off unless --save"
    if offset_deg is not None and abs(now - offset_deg) > 1e-6:  # the servo's resolution
        stored = (f"rounded from {offset_deg:+g} deg to the servo's steps of "
                  f"{DEG_PER_PULSE:g} deg; {stored}")
    note = f" ({stored})" if offset_deg is not None or save else ""
    settings.out.print(f"servo {servo_id} angle offset: {now:+.2f} deg{note}")


@click.command(context_settings=NUMBER_ARGS)
@click.argument("servo_id", metavar="ID", type=SERVO_ID)
@click.option("--angle", nargs=2, type=ANGLE, metavar="MIN MAX",
              help="Write the angle limits in deg, -120..120 (stored; the servo clamps targets).")
@click.option("--vin", nargs=2, type=VOLTAGE, metavar="MIN_V MAX_V",
              help="Write the input voltage limits in V, 4.5..12 (stored; outside, it unloads).")
@click.option("--temp", type=click.IntRange(50, 100), metavar="MAX_C",
              help="Write the temperature limit in deg C, 50..100 (stored; above, it unloads).")
@click.option("--force", is_flag=True,
              help="Write --vin even if the servo's present voltage is outside it.")
@pass_settings
def limits(
    settings: Settings, servo_id: int, angle: tuple[float, float] | None,
    vin: tuple[float, float] | None, temp: int | None, force: bool,
) -> None:
    """Show servo ID's angle, voltage and temperature limits, or write them.

    --vin is refused if the servo's present voltage is outside the new limits (it
    would unload at once and a loaded joint would drop), unless --force is given.
    """
    if angle is not None and pulses_from_deg(angle[0]) >= pulses_from_deg(angle[1]):
        raise click.BadParameter(f"min {angle[0]:g} must be below max {angle[1]:g} deg",
                                 param_hint="'--angle'")
    if vin is not None and mv_from_v(vin[0]) >= mv_from_v(vin[1]):
        raise click.BadParameter(f"min {vin[0]:g} must be below max {vin[1]:g} V",
                                 param_hint="'--vin'")

    def check(bus: LxServoPort, sid: int) -> None:
        if vin is None:
            bus.read_id(sid)
            return
        now = bus.read_vin_v(sid)
        if not force and not vin[0] <= now <= vin[1]:
            raise ConfigError(
                f"servo {sid} is at {now:.2f} V, outside the new limits {vin[0]:g}..{vin[1]:g} V: "
                "it would unload at once (a loaded joint would drop); --force to write anyway"
            )

    writes = angle is not None or vin is not None or temp is not None
    with settings.open_bus(check_ids=[servo_id] if writes else [], check=check) as bus:
        if angle is not None:
            bus.write_angle_limits_deg(servo_id, *angle)
        if vin is not None:
            bus.write_vin_limits_v(servo_id, *vin)
        if temp is not None:
            bus.write_temp_limit_c(servo_id, temp)
        settings.out.print(_limits_table(bus, servo_id))


def _limits_table(bus: LxServoPort, sid: int) -> Table:
    table = Table(title=f"servo {sid} limits", title_justify="left")
    table.add_column("limit")
    table.add_column("min", justify="right")
    table.add_column("max", justify="right")
    ang = try_read(partial(bus.read_angle_limits_deg, sid))
    vin = try_read(partial(bus.read_vin_limits_v, sid))
    tmax = try_read(partial(bus.read_temp_limit_c, sid))
    for name, value, spec, unit in (("angle", ang, "+.1f", "deg"), ("voltage", vin, ".2f", "V")):
        if isinstance(value, str):
            table.add_row(name, value, value)
        else:
            table.add_row(name, fmt(value[0], spec, unit), fmt(value[1], spec, unit))
    table.add_row("temperature", "", fmt(tmax, "d", "C"))
    return table


@click.command()
@click.argument("servo_id", metavar="ID", type=SERVO_ID)
@click.argument("state", type=click.Choice(["on", "off"]), required=False)
@click.option("--alarms", type=AlarmsType(),
              help="Faults that make the LED flash: any of over-temperature,over-voltage,stalled "
                   "(comma separated), or none.")
@pass_settings
def led(settings: Settings, servo_id: int, state: str | None, alarms: AlarmFlag | None) -> None:
    """Show servo ID's LED and alarm settings, or turn the LED on/off (stored)."""
    writes = state is not None or alarms is not None
    with settings.open_bus(check_ids=[servo_id] if writes else []) as bus:
        if state is not None:
            bus.set_led(servo_id, state == "on")
        if alarms is not None:
            bus.write_alarm_mask(servo_id, alarms)
        on = try_read(partial(bus.read_led, servo_id))
        mask = try_read(partial(bus.read_alarm_mask, servo_id))
    led_text = on if isinstance(on, str) else ("on" if on else "off")
    mask_text = mask if isinstance(mask, str) else alarm_names(mask)
    settings.out.print(f"servo {servo_id}: LED {led_text}, flashes on: {mask_text}")


COMMANDS = [offset, limits, led]
