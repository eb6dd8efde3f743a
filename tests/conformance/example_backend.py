"""An example servo family, written from docs/adding_a_backend.md alone: the "toy" servos.

A toy servo turns a full circle in 4096 pulses (2048 the mid-point), not the LX
family's 0.24 deg a pulse, and lives on an in-memory wire (``ToyWire``) that answers
requests on a simulated clock. ``ToyServoPort`` keeps the ``ServoPort`` contract on
that wire; ``open_toy_port`` is the factory the table names (one line:
``"toy": "conformance.example_backend:open_toy_port"``); ``conformance_backend`` hands
it to the suite with the wire's truth.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from types import TracebackType
from typing import Any

from busarm.bus.servo_port import ServoModel, ServoPort, ServoState, open_servo_port
from busarm.clock import Clock, SimClock
from busarm.errors import (
    BusTimeoutError,
    ConfigError,
    HaltedError,
    LimitError,
    MotionTimeoutError,
)
from busarm.units import check_range
from conformance.backends import Backend, closed_after

TOY = ServoModel("toy", deg_per_pulse=360 / 4096, center_pulses=2048, min_pulses=0,
                 max_pulses=4095, max_move_s=10.0)
TOY_IDS = (1, 2, 3, 4, 5, 10)
REQUEST_S = 0.0005
"""What one request costs on the toy wire."""


# ---------------------------------------------------------------------- the toy wire


@dataclass
class ToyServo:
    """One simulated toy servo: a move from ``start_deg`` to ``target_deg`` between
    ``t0`` and ``t1`` (linear), its torque, offset and readings."""

    start_deg: float = 0.0
    target_deg: float = 0.0
    t0: float = 0.0
    t1: float = 0.0
    torque: bool = False
    offset_deg: float = 0.0
    saved_offset_deg: float = 0.0
    silent: bool = False

    def at(self, now: float) -> float:
        if now >= self.t1 or self.t1 <= self.t0:
            return self.target_deg
        share = max(0.0, (now - self.t0) / (self.t1 - self.t0))
        return self.start_deg + share * (self.target_deg - self.start_deg)

    def go(self, now: float, target_deg: float, duration_s: float) -> None:
        self.start_deg, self.target_deg = self.at(now), target_deg
        self.t0, self.t1 = now, now + duration_s
        self.torque = True


class ToyWire:
    """Toy servos on an in-memory wire. ``request`` answers with wire values (pulses),
    or None when no servo answers; writes are answered with ``()``."""

    def __init__(self, ids: Iterable[int] = TOY_IDS) -> None:
        self.clock = SimClock()
        self.servos = {sid: ToyServo() for sid in ids}
        self.writes = 0
        self.name = "toy wire"
        self._lock = threading.Lock()

    def request(self, op: str, servo_id: int, *args: Any) -> tuple[Any, ...] | None:
        self.clock.sleep(REQUEST_S)
        with self._lock:
            now = self.clock.now()
            if op.startswith("set_") or op in ("move", "stop"):
                self.writes += 1
                for sid in self._addressed(servo_id):
                    getattr(self, f"_{op}")(self.servos[sid], now, *args)
                return ()
            servo = self.servos.get(servo_id)
            if servo is None or servo.silent:
                return None
            return getattr(self, f"_{op}")(servo, now)  # type: ignore[no-any-return]

    def _addressed(self, servo_id: int) -> list[int]:
        if servo_id == 0:  # 0: every servo
            return [sid for sid, s in self.servos.items() if not s.silent]
        servo = self.servos.get(servo_id)
        return [servo_id] if servo is not None and not servo.silent else []

    def _move(self, servo: ToyServo, now: float, pulses: int, duration_s: float) -> None:
        servo.go(now, TOY.deg_from_pulses(pulses), duration_s)

    def _stop(self, servo: ToyServo, now: float) -> None:
        if servo.torque:
            servo.go(now, servo.at(now), 0.0)

    def _set_torque(self, servo: ToyServo, now: float, on: bool) -> None:
        servo.start_deg = servo.target_deg = servo.at(now)
        servo.t0 = servo.t1 = now
        servo.torque = on

    def _set_offset(self, servo: ToyServo, now: float, offset_deg: float) -> None:
        servo.offset_deg = offset_deg

    def _set_saved_offset(self, servo: ToyServo, now: float) -> None:
        servo.saved_offset_deg = servo.offset_deg

    def _read_position(self, servo: ToyServo, now: float) -> tuple[int]:
        return (round(TOY.pulses_exact(servo.at(now))),)

    def _read_target(self, servo: ToyServo, now: float) -> tuple[int]:
        return (round(TOY.pulses_exact(servo.target_deg)),)

    def _read_torque(self, servo: ToyServo, now: float) -> tuple[bool]:
        return (servo.torque,)

    def _read_offset(self, servo: ToyServo, now: float) -> tuple[float]:
        return (servo.offset_deg,)

    def _read_limits(self, servo: ToyServo, now: float) -> tuple[float, float]:
        return (TOY.min_deg, TOY.max_deg)

    def _read_health(self, servo: ToyServo, now: float) -> tuple[int, float, int, float, float]:
        return (31, 7.4, 80, 6.0, 8.4)  # temp C, vin V, temp limit C, vin limits V


# ---------------------------------------------------------------------- the port


class ToyServoPort:
    """Toy servos on a ``ToyWire``: a ServoPort (docs/adding_a_backend.md)."""

    model = TOY

    def __init__(self, wire: ToyWire, *, timeout_s: float = 0.005, retries: int = 1) -> None:
        self.wire = wire
        self.clock: Clock = wire.clock
        self.name = wire.name
        self.timeout_s = check_range("timeout_s", timeout_s, 0.0, 1.0, "s")
        self.retries = retries
        self.wrote = False
        self.written_ids: set[int] = set()
        self._lock = threading.RLock()
        self._limits: dict[int, tuple[float, float]] = {}
        self._move_ends: dict[int, float] = {}
        self._halted: str | None = None
        self._unstopped = False
        self._closed = False

    # ------------------------------------------------------------------ the wire

    def _ask(self, op: str, servo_id: int) -> tuple[Any, ...]:
        with self._lock:
            for _ in range(self.retries + 1):
                reply = self.wire.request(op, servo_id)
                if reply is not None:
                    return reply
                self.clock.sleep(self.timeout_s)  # waited for an answer that never came
        raise BusTimeoutError(f"toy servo {servo_id} did not answer {op} within "
                              f"{self.timeout_s * 1e3:.1f} ms", servo_id=servo_id,
                              timeout_s=self.timeout_s)

    def _write(self, op: str, servo_id: int, *args: Any, is_stop: bool = False) -> None:
        if self._halted is not None and not is_stop:
            raise HaltedError(f"{op} refused: the robot is halted ({self._halted}); "
                              "re-arm it first")
        with self._lock:
            self.wrote = self._unstopped = True
            if servo_id:
                self.written_ids.add(servo_id)
            self.wire.request(op, servo_id, *args)

    # ------------------------------------------------------------------ reading

    def read_position_pulses(self, servo_id: int) -> int:
        return int(self._ask("read_position", servo_id)[0])

    def read_position_deg(self, servo_id: int) -> float:
        return TOY.deg_from_pulses(self.read_position_pulses(servo_id))

    def read_positions_deg(self, servo_ids: Iterable[int]) -> dict[int, float]:
        return {sid: self.read_position_deg(sid) for sid in servo_ids}

    def last_target_pulses(self, servo_id: int) -> int | None:
        return int(self._ask("read_target", servo_id)[0])

    def read_torque(self, servo_id: int) -> bool:
        return bool(self._ask("read_torque", servo_id)[0])

    def read_offset_deg(self, servo_id: int) -> float:
        return float(self._ask("read_offset", servo_id)[0])

    def read_angle_limits_deg(self, servo_id: int) -> tuple[float, float]:
        lo, hi = self._ask("read_limits", servo_id)
        return float(lo), float(hi)

    def read_temp_c(self, servo_id: int) -> int:
        return int(self._ask("read_health", servo_id)[0])

    def read_vin_v(self, servo_id: int) -> float:
        return float(self._ask("read_health", servo_id)[1])

    def read_temp_limit_c(self, servo_id: int) -> int:
        return int(self._ask("read_health", servo_id)[2])

    def read_vin_limits_v(self, servo_id: int) -> tuple[float, float]:
        health = self._ask("read_health", servo_id)
        return float(health[3]), float(health[4])

    def read_states(self, servo_ids: Iterable[int]) -> list[ServoState]:
        return [ServoState(sid, self.read_position_deg(sid), self.read_temp_c(sid),
                           self.read_vin_v(sid)) for sid in servo_ids]

    # ------------------------------------------------------------------ moving

    def set_limits_deg(self, servo_id: int, min_deg: float, max_deg: float) -> None:
        check_range("min_deg", min_deg, TOY.min_deg, TOY.max_deg, "deg")
        check_range("max_deg", max_deg, TOY.min_deg, TOY.max_deg, "deg")
        if min_deg >= max_deg:
            raise ConfigError(f"min_deg {min_deg:g} must be less than max_deg {max_deg:g}")
        self._limits[servo_id] = (float(min_deg), float(max_deg))

    def _checked(self, servo_id: int, angle_deg: float) -> int:
        pulses = TOY.pulses_from_deg(angle_deg)  # ConfigError outside the servo's range
        lo, hi = self._limits.get(servo_id, (TOY.min_deg, TOY.max_deg))
        if not lo <= angle_deg <= hi:
            raise LimitError(f"servo {servo_id}: target {angle_deg:g} deg is outside its "
                             f"limits {lo:g}..{hi:g} deg")
        return pulses

    def move_deg(self, servo_id: int, angle_deg: float, duration_s: float = 0.0) -> None:
        self.sync_move_deg({servo_id: angle_deg}, duration_s)

    def sync_move_deg(self, targets_deg: Mapping[int, float], duration_s: float | None = None,
                      *, speed_deg_s: float | None = None) -> float:
        if not targets_deg or (duration_s is None) == (speed_deg_s is None):
            raise ConfigError("give targets, and exactly one of duration_s or speed_deg_s")
        pulses = {sid: self._checked(sid, a) for sid, a in targets_deg.items()}
        if speed_deg_s is not None:
            check_range("speed_deg_s", speed_deg_s, 0.1, 10000.0, "deg/s")
            now = self.read_positions_deg(pulses)
            duration_s = max(abs(targets_deg[s] - now[s]) for s in pulses) / speed_deg_s
        assert duration_s is not None
        check_range("duration_s", duration_s, 0.0, TOY.max_move_s, "s")
        with self._lock:  # one after another, each a few microseconds: together enough
            for sid, p in pulses.items():
                self._write("move", sid, p, duration_s)
            end = self.clock.now() + duration_s
            self._move_ends.update(dict.fromkeys(pulses, end))
        return duration_s

    def wait_until_reached(self, targets_deg: Mapping[int, float], *,
                           tolerance_deg: float = 1.0, timeout_s: float | None = None
                           ) -> dict[int, float]:
        if timeout_s is None:
            timeout_s = max(self.move_end_s(targets_deg) - self.clock.now(), 0.0) + 2.0
        deadline = self.clock.now() + timeout_s
        while True:
            if self._halted is not None:
                raise HaltedError(f"the move was stopped: the robot is halted ({self._halted})")
            positions = self.read_positions_deg(targets_deg)
            off = [s for s, t in targets_deg.items() if abs(positions[s] - t) > tolerance_deg]
            if not off:
                return positions
            if self.clock.now() >= deadline:
                raise MotionTimeoutError(f"not within {tolerance_deg:g} deg after "
                                         f"{timeout_s:.1f} s: " + ", ".join(
                                             f"servo {s} at {positions[s]:.1f} deg, target "
                                             f"{targets_deg[s]:.1f}" for s in off))
            self.clock.sleep(0.02)

    def move_end_s(self, servo_ids: Iterable[int]) -> float:
        return max([0.0, *(self._move_ends.get(sid, 0.0) for sid in servo_ids)])

    def set_torque(self, servo_id: int, enabled: bool) -> None:
        self._write("set_torque", servo_id, bool(enabled))

    def adjust_offset_deg(self, servo_id: int, offset_deg: float) -> None:
        check_range("offset_deg", offset_deg, -30.0, 30.0, "deg")
        self._write("set_offset", servo_id, float(offset_deg))

    def save_offset(self, servo_id: int) -> None:
        self._write("set_saved_offset", servo_id)

    # ------------------------------------------------------------------ stopping

    def stop(self, servo_ids: Iterable[int] | None = None) -> None:
        for sid in [0] if servo_ids is None else list(servo_ids):
            self._write("stop", sid, is_stop=True)

    def emergency_stop(self) -> None:
        with contextlib.suppress(Exception):  # never raises: the wire may be what failed
            self._write("stop", 0, is_stop=True)
        self._unstopped = False

    def halt(self, why: str = "e-stop") -> None:
        self._halted = why  # first: a write racing the stop is refused
        self.emergency_stop()

    def rearm(self) -> None:
        self._halted = None

    @property
    def halted(self) -> str | None:
        return self._halted

    def close(self) -> None:
        self._closed = True

    def __enter__(self) -> ToyServoPort:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            if exc_type is not None and self._unstopped:
                self.emergency_stop()
        finally:
            self.close()


def open_toy_port(wire: ToyWire, **options: Any) -> ServoPort:
    """The factory the table names: toy servos on an open ``ToyWire``."""
    if not isinstance(wire, ToyWire):
        raise ConfigError(f"a toy servo port needs a ToyWire, not {type(wire).__name__}")
    return ToyServoPort(wire, **options)


@contextlib.contextmanager
def conformance_backend() -> Iterator[Backend]:
    """The toy family for the conformance suite, opened through the table."""
    wire = ToyWire()

    def silence(sid: int) -> None:
        wire.servos[sid].silent = True

    port = open_servo_port("toy", wire)
    with closed_after(Backend(
            port, TOY_IDS, truth_deg=lambda sid: wire.servos[sid].at(wire.clock.now()),
            is_loaded=lambda sid: wire.servos[sid].torque, writes=lambda: wire.writes,
            silence=silence)) as made:
        yield made
