"""The servo's registers as typed calls: readings, settings, faults.

Each call reads or writes one register of the LX protocol in the user's units (degrees
from the servo's mid-point, volts, deg C), with raw-pulse variants named so.
"""

from __future__ import annotations

from collections.abc import Iterable

from busarm.bus.servo_port import ServoState
from busarm.bus.servo_wire import ServoWire
from busarm.errors import BusConflictError, ConfigError, ProtocolError
from busarm.protocol import (
    BROADCAST_ID,
    AlarmFlag,
    AngleLimitReply,
    AngleOffsetReply,
    Command,
    IdReply,
    LedCtrlReply,
    LedErrorReply,
    LoadReply,
    MoveTimeReply,
    MoveTimeWaitReply,
    TempMaxLimitReply,
    VinLimitReply,
    check_servo_id,
)
from busarm.protocol.lx_units import (
    CENTER_PULSES,
    DEG_PER_PULSE,
    offset_pulses_from_deg,
    pulses_from_deg,
)
from busarm.units import check_int_range, check_range, mv_from_v

__all__ = [
    "ServoRegisters",
    "ServoState",
]


class ServoRegisters(ServoWire):
    """Typed reads and writes of one servo's registers, on any carrier of LX commands
    (a part of ``ServoBus`` and ``BoardServoBus``)."""

    # ------------------------------------------------------------------ readings

    def read_position_pulses(self, servo_id: int) -> int:
        """Current position in pulses (signed: may read below 0 near the end stop)."""
        return self.read_values(servo_id, Command.POS_READ)[0]

    def read_position_deg(self, servo_id: int) -> float:
        return (self.read_values(servo_id, Command.POS_READ)[0] - CENTER_PULSES) * DEG_PER_PULSE

    def read_positions_deg(self, servo_ids: Iterable[int]) -> dict[int, float]:
        return {sid: self.read_position_deg(sid) for sid in servo_ids}

    def read_temp_c(self, servo_id: int) -> int:
        return self.read_values(servo_id, Command.TEMP_READ)[0]

    def read_vin_v(self, servo_id: int) -> float:
        return self.read_values(servo_id, Command.VIN_READ)[0] / 1000.0

    def read_state(self, servo_id: int) -> ServoState:
        """Position, temperature and voltage of one servo (three transactions)."""
        return ServoState(
            servo_id,
            self.read_position_deg(servo_id),
            self.read_temp_c(servo_id),
            self.read_vin_v(servo_id),
        )

    def read_states(self, servo_ids: Iterable[int]) -> list[ServoState]:
        return [self.read_state(sid) for sid in servo_ids]

    def read_move_time(self, servo_id: int) -> MoveTimeReply:
        """The last MOVE_TIME_WRITE target and time the servo received."""
        return self._read(servo_id, Command.MOVE_TIME_READ, MoveTimeReply)

    def last_target_pulses(self, servo_id: int) -> int | None:
        """Where the servo was last told to go (pulses), as it reports it."""
        return self.read_move_time(servo_id).position_pulses

    def read_move_time_wait(self, servo_id: int) -> MoveTimeWaitReply:
        """The pending MOVE_TIME_WAIT_WRITE (some servos never answer: a typed timeout)."""
        return self._read(servo_id, Command.MOVE_TIME_WAIT_READ, MoveTimeWaitReply)

    def read_id(self, servo_id: int = BROADCAST_ID) -> int:
        """ID_READ; with the broadcast ID only safe when a single servo is on the bus
        (several answering at once raise BusConflictError)."""
        try:
            return self._read(servo_id, Command.ID_READ, IdReply).reported_id
        except ProtocolError as exc:
            if servo_id != BROADCAST_ID:
                raise
            raise BusConflictError(
                f"more than one servo answered ID_READ on the broadcast ID: {exc}"
            ) from exc

    # ------------------------------------------------------------------ settings

    def set_torque(self, servo_id: int, enabled: bool) -> None:
        """Load (hold, True) or unload (limp, False) the motor."""
        check_servo_id(servo_id, allow_broadcast=True)
        self.send(servo_id, Command.LOAD_OR_UNLOAD_WRITE, int(bool(enabled)))

    def read_torque(self, servo_id: int) -> bool:
        return self._read(servo_id, Command.LOAD_OR_UNLOAD_READ, LoadReply).is_loaded

    def read_offset_deg(self, servo_id: int) -> float:
        return self._read(servo_id, Command.ANGLE_OFFSET_READ, AngleOffsetReply).offset_deg

    def adjust_offset_deg(self, servo_id: int, offset_deg: float) -> None:
        """Set the angle offset (-30..30 deg) now; lost at power off unless save_offset()."""
        check_servo_id(servo_id)
        self.send(servo_id, Command.ANGLE_OFFSET_ADJUST, offset_pulses_from_deg(offset_deg))

    def save_offset(self, servo_id: int) -> None:
        """Store the current offset so that it survives power off."""
        check_servo_id(servo_id)
        self.send(servo_id, Command.ANGLE_OFFSET_WRITE)

    def read_angle_limits_deg(self, servo_id: int) -> tuple[float, float]:
        r = self._read(servo_id, Command.ANGLE_LIMIT_READ, AngleLimitReply)
        return r.min_deg, r.max_deg

    def write_angle_limits_deg(self, servo_id: int, min_deg: float, max_deg: float) -> None:
        """The servo's own angle limits (stored): it clamps every target to them."""
        check_servo_id(servo_id)
        lo, hi = pulses_from_deg(min_deg), pulses_from_deg(max_deg)
        if lo >= hi:
            raise ConfigError(f"min_deg {min_deg:g} must be below max_deg {max_deg:g}")
        self.send(servo_id, Command.ANGLE_LIMIT_WRITE, lo, hi)

    def read_vin_limits_v(self, servo_id: int) -> tuple[float, float]:
        r = self._read(servo_id, Command.VIN_LIMIT_READ, VinLimitReply)
        return r.min_v, r.max_v

    def write_vin_limits_v(self, servo_id: int, min_v: float, max_v: float) -> None:
        """Input voltage limits (stored), 4.5..12 V: outside them the servo unloads."""
        check_servo_id(servo_id)
        check_range("min_v", min_v, 4.5, 12.0, "V")
        check_range("max_v", max_v, 4.5, 12.0, "V")
        self.send(servo_id, Command.VIN_LIMIT_WRITE, mv_from_v(min_v), mv_from_v(max_v))

    def read_temp_limit_c(self, servo_id: int) -> int:
        return self._read(servo_id, Command.TEMP_MAX_LIMIT_READ, TempMaxLimitReply).temp_max_c

    def write_temp_limit_c(self, servo_id: int, temp_max_c: int) -> None:
        """Maximum temperature (stored), 50..100 deg C: above it the servo unloads."""
        check_servo_id(servo_id)
        check_int_range("temp_max_c", temp_max_c, 50, 100)
        self.send(servo_id, Command.TEMP_MAX_LIMIT_WRITE, temp_max_c)

    def set_led(self, servo_id: int, on: bool) -> None:
        """Turn the LED on or off (stored)."""
        check_servo_id(servo_id, allow_broadcast=True)
        self.send(servo_id, Command.LED_CTRL_WRITE, 0 if on else 1)

    def read_led(self, servo_id: int) -> bool:
        """True if the LED is on."""
        return not self._read(servo_id, Command.LED_CTRL_READ, LedCtrlReply).is_led_off

    def write_alarm_mask(self, servo_id: int, alarms: AlarmFlag) -> None:
        """Which faults make the LED flash."""
        check_servo_id(servo_id, allow_broadcast=True)
        self.send(servo_id, Command.LED_ERROR_WRITE, check_int_range("alarms", alarms, 0, 7))

    def read_alarm_mask(self, servo_id: int) -> AlarmFlag:
        return self._read(servo_id, Command.LED_ERROR_READ, LedErrorReply).alarm_mask

    def read_faults(self, servo_id: int) -> AlarmFlag:
        """Faults present now, from the readings against the servo's own limits.

        OVER_TEMPERATURE if the temperature is at or above its limit, OVER_VOLTAGE if
        the input voltage is outside its limits. (No command reads a stall directly.)
        """
        flags = AlarmFlag.NONE
        if self.read_temp_c(servo_id) >= self.read_temp_limit_c(servo_id):
            flags |= AlarmFlag.OVER_TEMPERATURE
        lo, hi = self.read_vin_limits_v(servo_id)
        if not lo <= self.read_vin_v(servo_id) <= hi:
            flags |= AlarmFlag.OVER_VOLTAGE
        return flags
