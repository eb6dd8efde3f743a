"""The physics of one simulated servo: the horn's motion, its heat, and the faults that
unload it (the model is described in busarm.sim.servo).

Motion is piecewise linear, computed in closed form; the temperature is integrated
exactly between the events where the effort changes or a fault starts or ends.
"""

from __future__ import annotations

import math

from busarm.errors import ConfigError
from busarm.protocol import ServoMode
from busarm.protocol.lx_units import MOTOR_SPEED_MAX
from busarm.sim.servo_params import FULL_TURN_PULSES, ServoParams

__all__ = [
    "ServoPhysics",
]


_EPS = 1e-9
"""Pulses within which the horn counts as touching a stop (float noise, not physics)."""
_INF = math.inf


def _sign(x: float) -> int:
    return (x > 0) - (x < 0)


class ServoPhysics:
    """Motion, heat and faults of one servo (the base of ``SimServo``).

    The settings it obeys are set by ``SimServo`` and changed by its commands.
    """

    params: ServoParams
    servo_id: int
    # Settings the physics obeys.
    _offset: int
    _angle_min: int
    _angle_max: int
    _vin_min: int
    _vin_max: int
    _temp_max: int
    _mode: ServoMode
    _motor_speed: int
    _torque_on: bool
    # Surroundings: supply, obstacles, external load.
    _supply_mv: int
    _stop_min: float | None
    _stop_max: float | None
    _external_effort: float
    # Dynamic state.
    _now: float
    _temp: float
    _overheated: bool
    _vin_fault: bool
    # The drive: a straight piece of motion from (t0, p0). Set by _start_drive.
    _t0: float
    _p0: float
    _dir: int
    _rate: float
    _span: float
    _t_end: float
    _p_end: float
    _t_arrive: float
    _target: float
    _blocked: bool
    _t_contact: float
    _rest_contact: int
    _rest_since: float
    _eff_before: float
    _eff_after: float

    def _power_on_physics(self, now: float, position: float) -> None:
        """The surroundings and the horn at power-on, at time ``now``: the supply of
        ``params``, no obstacle, no load, ambient temperature, the horn at rest at the
        physical ``position``. (The settings come first: the faults read them.)"""
        p = self.params
        # Surroundings: supply, obstacles, external load.
        self._supply_mv = p.supply_mv
        self._stop_min = None
        self._stop_max = None
        self._external_effort = 0.0
        # Dynamic state.
        self._now = float(now)
        self._temp = p.ambient_c
        self._overheated = False
        self._vin_fault = not self._vin_min <= self._supply_mv <= self._vin_max
        self._start_drive(self._now, position, 0, 0.0, 0.0, 0, _INF)

    def advance(self, now: float) -> None:
        """Integrate motion and temperature up to ``now`` (earlier times are ignored)."""
        t = self._now
        if not now > t:
            return
        if not math.isfinite(now):
            raise ConfigError(f"now = {now!r} must be finite")
        if self._advance_in_one_piece(t, now):
            return
        p = self.params
        tau = p.thermal_time_constant_s
        while True:
            # _check_thermal acts only then: the call is skipped on the hot path.
            if self._overheated or self._temp >= self._temp_max:
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
        if self._overheated or self._temp >= self._temp_max:
            self._check_thermal(now)  # catches a threshold met only within rounding

    def _advance_in_one_piece(self, t: float, now: float) -> bool:
        """``advance`` from ``t`` to ``now`` where that is its loop's single pass (no
        fault, one drive piece, no threshold to cross: a twin's every tick); False,
        having changed nothing, where it is not."""
        if self._overheated or self._temp >= self._temp_max:
            return False
        if t >= self._t_end:
            effort = self._eff_after
        elif now <= self._t_end:
            effort = self._eff_before
        else:
            return False
        p = self.params
        goal = p.ambient_c + effort * p.full_effort_rise_c
        temp = self._temp
        if temp < self._temp_max < goal:
            return False  # it may cross the threshold on the way: the loop finds where
        if temp != goal:
            temp = goal + (temp - goal) * math.exp((t - now) / p.thermal_time_constant_s)
            self._temp = goal if abs(temp - goal) < 1e-9 else temp
        self._now = now
        if self._temp >= self._temp_max:
            self._check_thermal(now)  # catches a threshold met only within rounding
        return True

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
