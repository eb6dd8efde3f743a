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
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import ClassVar

from busarm.errors import ConfigError
from busarm.protocol import (
    AlarmFlag,
    AngleLimitReply,
    AngleOffsetReply,
    Command,
    IdReply,
    LedCtrlReply,
    LedErrorReply,
    LoadReply,
    ModeReply,
    MoveTimeReply,
    MoveTimeWaitReply,
    PositionReply,
    Reply,
    Request,
    ServoMode,
    TempMaxLimitReply,
    TempReply,
    VinLimitReply,
    VinReply,
    check_servo_id,
)
from busarm.units import DEG_PER_PULSE, MOTOR_SPEED_MAX, POSITION_MAX_PULSES, POSITION_MIN_PULSES

FULL_TURN_PULSES = round(360.0 / DEG_PER_PULSE)
"""One full turn of the horn in pulses (1500), the period of motor-mode readings."""

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

_EPS = 1e-9
"""Pulses within which the horn counts as touching a stop (float noise, not physics)."""
_INF = math.inf


@dataclass(frozen=True)
class ServoParams:
    """Physical constants of one servo model. Defaults: the arm's 35 kg joints.

    Speeds are the vendor's nominal no-load figures at 11.1 V; the thermal figures are
    assumptions chosen so that a stalled servo trips in tens of seconds. Tests may
    shrink the times to run faster.
    """

    max_speed_s_per_60deg: float = 0.20
    """Fastest position-mode move: seconds per 60 deg (0.2 -> 300 deg/s = 1250 pulses/s)."""
    motor_deg_per_s_at_full_speed: float = 300.0
    """Motor mode: turning rate at speed 1000 (rate is proportional to speed)."""
    stall_time_s: float = 0.5
    """How long a loaded motor must be held short of its target before STALLED shows."""
    ambient_c: float = 25.0
    """Ambient temperature: power-on temperature and what an idle servo cools to."""
    thermal_time_constant_s: float = 40.0
    """Time constant of the first-order thermal model."""
    full_effort_rise_c: float = 100.0
    """Steady temperature rise above ambient at effort 1 (pushing a stop)."""
    effort_holding: float = 0.02
    """Effort (0..1) of a loaded servo holding still."""
    effort_moving: float = 0.15
    """Effort of a servo moving freely."""
    effort_stalled: float = 1.0
    """Effort of a servo pushing against an obstacle."""
    over_temp_hysteresis_c: float = 1.0
    """An over-temperature fault clears at temp_max - this (must be > 0)."""
    supply_mv: int = 11100
    """Supply voltage at power-on (a 3S pack); change it with ``SimServo.supply_mv``."""
    min_responsive_mv: int = 6000
    """Below this supply the servo stops answering and blinks (field notes)."""
    motor_wrap_min_pulses: float = -250.0
    """Lowest reading in motor mode; readings wrap into [this, this + 1500)."""
    answers_wait_read: bool = True
    """False: never answer MOVE_TIME_WAIT_READ (reported of some servos)."""

    def __post_init__(self) -> None:
        positive = (
            "max_speed_s_per_60deg", "motor_deg_per_s_at_full_speed",
            "thermal_time_constant_s", "over_temp_hysteresis_c",
        )
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"ServoParams.{name} = {value!r} must be > 0")
        non_negative = ("stall_time_s", "full_effort_rise_c")
        for name in non_negative:
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"ServoParams.{name} = {value!r} must be >= 0")
        for name in ("effort_holding", "effort_moving", "effort_stalled"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 1.0):
                raise ConfigError(f"ServoParams.{name} = {value!r} is out of range 0..1")
        if not math.isfinite(self.ambient_c):
            raise ConfigError(f"ServoParams.ambient_c = {self.ambient_c!r} must be finite")
        for name in ("supply_mv", "min_responsive_mv"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 65535:
                raise ConfigError(f"ServoParams.{name} = {value!r} is out of range 0..65535")
        # The wrapped turn must hold every position-mode angle, offsets included.
        lo = self.motor_wrap_min_pulses
        if not -375.0 <= lo <= -125.0:
            raise ConfigError(
                f"ServoParams.motor_wrap_min_pulses = {lo!r} is out of range -375..-125"
            )

    @property
    def max_speed_pulses_per_s(self) -> float:
        """Fastest position-mode speed in pulses per second."""
        return 60.0 / DEG_PER_PULSE / self.max_speed_s_per_60deg

    @property
    def motor_pulses_per_s_at_full_speed(self) -> float:
        """Motor-mode rate at speed 1000 in pulses per second."""
        return self.motor_deg_per_s_at_full_speed / DEG_PER_PULSE

    @classmethod
    def arm_35kg(cls) -> ServoParams:
        """The arm's 35 kg joint servos (the defaults)."""
        return cls()

    @classmethod
    def gripper(cls) -> ServoParams:
        """The 20 kg gripper servo: 0.18 s/60 deg nominal; smaller, so it heats faster."""
        return cls(
            max_speed_s_per_60deg=0.18,
            motor_deg_per_s_at_full_speed=60.0 / 0.18,
            thermal_time_constant_s=30.0,
        )


PARAMS_35KG = ServoParams()
"""The arm's 35 kg joint servos."""
PARAMS_20KG = ServoParams.gripper()
"""The 20 kg gripper servo."""


def _sign(x: float) -> int:
    return (x > 0) - (x < 0)


def _clamp_int(value: float, lo: int, hi: int) -> int:
    """Round half up and clamp to a wire field's range."""
    return min(hi, max(lo, math.floor(value + 0.5)))


_Handler = Callable[["SimServo", Request, float], "Reply | None"]


class SimServo:
    """One simulated bus servo (see the module docstring for the model)."""

    _HANDLERS: ClassVar[dict[Command, _Handler]]

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
        p = self.params
        if not math.isfinite(now):
            raise ConfigError(f"now = {now!r} must be finite")
        position = self._check_physical("position_pulses", position_pulses)
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
        start = _clamp_int(position, POSITION_MIN_PULSES, POSITION_MAX_PULSES)
        self._last_move = (start, 0)
        self._wait_values = (start, 0)
        self._pending: tuple[int, int] | None = None
        # Surroundings: supply, obstacles, external load.
        self._supply_mv = p.supply_mv
        self._stop_min: float | None = None
        self._stop_max: float | None = None
        self._external_effort = 0.0
        # Dynamic state.
        self._now = float(now)
        self._temp = p.ambient_c
        self._overheated = False
        self._vin_fault = not self._vin_min <= self._supply_mv <= self._vin_max
        # The drive: a straight piece of motion from (t0, p0). Set by _start_drive.
        self._t0 = self._now
        self._p0 = position
        self._dir = 0
        self._rate = 0.0
        self._span = 0.0
        self._t_end = self._now
        self._p_end = position
        self._t_arrive = self._now
        self._target = position
        self._blocked = False
        self._t_contact = _INF
        self._rest_contact = 0
        self._rest_since = _INF
        self._eff_before = 0.0
        self._eff_after = 0.0
        self._start_drive(self._now, position, 0, 0.0, 0.0, 0, _INF)
        self.horn_sensor: Callable[[], float] | None = None
        """Set by an outside physics model (the digital twin): where the horn really is,
        in physical pulses. POS_READ then reports it instead of the model's own motion,
        which becomes the command the physics follows."""

    def __repr__(self) -> str:
        return (
            f"SimServo(id={self.servo_id}, position={self.position_pulses:.1f}, "
            f"mode={self._mode.name}, loaded={self.is_loaded}, temp={self._temp:.1f}C)"
        )

    # ------------------------------------------------------------------ bus interface

    def handle(self, request: Request, now: float) -> Reply | None:
        """Apply ``request`` at time ``now``; the reply of a read command, else None.

        The request's ID is not checked: the bus routes frames (broadcast included).
        A ``now`` earlier than the last one is taken as the last one.
        """
        self.advance(now)
        return self._HANDLERS[request.command](self, request, self._now)

    def advance(self, now: float) -> None:
        """Integrate motion and temperature up to ``now`` (earlier times are ignored)."""
        t = self._now
        if not now > t:
            return
        if not math.isfinite(now):
            raise ConfigError(f"now = {now!r} must be finite")
        p = self.params
        tau = p.thermal_time_constant_s
        while True:
            self._check_thermal(t)
            # The effort is constant until the present drive piece ends (or until now).
            if t < self._t_end:
                effort, t_next = self._eff_before, min(self._t_end, now)
            else:
                effort, t_next = self._eff_after, now
            goal = p.ambient_c + effort * p.full_effort_rise_c
            temp = self._temp
            # Does the temperature cross a fault threshold inside this piece?
            if self._overheated:
                threshold = self._temp_max - p.over_temp_hysteresis_c
                crosses = goal < threshold < temp
            else:
                threshold = float(self._temp_max)
                crosses = temp < threshold < goal
            if crosses:
                t_cross = t + tau * math.log((temp - goal) / (threshold - goal))
                if t_cross <= t_next:
                    t = max(t, t_cross)
                    self._temp = threshold
                    self._set_overheated(not self._overheated, t)
                    continue
            if temp != goal:
                temp = goal + (temp - goal) * math.exp((t - t_next) / tau)
                # Snap when settled, so an idle servo skips the arithmetic above.
                self._temp = goal if abs(temp - goal) < 1e-9 else temp
            t = t_next
            if t >= now:
                break
        self._now = now
        self._check_thermal(now)  # catches a threshold met only within rounding

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

    @property
    def physical_pulses(self) -> float:
        """The horn's physical angle (logical + offset); what power-off storage keeps."""
        return self._wrap(self._phys_at(self._now))

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

    @property
    def is_loaded(self) -> bool:
        """Whether the motor gives torque: asked for, and no voltage or heat fault."""
        return self._torque_on and not (self._overheated or self._vin_fault)

    @property
    def external_effort(self) -> float:
        """Extra effort (0..1) from an outside load (gravity, a grip) while loaded."""
        return self._external_effort

    @external_effort.setter
    def external_effort(self, value: float) -> None:
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise ConfigError(f"external_effort = {value!r} is out of range 0..1")
        self._external_effort = float(value)
        self._set_efforts()

    def set_obstacle(
        self, min_pulses: float | None = None, max_pulses: float | None = None
    ) -> None:
        """Put physical stops at ``min_pulses`` and ``max_pulses`` (None: no stop there).

        Takes effect at the last advance; a horn beyond a stop is pushed onto it. A move
        in progress carries on toward its target as far as the stops let it.
        """
        stops = [
            None if s is None else self._check_physical(name, s)
            for name, s in (("min_pulses", min_pulses), ("max_pulses", max_pulses))
        ]
        lo, hi = stops
        if lo is not None and hi is not None and lo >= hi:
            raise ConfigError(f"obstacle min_pulses {lo} must be less than max_pulses {hi}")
        t = self._now
        position = self._wrap(self._phys_at(t))
        contact, since = self._contact_at(t)
        target, arrive = self._target, self._t_arrive
        self._stop_min, self._stop_max = lo, hi
        if hi is not None and position > hi + _EPS:
            position, contact, since = hi, 1, t
        elif lo is not None and position < lo - _EPS:
            position, contact, since = lo, -1, t
        self._start_drive(t, position, 0, 0.0, 0.0, contact, since)
        if self.is_loaded:
            if self._mode is ServoMode.MOTOR:
                self._restart(t)
            else:
                self._drive_to(t, target, max(0.0, arrive - t))

    def move_by_hand(self, position_pulses: float, now: float) -> None:
        """Turn the unloaded horn by hand so POS_READ reports ``position_pulses``.

        Obstacles stop the hand too. Raises ConfigError if the motor is loaded.
        """
        self.advance(now)
        if self.is_loaded:
            raise ConfigError(
                f"servo {self.servo_id} is loaded (torque on): unload it before moving it by hand"
            )
        t = self._now
        if not math.isfinite(position_pulses):
            raise ConfigError(f"position_pulses = {position_pulses!r} must be finite")
        target = self._check_physical("position_pulses + offset", position_pulses + self._offset)
        start = self._wrap(self._phys_at(t))
        contact, since = self._contact_at(t)
        direction = _sign(target - start)
        if direction == 0:
            return
        free = self._free_distance(start, direction, contact)
        if free < abs(target - start):
            end, contact, since = start + direction * free, direction, t
        else:
            end, contact, since = target, 0, _INF
        self._start_drive(t, self._wrap(end), 0, 0.0, 0.0, contact, since)

    # ------------------------------------------------------------------ motion internals

    def _check_physical(self, name: str, value: float) -> float:
        lo = self.params.motor_wrap_min_pulses
        hi = lo + FULL_TURN_PULSES
        if isinstance(value, bool) or not isinstance(value, int | float) or not (
            math.isfinite(value) and lo <= value < hi
        ):
            raise ConfigError(f"{name} = {value!r} is out of range {lo}..{hi} (one turn)")
        return float(value)

    def _wrap(self, position: float) -> float:
        lo = self.params.motor_wrap_min_pulses
        return (position - lo) % FULL_TURN_PULSES + lo

    def _phys_at(self, t: float) -> float:
        """Physical position at ``t`` (unwrapped in motor mode)."""
        if t >= self._t_end:
            return self._p_end
        return self._p0 + self._dir * self._rate * (t - self._t0)

    def _contact_at(self, t: float) -> tuple[int, float]:
        """(direction a touching stop blocks: -1, 0, +1; since when the horn pushes it)."""
        if self._blocked and t >= self._t_end:
            return self._dir, self._t_contact
        if self._span > 0 and t > self._t0:
            return 0, _INF
        return self._rest_contact, self._rest_since

    def _free_distance(self, position: float, direction: int, contact: int) -> float:
        """How far the horn can go from ``position`` in ``direction`` before a stop."""
        best = _INF
        circle = self._mode is ServoMode.MOTOR
        for stop, is_max in ((self._stop_min, False), (self._stop_max, True)):
            if stop is None:
                continue
            ahead = (stop - position) * direction
            if circle:
                ahead %= FULL_TURN_PULSES
                if ahead > FULL_TURN_PULSES - _EPS:
                    ahead = 0.0
            if abs(ahead) <= _EPS:
                # Touching: it blocks the way it was met, or by its name if unknown.
                blocks = contact == direction or (contact == 0 and is_max == (direction > 0))
                ahead = 0.0 if blocks else (FULL_TURN_PULSES if circle else _INF)
            elif ahead < 0:
                continue  # behind the horn on a line
            best = min(best, ahead)
        return best

    def _start_drive(
        self, t: float, position: float, direction: int, rate: float, reach: float,
        contact: int, since: float, target: float | None = None,
    ) -> None:
        """Start a straight piece of motion: ``reach`` pulses at ``rate`` (0: hold)."""
        self._t0 = t
        self._p0 = position
        self._rest_contact = contact
        self._rest_since = since
        if direction == 0 or rate <= 0.0 or reach <= 0.0:
            self._dir, self._rate, self._span = 0, 0.0, 0.0
            self._t_end = self._t_arrive = t
            self._p_end = self._target = position
            self._blocked = False
            self._t_contact = _INF
            self._set_efforts()
            return
        free = self._free_distance(position, direction, contact)
        span = min(reach, free)
        self._dir, self._rate, self._span = direction, rate, span
        self._blocked = free < reach
        self._t_end = t + span / rate
        self._t_arrive = t + reach / rate
        if target is None:
            target = position + direction * reach
        self._target = target
        self._p_end = position + direction * span if self._blocked else target
        if self._blocked:
            # Already pushing this way: the stall clock keeps running.
            self._t_contact = since if span == 0.0 and contact == direction else self._t_end
        else:
            self._t_contact = _INF
        self._set_efforts()

    def _set_efforts(self) -> None:
        """Effort before and after the present drive piece ends."""
        p = self.params
        if not self.is_loaded:
            self._eff_before = self._eff_after = 0.0
            return
        if self._mode is ServoMode.MOTOR:
            duty = abs(self._motor_speed) / MOTOR_SPEED_MAX
            moving = max(p.effort_holding, p.effort_moving * duty)
            pushing = max(p.effort_holding, p.effort_stalled * duty)
        else:
            moving, pushing = p.effort_moving, p.effort_stalled
        after = pushing if self._blocked else p.effort_holding
        before = moving if self._span > 0 else after
        extra = self._external_effort
        self._eff_before = min(1.0, before + extra)
        self._eff_after = min(1.0, after + extra)

    def _restart(self, t: float) -> None:
        """Replace the drive with what the present state asks for: hold, or turn."""
        position = self._wrap(self._phys_at(t))
        contact, since = self._contact_at(t)
        if self.is_loaded and self._mode is ServoMode.MOTOR and self._motor_speed != 0:
            rate = (
                abs(self._motor_speed) / MOTOR_SPEED_MAX
                * self.params.motor_pulses_per_s_at_full_speed
            )
            self._start_drive(t, position, _sign(self._motor_speed), rate, _INF, contact, since)
        else:
            self._start_drive(t, position, 0, 0.0, 0.0, contact, since)

    def _drive_to(self, t: float, target: float, duration_s: float) -> None:
        """Move (loaded, position mode) to the physical ``target`` in ``duration_s`` or more."""
        position = self._wrap(self._phys_at(t))
        contact, since = self._contact_at(t)
        # Stay within one turn (an offset change after motor mode could ask for more).
        lo = self.params.motor_wrap_min_pulses
        target = min(lo + FULL_TURN_PULSES - 1e-6, max(lo, target))
        distance = abs(target - position)
        if distance == 0.0:
            self._start_drive(t, position, 0, 0.0, 0.0, contact, since)
            return
        duration = max(duration_s, distance / self.params.max_speed_pulses_per_s)
        self._start_drive(
            t, position, _sign(target - position), distance / duration, distance,
            contact, since, target,
        )

    def _start_move(self, t: float, position_pulses: int, time_ms: int) -> None:
        """A move command: loads the motor and heads for the clamped target."""
        if self._mode is ServoMode.MOTOR:
            return
        self._torque_on = True
        if not self.is_loaded:
            return  # a fault holds the motor off; it will hold where it is on recovery
        logical = min(self._angle_max, max(self._angle_min, position_pulses))
        self._drive_to(t, logical + self._offset, time_ms / 1000.0)

    # ------------------------------------------------------------------ fault internals

    def _check_thermal(self, t: float) -> None:
        """Start or end an over-temperature fault if the temperature says so at ``t``."""
        if self._overheated:
            if self._temp <= self._temp_max - self.params.over_temp_hysteresis_c:
                self._set_overheated(False, t)
        elif self._temp >= self._temp_max:
            self._set_overheated(True, t)

    def _set_overheated(self, value: bool, t: float) -> None:
        was_loaded = self.is_loaded
        self._overheated = value
        if self.is_loaded != was_loaded:
            self._restart(t)

    def _refresh_vin(self, t: float) -> None:
        was_loaded = self.is_loaded
        self._vin_fault = not self._vin_min <= self._supply_mv <= self._vin_max
        if self.is_loaded != was_loaded:
            self._restart(t)

    # ------------------------------------------------------------------ command handlers

    def _move_time_write(self, request: Request, t: float) -> None:
        position, time_ms = request.args
        self._last_move = (position, time_ms)
        self._start_move(t, position, time_ms)

    def _move_time_read(self, request: Request, t: float) -> Reply:
        return MoveTimeReply(*self._last_move)

    def _move_time_wait_write(self, request: Request, t: float) -> None:
        position, time_ms = request.args
        self._pending = self._wait_values = (position, time_ms)

    def _move_time_wait_read(self, request: Request, t: float) -> Reply | None:
        if not self.params.answers_wait_read:
            return None
        return MoveTimeWaitReply(*self._wait_values)

    def _move_start(self, request: Request, t: float) -> None:
        if self._pending is None:
            return
        position, time_ms = self._pending
        self._pending = None
        self._last_move = (position, time_ms)
        self._start_move(t, position, time_ms)

    def _move_stop(self, request: Request, t: float) -> None:
        # Motor mode ignores it (field notes); an unloaded servo is not moving anyway.
        if self._mode is ServoMode.POSITION and self.is_loaded:
            self._restart(t)

    def _id_write(self, request: Request, t: float) -> None:
        self.servo_id = request.args[0]

    def _id_read(self, request: Request, t: float) -> Reply:
        return IdReply(self.servo_id)

    def _angle_offset_adjust(self, request: Request, t: float) -> None:
        old, new = self._offset, request.args[0]
        self._offset = new
        if self._mode is ServoMode.POSITION and self.is_loaded and new != old:
            # Same logical target, so the physical target moves by the difference.
            target = self._target + (new - old)
            self._drive_to(t, target, max(0.0, self._t_arrive - t))

    def _angle_offset_write(self, request: Request, t: float) -> None:
        self._saved_offset = self._offset

    def _angle_offset_read(self, request: Request, t: float) -> Reply:
        return AngleOffsetReply(self._offset)

    def _angle_limit_write(self, request: Request, t: float) -> None:
        self._angle_min, self._angle_max = request.args

    def _angle_limit_read(self, request: Request, t: float) -> Reply:
        return AngleLimitReply(self._angle_min, self._angle_max)

    def _vin_limit_write(self, request: Request, t: float) -> None:
        self._vin_min, self._vin_max = request.args
        self._refresh_vin(t)

    def _vin_limit_read(self, request: Request, t: float) -> Reply:
        return VinLimitReply(self._vin_min, self._vin_max)

    def _temp_max_limit_write(self, request: Request, t: float) -> None:
        self._temp_max = request.args[0]
        self._check_thermal(t)

    def _temp_max_limit_read(self, request: Request, t: float) -> Reply:
        return TempMaxLimitReply(self._temp_max)

    def _temp_read(self, request: Request, t: float) -> Reply:
        # Whole degrees, truncated: reads >= the limit exactly while the heat fault trips.
        return TempReply(min(255, max(0, math.floor(self._temp))))

    def _vin_read(self, request: Request, t: float) -> Reply:
        return VinReply(self._supply_mv)

    def _pos_read(self, request: Request, t: float) -> Reply:
        sensed = self.horn_sensor() if self.horn_sensor is not None else self._phys_at(t)
        logical = self._wrap(sensed) - self._offset
        return PositionReply(_clamp_int(logical, -32768, 32767))

    def _or_motor_mode_write(self, request: Request, t: float) -> None:
        mode, _null, speed = request.args
        new_mode = ServoMode(mode)
        self._motor_speed = speed
        if new_mode is ServoMode.POSITION and self._mode is ServoMode.POSITION:
            return  # the speed is stored but means nothing here; a move goes on
        self._mode = new_mode
        if new_mode is ServoMode.MOTOR:
            self._torque_on = True
        self._restart(t)

    def _or_motor_mode_read(self, request: Request, t: float) -> Reply:
        return ModeReply(self._mode, self._motor_speed)

    def _load_or_unload_write(self, request: Request, t: float) -> None:
        was_loaded = self.is_loaded
        self._torque_on = bool(request.args[0])
        if self.is_loaded != was_loaded:
            self._restart(t)

    def _load_or_unload_read(self, request: Request, t: float) -> Reply:
        return LoadReply(self.is_loaded)

    def _led_ctrl_write(self, request: Request, t: float) -> None:
        self._is_led_off = bool(request.args[0])

    def _led_ctrl_read(self, request: Request, t: float) -> Reply:
        return LedCtrlReply(self._is_led_off)

    def _led_error_write(self, request: Request, t: float) -> None:
        self._alarm_mask = AlarmFlag(request.args[0])

    def _led_error_read(self, request: Request, t: float) -> Reply:
        return LedErrorReply(self._alarm_mask)


SimServo._HANDLERS = {
    Command.MOVE_TIME_WRITE: SimServo._move_time_write,
    Command.MOVE_TIME_READ: SimServo._move_time_read,
    Command.MOVE_TIME_WAIT_WRITE: SimServo._move_time_wait_write,
    Command.MOVE_TIME_WAIT_READ: SimServo._move_time_wait_read,
    Command.MOVE_START: SimServo._move_start,
    Command.MOVE_STOP: SimServo._move_stop,
    Command.ID_WRITE: SimServo._id_write,
    Command.ID_READ: SimServo._id_read,
    Command.ANGLE_OFFSET_ADJUST: SimServo._angle_offset_adjust,
    Command.ANGLE_OFFSET_WRITE: SimServo._angle_offset_write,
    Command.ANGLE_OFFSET_READ: SimServo._angle_offset_read,
    Command.ANGLE_LIMIT_WRITE: SimServo._angle_limit_write,
    Command.ANGLE_LIMIT_READ: SimServo._angle_limit_read,
    Command.VIN_LIMIT_WRITE: SimServo._vin_limit_write,
    Command.VIN_LIMIT_READ: SimServo._vin_limit_read,
    Command.TEMP_MAX_LIMIT_WRITE: SimServo._temp_max_limit_write,
    Command.TEMP_MAX_LIMIT_READ: SimServo._temp_max_limit_read,
    Command.TEMP_READ: SimServo._temp_read,
    Command.VIN_READ: SimServo._vin_read,
    Command.POS_READ: SimServo._pos_read,
    Command.OR_MOTOR_MODE_WRITE: SimServo._or_motor_mode_write,
    Command.OR_MOTOR_MODE_READ: SimServo._or_motor_mode_read,
    Command.LOAD_OR_UNLOAD_WRITE: SimServo._load_or_unload_write,
    Command.LOAD_OR_UNLOAD_READ: SimServo._load_or_unload_read,
    Command.LED_CTRL_WRITE: SimServo._led_ctrl_write,
    Command.LED_CTRL_READ: SimServo._led_ctrl_read,
    Command.LED_ERROR_WRITE: SimServo._led_error_write,
    Command.LED_ERROR_READ: SimServo._led_error_read,
}
assert set(SimServo._HANDLERS) == set(Command)

__all__ = [
    "DEFAULT_ALARM_MASK",
    "FULL_TURN_PULSES",
    "PARAMS_20KG",
    "PARAMS_35KG",
    "STORED_FIELDS",
    "ServoParams",
    "SimServo",
]
