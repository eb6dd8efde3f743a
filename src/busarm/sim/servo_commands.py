"""The LX protocol as one simulated servo answers it: a handler per command, on typed
``Request``/``Reply`` objects (the bus around the servo does the bytes).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import ClassVar

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
)
from busarm.protocol.lx_units import POSITION_MAX_PULSES, POSITION_MIN_PULSES
from busarm.sim.servo_physics import ServoPhysics

__all__ = [
    "ServoCommands",
]


def _clamp_int(value: float, lo: int, hi: int) -> int:
    """Round half up and clamp to a wire field's range."""
    return min(hi, max(lo, math.floor(value + 0.5)))


_Handler = Callable[["ServoCommands", Request, float], "Reply | None"]


class ServoCommands(ServoPhysics):
    """What each command does to one servo (a part of ``SimServo``)."""

    _HANDLERS: ClassVar[dict[Command, _Handler]]
    _saved_offset: int
    _is_led_off: bool
    _alarm_mask: AlarmFlag
    _last_move: tuple[int, int]  # what MOVE_TIME_READ reports
    _wait_values: tuple[int, int]  # what MOVE_TIME_WAIT_READ reports
    _pending: tuple[int, int] | None  # the move MOVE_START starts
    horn_sensor: Callable[[], float] | None
    """Set by an outside physics model (the digital twin): where the horn really is,
    in physical pulses. POS_READ then reports it instead of the model's own motion,
    which becomes the command the physics follows."""

    def _power_on_moves(self, position: float) -> None:
        """The move registers at power-on: the horn's ``position``, no time, none pending."""
        start = _clamp_int(position, POSITION_MIN_PULSES, POSITION_MAX_PULSES)
        self._last_move = (start, 0)
        self._wait_values = (start, 0)
        self._pending = None

    def handle(self, request: Request, now: float) -> Reply | None:
        """Apply ``request`` at time ``now``; the reply of a read command, else None.

        The request's ID is not checked: the bus routes frames (broadcast included).
        A ``now`` earlier than the last one is taken as the last one.
        """
        self.advance(now)
        return self._HANDLERS[request.command](self, request, self._now)

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


ServoCommands._HANDLERS = {
    Command.MOVE_TIME_WRITE: ServoCommands._move_time_write,
    Command.MOVE_TIME_READ: ServoCommands._move_time_read,
    Command.MOVE_TIME_WAIT_WRITE: ServoCommands._move_time_wait_write,
    Command.MOVE_TIME_WAIT_READ: ServoCommands._move_time_wait_read,
    Command.MOVE_START: ServoCommands._move_start,
    Command.MOVE_STOP: ServoCommands._move_stop,
    Command.ID_WRITE: ServoCommands._id_write,
    Command.ID_READ: ServoCommands._id_read,
    Command.ANGLE_OFFSET_ADJUST: ServoCommands._angle_offset_adjust,
    Command.ANGLE_OFFSET_WRITE: ServoCommands._angle_offset_write,
    Command.ANGLE_OFFSET_READ: ServoCommands._angle_offset_read,
    Command.ANGLE_LIMIT_WRITE: ServoCommands._angle_limit_write,
    Command.ANGLE_LIMIT_READ: ServoCommands._angle_limit_read,
    Command.VIN_LIMIT_WRITE: ServoCommands._vin_limit_write,
    Command.VIN_LIMIT_READ: ServoCommands._vin_limit_read,
    Command.TEMP_MAX_LIMIT_WRITE: ServoCommands._temp_max_limit_write,
    Command.TEMP_MAX_LIMIT_READ: ServoCommands._temp_max_limit_read,
    Command.TEMP_READ: ServoCommands._temp_read,
    Command.VIN_READ: ServoCommands._vin_read,
    Command.POS_READ: ServoCommands._pos_read,
    Command.OR_MOTOR_MODE_WRITE: ServoCommands._or_motor_mode_write,
    Command.OR_MOTOR_MODE_READ: ServoCommands._or_motor_mode_read,
    Command.LOAD_OR_UNLOAD_WRITE: ServoCommands._load_or_unload_write,
    Command.LOAD_OR_UNLOAD_READ: ServoCommands._load_or_unload_read,
    Command.LED_CTRL_WRITE: ServoCommands._led_ctrl_write,
    Command.LED_CTRL_READ: ServoCommands._led_ctrl_read,
    Command.LED_ERROR_WRITE: ServoCommands._led_error_write,
    Command.LED_ERROR_READ: ServoCommands._led_error_read,
}
assert set(ServoCommands._HANDLERS) == set(Command)
