"""Moving servos: software limits, timed and synchronised moves, stops, the wait for
arrival, and motor (continuous rotation) mode.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from busarm.bus.servo_registers import ServoRegisters
from busarm.errors import (
    BusTimeoutError,
    ConfigError,
    HaltedError,
    LimitError,
    MotionTimeoutError,
    ProtocolError,
)
from busarm.protocol import BROADCAST_ID, Command, ModeReply, ServoMode, check_servo_id
from busarm.protocol.lx_units import (
    MOTOR_SPEED_MAX,
    MOVE_TIME_MAX_MS,
    deg_from_pulses,
    ms_from_s,
    pulses_from_deg,
)
from busarm.units import check_int_range, check_range

__all__ = [
    "WAIT_SLACK_S",
    "ServoMotion",
]


WAIT_SLACK_S = 2.0
"""wait_until_reached's default allowance beyond the end of the commanded move."""


class ServoMotion(ServoRegisters):
    """Moves and their limits, the wait for them, and motor mode, on any carrier of LX
    commands (a part of ``ServoBus`` and ``BoardServoBus``)."""

    # ------------------------------------------------------------------ limits

    def set_limits_deg(self, servo_id: int, min_deg: float, max_deg: float) -> None:
        """Software limits: moves outside [min_deg, max_deg] raise LimitError, sending nothing."""
        check_servo_id(servo_id)
        check_range("min_deg", min_deg, -120.0, 120.0, "deg")
        check_range("max_deg", max_deg, -120.0, 120.0, "deg")
        if min_deg >= max_deg:
            raise ConfigError(f"min_deg {min_deg} must be less than max_deg {max_deg}")
        self._limits[servo_id] = (float(min_deg), float(max_deg))

    def _check_target(self, servo_id: int, angle_deg: float) -> int:
        check_servo_id(servo_id)
        pulses = pulses_from_deg(angle_deg)
        lim = self._limits.get(servo_id)
        if lim is not None and not lim[0] <= angle_deg <= lim[1]:
            raise LimitError(
                f"servo {servo_id}: target {angle_deg:g} deg is outside its limits "
                f"{lim[0]:g}..{lim[1]:g} deg"
            )
        return pulses

    # ------------------------------------------------------------------ motion

    def move_pulses(self, servo_id: int, position_pulses: int, move_time_ms: int = 0) -> None:
        """MOVE_TIME_WRITE in wire units: go to ``position_pulses`` over ``move_time_ms``."""
        check_servo_id(servo_id)
        check_int_range("position_pulses", position_pulses, 0, 1000)
        self._check_target(servo_id, deg_from_pulses(position_pulses))
        self.send(servo_id, Command.MOVE_TIME_WRITE, position_pulses, move_time_ms)
        self._moving_until((servo_id,), move_time_ms / 1000.0)

    def move_deg(self, servo_id: int, angle_deg: float, duration_s: float = 0.0) -> None:
        """Move to ``angle_deg`` (from the mid-point) at uniform speed over ``duration_s``."""
        pulses = self._check_target(servo_id, angle_deg)
        time_ms = ms_from_s(duration_s)
        self.send(servo_id, Command.MOVE_TIME_WRITE, pulses, time_ms)
        self._moving_until((servo_id,), time_ms / 1000.0)

    def move_at_speed_deg(self, servo_id: int, angle_deg: float, speed_deg_s: float) -> float:
        """Move at no more than ``speed_deg_s``; returns the move's duration in seconds."""
        return self.sync_move_deg({servo_id: angle_deg}, speed_deg_s=speed_deg_s, use_start=False)

    def sync_move_deg(
        self,
        targets_deg: Mapping[int, float],
        duration_s: float | None = None,
        *,
        speed_deg_s: float | None = None,
        use_start: bool = True,
    ) -> float:
        """Move several servos so that they start and arrive together.

        Give ``duration_s``, or ``speed_deg_s`` (the fastest joint's speed; the
        duration then comes from the largest move, read from the servos). Every target
        is checked before anything is sent. Each servo gets MOVE_TIME_WAIT_WRITE, then
        one broadcast MOVE_START starts them all. Returns the duration in seconds.
        """
        if not targets_deg:
            raise ConfigError("sync_move_deg needs at least one target")
        if (duration_s is None) == (speed_deg_s is None):
            raise ConfigError("give exactly one of duration_s or speed_deg_s")
        pulses = {sid: self._check_target(sid, a) for sid, a in targets_deg.items()}
        if speed_deg_s is not None:
            check_range("speed_deg_s", speed_deg_s, 0.1, 10000.0, "deg/s")
            current = self.read_positions_deg(pulses)
            largest = max(abs(targets_deg[sid] - current[sid]) for sid in pulses)
            duration_s = largest / speed_deg_s
            if duration_s > MOVE_TIME_MAX_MS / 1000.0:
                # Capping the time would move faster than the user's speed limit.
                raise ConfigError(
                    f"a {largest:.1f} deg move at {speed_deg_s:g} deg/s takes {duration_s:.1f} s, "
                    f"more than the servo's 30 s maximum: raise the speed or split the move"
                )
        assert duration_s is not None
        time_ms = ms_from_s(duration_s)
        self.send_moves(pulses, time_ms, use_start=use_start)
        self._moving_until(pulses, time_ms / 1000.0)
        return time_ms / 1000.0

    def stop(self, servo_ids: Iterable[int] | None = None) -> None:
        """MOVE_STOP: stop moving and hold position (all servos if none given)."""
        if servo_ids is None:
            self.send(BROADCAST_ID, Command.MOVE_STOP)
            return
        ids = [check_servo_id(s) for s in servo_ids]
        for sid in ids:
            self.send(sid, Command.MOVE_STOP)

    def wait_until_reached(
        self,
        targets_deg: Mapping[int, float],
        *,
        tolerance_deg: float = 1.0,
        timeout_s: float | None = None,
        poll_s: float = 0.02,
    ) -> dict[int, float]:
        """Poll positions until every servo is within ``tolerance_deg`` of its target.

        Returns the last positions; raises MotionTimeoutError naming the servos that
        did not get there within ``timeout_s`` (default: until the longest move this
        bus commanded to them should have ended, plus WAIT_SLACK_S).
        """
        check_range("tolerance_deg", tolerance_deg, 0.0, 240.0, "deg")
        if timeout_s is None:
            timeout_s = max(self.move_end_s(targets_deg) - self._now(), 0.0) + WAIT_SLACK_S
        check_range("timeout_s", timeout_s, 0.0, 3600.0, "s")
        check_range("poll_s", poll_s, 0.0, 10.0, "s")
        for sid in targets_deg:
            check_servo_id(sid)
        deadline = self._now() + timeout_s
        while True:
            if self._halted is not None:  # the move was stopped: it will never arrive
                raise HaltedError(f"the move was stopped: the robot is halted ({self._halted})")
            positions = self.read_positions_deg(targets_deg)
            off = {s: positions[s] - t for s, t in targets_deg.items()
                   if abs(positions[s] - t) > tolerance_deg}
            if not off:
                return positions
            if self._now() >= deadline:
                detail = ", ".join(
                    f"servo {s} at {positions[s]:.1f} deg, target {targets_deg[s]:.1f}"
                    + ("" if self._is_loaded(s) else
                       " (torque off: it unloaded; check its voltage and temperature limits)")
                    for s in off
                )
                raise MotionTimeoutError(
                    f"not within {tolerance_deg:g} deg after {timeout_s:.1f} s: {detail}"
                )
            self.clock.sleep(poll_s)

    def move_end_s(self, servo_ids: Iterable[int]) -> float:
        """When (on the bus's clock) the last move this bus commanded to any of
        ``servo_ids`` should end; 0.0 if it commanded none."""
        return max([0.0, *(self._move_ends.get(sid, 0.0) for sid in servo_ids)])

    def _is_loaded(self, servo_id: int) -> bool:
        try:
            return self.read_torque(servo_id)
        except (BusTimeoutError, ProtocolError):
            return True  # unknown: say nothing

    def _moving_until(self, servo_ids: Iterable[int], duration_s: float) -> None:
        end = self._now() + duration_s
        for sid in servo_ids:
            self._move_ends[sid] = end

    # ------------------------------------------------------------------ motor mode

    def set_motor_speed(self, servo_id: int, speed: int) -> None:
        """Motor (continuous rotation) mode at ``speed`` -1000..1000; 0 stops the motor."""
        check_servo_id(servo_id, allow_broadcast=True)
        check_int_range("speed", speed, -MOTOR_SPEED_MAX, MOTOR_SPEED_MAX)
        self.send(servo_id, Command.OR_MOTOR_MODE_WRITE, int(ServoMode.MOTOR), 0, speed)
        if speed:
            self._spinning.add(servo_id)
        else:
            self._spinning.discard(servo_id)

    def stop_motor(self, servo_id: int) -> None:
        """Stop a servo in motor mode (speed 0: MOVE_STOP does not stop a motor)."""
        self.set_motor_speed(servo_id, 0)

    def set_position_mode(self, servo_id: int) -> None:
        """Back to position control (holds where the motor stopped)."""
        check_servo_id(servo_id, allow_broadcast=True)
        self.send(servo_id, Command.OR_MOTOR_MODE_WRITE, int(ServoMode.POSITION), 0, 0)
        self._spinning.discard(servo_id)

    def read_mode(self, servo_id: int) -> ModeReply:
        return self._read(servo_id, Command.OR_MOTOR_MODE_READ, ModeReply)
