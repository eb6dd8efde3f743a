"""The firmware of one simulated LX bus servo: settings, motion, limits, faults.

``SimServo`` works on typed ``Request``/``Reply`` objects (the bus around it does the
bytes) and on an explicit, never decreasing clock: every call takes ``now`` in seconds.
Nothing sleeps; motion and temperature are integrated up to ``now`` when asked.

The model
---------
Positions. The horn's *physical* angle (the potentiometer, in pulses) is what moves;
``POS_READ`` reports the *logical* position = physical - offset, rounded. In position
mode the physical angle stays on a line; in motor mode it turns freely and is reported
wrapped into one turn of ``FULL_TURN_PULSES`` (1500 pulses = 360 deg) starting at
``ServoParams.motor_wrap_min_pulses`` (-250: the 120 deg blind zone of the
potentiometer split evenly past both ends, so a read near 0 can be negative, as on
real servos).

Position mode. ``MOVE_TIME_WRITE(pos, time_ms)`` clamps ``pos`` to the angle limits
and moves at uniform speed from the present position so as to arrive after
``time_ms``, but never faster than ``ServoParams.max_speed_s_per_60deg`` (``time_ms``
0 means as fast as it can). A move command loads the motor (torque on).
``MOVE_TIME_READ`` returns the last move as written (unclamped); a move started by
``MOVE_START`` counts as written. ``MOVE_TIME_WAIT_WRITE`` only stores a pending
move, ``MOVE_START`` starts it from wherever the servo is then (and does nothing if
none is pending), ``MOVE_TIME_WAIT_READ`` returns the last values stored (or no reply
at all with ``answers_wait_read=False``; some real servos never answer it).
``MOVE_STOP`` holds the present position (the motor stays loaded). Move commands in
motor mode are recorded for ``MOVE_TIME_READ`` but do nothing else. Changing the angle
limits does not move the servo; they apply to later targets.

Offsets. ``ANGLE_OFFSET_ADJUST`` changes the offset at once; a loaded servo in
position mode keeps its logical target, so the horn turns (at up to full speed) by
the difference. An unloaded horn stays where it is, so the reading shifts instead.
``ANGLE_OFFSET_WRITE`` saves the present offset for the next power-on.

Motor mode. ``OR_MOTOR_MODE_WRITE(1, _, speed)`` loads the motor and turns it
continuously at ``speed / 1000 * motor_deg_per_s_at_full_speed``; speed 0 stops it.
``MOVE_STOP`` does not stop it (field notes). Switching back to position mode holds
the present (wrapped) position, even outside the angle limits, which only bind new
targets.

Torque. Power-on: position mode, speed 0, unloaded (the manual's defaults).
``LOAD_OR_UNLOAD_WRITE`` turns torque on or off; an unloaded servo ignores motion
commands except that a move command loads it again. ``move_by_hand`` turns an
unloaded horn (teaching).

Faults. Supply voltage outside the VIN limits (inclusive) unloads the motor and
raises ``OVER_VOLTAGE``; temperature at or above the limit unloads it and raises
``OVER_TEMPERATURE``. While a fault lasts, commands are still recorded and a move
still asks for torque, but nothing moves. When every fault has cleared, a servo that
had torque asked for re-enters the working state (manual point 16): it reloads and
holds where it is (in motor mode it resumes its set speed). The manual only says
"below" the limit for recovery; the model wants ``over_temp_hysteresis_c`` below it
(1 C by default, what a whole-degree reading implies), which also keeps it from
chattering. ``STALLED`` is active while a loaded motor pushes against an obstacle
(``set_obstacle``) that stops it short of its target (or, in motor mode, at all) for
at least ``stall_time_s``. The LED blinks when ``active_faults & alarm_mask`` is not
empty, whatever ``LED_CTRL`` says, and below ``min_responsive_mv`` (where the servo
also stops answering, per the field notes).

Heat. First order: dT/dt = (ambient + effort * full_effort_rise_c - T) / tau, with
effort 0 unloaded, ``effort_holding`` holding, ``effort_moving`` moving and
``effort_stalled`` pushing against an obstacle (motor mode: scaled by |speed| / 1000,
never below holding), plus ``external_effort`` (a load torque a physics model may
set) while loaded, capped at 1. With the defaults a servo held against an obstacle
reaches 85 C after about 37 s.

Integration. Motion is piecewise linear, computed in closed form; the temperature is
integrated exactly between the events where the effort changes (a move ends, the horn
meets an obstacle) or a fault starts or ends, so any time step gives the same
answer, and a step where nothing happens costs one exponential.

Obstacles are two stops in physical pulses (``set_obstacle(min, max)``); a horn found
beyond one is pushed onto it. In motor mode the stops sit on the circle, so a single
stop catches the horn from either side.

Not modelled: acceleration and overshoot, speed sagging with load or supply voltage,
gravity (unless ``external_effort`` is set), the firmware's real stall protection
(the model keeps pushing and lets the heat cut in), the offset move's exact timing,
a horn turned by hand across the blind zone, brown-out resets, EEPROM wear. Every
command is applied whatever its ID: routing, broadcast and silence below 6 V are the
bus's job (``is_responsive``).

The parts: the physical constants (``ServoParams``, busarm.sim.servo_params), the
motion, heat and faults (busarm.sim.servo_physics) and the command handlers
(busarm.sim.servo_commands); ``SimServo`` here holds the settings, powers on, and shows
the state.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from busarm.errors import ConfigError
from busarm.protocol import AlarmFlag, ServoMode, check_servo_id
from busarm.protocol.lx_units import POSITION_MAX_PULSES, POSITION_MIN_PULSES
from busarm.sim.servo_commands import ServoCommands
from busarm.sim.servo_params import FULL_TURN_PULSES, ServoParams

# Power-on values of the saved settings, from the manual (Table 4 and points 7-28).
DEFAULT_SERVO_ID = 1
DEFAULT_OFFSET_PULSES = 0
DEFAULT_ANGLE_MIN_PULSES = POSITION_MIN_PULSES
DEFAULT_ANGLE_MAX_PULSES = POSITION_MAX_PULSES
DEFAULT_VIN_MIN_MV = 6500
"""The manual's "6500v" means 6500 mV (field notes)."""
DEFAULT_VIN_MAX_MV = 12000
DEFAULT_TEMP_MAX_C = 85
DEFAULT_IS_LED_OFF = False
DEFAULT_ALARM_MASK = AlarmFlag.OVER_TEMPERATURE | AlarmFlag.OVER_VOLTAGE | AlarmFlag.STALLED
"""7: every fault blinks the LED. Volatile: the manual does not say LED_ERROR is saved."""

STORED_FIELDS: tuple[str, ...] = (
    "id", "offset_pulses", "min_pulses", "max_pulses", "min_mv", "max_mv", "temp_max_c",
    "is_led_off",
)
"""Keys of ``SimServo.stored_fields()``: exactly what the manual saves on power-off."""

# Ranges of the saved settings (the protocol's request ranges).
_STORED_RANGES: dict[str, tuple[int, int]] = {
    "id": (0, 253), "offset_pulses": (-125, 125), "min_pulses": (0, 1000),
    "max_pulses": (0, 1000), "min_mv": (4500, 12000), "max_mv": (4500, 12000),
    "temp_max_c": (50, 100), "is_led_off": (0, 1),
}


class SimServo(ServoCommands):
    """One simulated bus servo (see the module docstring for the model)."""

    def __init__(
        self,
        servo_id: int,
        *,
        params: ServoParams | None = None,
        position_pulses: float = 500.0,
        now: float = 0.0,
    ) -> None:
        """A servo just powered on at time ``now`` with its horn at ``position_pulses``.

        ``position_pulses`` is the physical horn angle (with the power-on offset of 0 it
        is also what POS_READ reports).
        """
        self.servo_id = check_servo_id(servo_id)
        self.params = params if params is not None else ServoParams()
        if not math.isfinite(now):
            raise ConfigError(f"now = {now!r} must be finite")
        position = self._check_physical("position_pulses", position_pulses)
        self._power_on_settings()
        self._power_on_moves(position)
        self._power_on_physics(now, position)
        self.horn_sensor = None

    def _power_on_settings(self) -> None:
        """The settings at power-on: the saved ones at their defaults (until ``from_stored``
        sets them), the volatile ones the manual's: position mode, speed 0, unloaded."""
        # Saved settings (survive power-off).
        self._saved_offset = DEFAULT_OFFSET_PULSES
        self._angle_min = DEFAULT_ANGLE_MIN_PULSES
        self._angle_max = DEFAULT_ANGLE_MAX_PULSES
        self._vin_min = DEFAULT_VIN_MIN_MV
        self._vin_max = DEFAULT_VIN_MAX_MV
        self._temp_max = DEFAULT_TEMP_MAX_C
        self._is_led_off = DEFAULT_IS_LED_OFF
        # Volatile settings (lost at power-off).
        self._offset = DEFAULT_OFFSET_PULSES
        self._alarm_mask = DEFAULT_ALARM_MASK
        self._mode = ServoMode.POSITION
        self._motor_speed = 0
        self._torque_on = False

    def __repr__(self) -> str:
        return (
            f"SimServo(id={self.servo_id}, position={self.position_pulses:.1f}, "
            f"mode={self._mode.name}, loaded={self.is_loaded}, temp={self._temp:.1f}C)"
        )

    def is_responsive(self, now: float) -> bool:
        """Whether the servo answers at all: not below ``min_responsive_mv`` (about 6 V).

        ``now`` is accepted for models where this depends on time; this one does not.
        """
        return self._supply_mv >= self.params.min_responsive_mv

    def stored_fields(self) -> dict[str, int]:
        """The settings saved on power-off (keys: ``STORED_FIELDS``)."""
        return {
            "id": self.servo_id,
            "offset_pulses": self._saved_offset,
            "min_pulses": self._angle_min,
            "max_pulses": self._angle_max,
            "min_mv": self._vin_min,
            "max_mv": self._vin_max,
            "temp_max_c": self._temp_max,
            "is_led_off": int(self._is_led_off),
        }

    @classmethod
    def from_stored(
        cls,
        stored: Mapping[str, float],
        *,
        params: ServoParams | None = None,
        position_pulses: float = 500.0,
        now: float = 0.0,
    ) -> SimServo:
        """A servo powered on with saved settings and its horn at ``position_pulses``.

        ``position_pulses`` is the physical angle (the horn stays where it was at
        power-off); with a saved offset, POS_READ reports it minus the offset.
        Raises ConfigError for a missing, unknown or out-of-range field.
        """
        missing = [k for k in STORED_FIELDS if k not in stored]
        unknown = sorted(k for k in stored if k not in _STORED_RANGES)
        if missing or unknown:
            raise ConfigError(
                f"stored servo fields: missing {missing}, unknown {unknown}; "
                f"expected exactly {list(STORED_FIELDS)}"
            )
        values: dict[str, int] = {}
        for key, (lo, hi) in _STORED_RANGES.items():
            raw = stored[key]
            if (
                isinstance(raw, bool) or not isinstance(raw, int | float)
                or not float(raw).is_integer() or not lo <= raw <= hi
            ):
                raise ConfigError(
                    f"stored servo field {key} = {raw!r} is not an integer {lo}..{hi}"
                )
            values[key] = int(raw)
        for lo_key, hi_key in (("min_pulses", "max_pulses"), ("min_mv", "max_mv")):
            if values[lo_key] >= values[hi_key]:
                raise ConfigError(
                    f"stored servo fields: {lo_key} {values[lo_key]} must be less than "
                    f"{hi_key} {values[hi_key]}"
                )
        servo = cls(values["id"], params=params, position_pulses=position_pulses, now=now)
        servo._saved_offset = servo._offset = values["offset_pulses"]
        servo._angle_min, servo._angle_max = values["min_pulses"], values["max_pulses"]
        servo._vin_min, servo._vin_max = values["min_mv"], values["max_mv"]
        servo._temp_max = values["temp_max_c"]
        servo._is_led_off = bool(values["is_led_off"])
        servo._refresh_vin(servo._now)
        return servo

    # ------------------------------------------------------------------ inspection

    @property
    def position_pulses(self) -> float:
        """The logical position POS_READ would report (unrounded), as of the last advance."""
        return self._wrap(self._phys_at(self._now)) - self._offset

    def setpoint_pulses_at(self, t: float) -> float:
        """The logical position the firmware's move profile has at ``t`` (where it is
        taking the horn then; a recorder's action), as of the last command."""
        return self._wrap(self._phys_at(t)) - self._offset

    @property
    def offset_pulses(self) -> float:
        """The angle offset in use (physical = logical + offset)."""
        return float(self._offset)

    @property
    def physical_pulses(self) -> float:
        """The horn's physical angle (logical + offset); what power-off storage keeps."""
        # _wrap(_phys_at(_now)) inline: a twin reads it for every servo at every tick.
        t = self._now
        position = (self._p_end if t >= self._t_end
                    else self._p0 + self._dir * self._rate * (t - self._t0))
        lo = self.params.motor_wrap_min_pulses
        return (position - lo) % FULL_TURN_PULSES + lo

    @property
    def temperature_c(self) -> float:
        """Internal temperature, as of the last advance."""
        return self._temp

    @temperature_c.setter
    def temperature_c(self, value: float) -> None:
        """Force the temperature (fault injection); takes effect at the last advance."""
        if not math.isfinite(value):
            raise ConfigError(f"temperature_c = {value!r} must be finite")
        self._temp = float(value)
        self._check_thermal(self._now)

    @property
    def active_faults(self) -> AlarmFlag:
        """Faults present now (whether or not the alarm mask lets them blink the LED)."""
        flags = AlarmFlag.NONE
        if self._overheated:
            flags |= AlarmFlag.OVER_TEMPERATURE
        if self._vin_fault:
            flags |= AlarmFlag.OVER_VOLTAGE
        if self._blocked and self._now - self._t_contact >= self.params.stall_time_s:
            flags |= AlarmFlag.STALLED
        return flags

    @property
    def is_led_blinking(self) -> bool:
        """The LED alarm: a fault the mask selects, or a supply too low to run on."""
        if self._supply_mv < self.params.min_responsive_mv:
            return True
        return bool(self.active_faults & self._alarm_mask)

    @property
    def supply_mv(self) -> int:
        """Supply voltage in mV (what VIN_READ reports)."""
        return self._supply_mv

    @supply_mv.setter
    def supply_mv(self, value: int) -> None:
        """Change the supply; takes effect at the last advance."""
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 65535:
            raise ConfigError(f"supply_mv = {value!r} is out of range 0..65535")
        self._supply_mv = value
        self._refresh_vin(self._now)


__all__ = [
    "DEFAULT_ALARM_MASK",
    "STORED_FIELDS",
    "SimServo",
]
