"""The seam between the LX servos' calls and whatever carries their commands.

The LX servo family's calls in the user's units (``ServoRegisters``, ``ServoMotion``) are
written once, in LX commands; two carriers, peers, take those commands to the servos:
the LX serial line (``busarm.bus.bus_core.BusCore``, in ``ServoBus``) and the vendor's
controller board (``busarm.bus.board_bus.BoardServoBus``). ``ServoWire`` is what the
calls need of a carrier, public and documented: ``send`` a write command, ``query`` or
``read_values`` a read, ``send_moves`` a synchronised move, ``emergency_stop``, ``close``.
It also keeps what every LX-family port keeps, whatever its carrier: the halt latch,
what was written, the port's clock and lock, and the context manager that stops on an
exception.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable, Mapping
from types import TracebackType
from typing import TypeVar

from busarm.bus.servo_port import ServoModel
from busarm.bus.transport import Transport
from busarm.clock import Clock
from busarm.errors import ConfigError, HaltedError
from busarm.protocol import BROADCAST_ID, SPECS, Command, Reply
from busarm.protocol.lx_units import (
    CENTER_PULSES,
    DEG_PER_PULSE,
    MOVE_TIME_MAX_MS,
    POSITION_MAX_PULSES,
    POSITION_MIN_PULSES,
)

__all__ = [
    "LX_MODEL",
    "ServoWire",
]


LX_MODEL = ServoModel("LX", DEG_PER_PULSE, CENTER_PULSES, POSITION_MIN_PULSES,
                      POSITION_MAX_PULSES, MOVE_TIME_MAX_MS / 1000.0)
"""The LX servos' scale: 0.24 deg a pulse, 500 the mid-point, 0..1000, moves up to 30 s."""

_R = TypeVar("_R", bound=Reply)
_W = TypeVar("_W", bound="ServoWire")


class ServoWire(ABC):
    """What the LX calls need of a carrier (abstract), and what every LX-family port
    keeps. The state is set by ``_init_state``, called by each carrier's constructor."""

    model: ServoModel = LX_MODEL
    transport: Transport
    clock: Clock
    _now: Callable[[], float]
    retries: int
    _lock: threading.RLock
    _limits: dict[int, tuple[float, float]]
    _spinning: set[int]  # servos this port set turning in motor mode
    _answered: set[int]  # servos that gave a valid reply on this port
    _move_ends: dict[int, float]  # servo ID -> when its last move should end
    wrote: bool
    written_ids: set[int]
    stop_sent: bool
    _unstopped: bool
    _halted: str | None
    stats: dict[str, int]

    def _init_state(self, clock: Clock, retries: int,
                    limits_deg: Mapping[int, tuple[float, float]] | None) -> None:
        """What every LX-family port keeps, whatever its carrier."""
        self.clock = clock
        self._now = clock.now  # the hot path's one clock read, bound once
        self.retries = retries
        self._lock = threading.RLock()
        self._limits = {}
        self._spinning = set()
        self._answered = set()
        self._move_ends = {}
        self.wrote = False
        """Whether a write command (one that can move or change a servo) has gone out."""
        self.written_ids = set()
        """The servos written to by ID (broadcast writes are not counted here)."""
        self.stop_sent = False
        """Whether the emergency stop has been sent."""
        self._unstopped = False  # written since the last emergency stop
        self._halted = None  # why the port is halted (``halt``), until ``rearm``
        for sid, (lo, hi) in (limits_deg or {}).items():
            self.set_limits_deg(sid, lo, hi)
        self.stats = {"retries": 0, "timeouts": 0, "bad_replies": 0}

    # ------------------------------------------------------------------ the seam

    @abstractmethod
    def send(self, servo_id: int, command: Command, *args: int) -> None:
        """Send a write command (no reply expected). ``servo_id`` may be 254 (broadcast).
        A carrier checks it first (``check_write``) and marks it written
        (``_mark_written``) before sending."""

    @abstractmethod
    def query(self, servo_id: int, command: Command) -> Reply:
        """Send a read command and return the validated, typed reply (with retries)."""

    @abstractmethod
    def read_values(self, servo_id: int, command: Command) -> tuple[int, ...]:
        """A read's reply as its wire values (the hot path of the unit-level reads)."""

    @abstractmethod
    def send_moves(self, pulses: Mapping[int, int], time_ms: int, *, use_start: bool) -> None:
        """Every servo to its target (pulses) in ``time_ms``, together (checked targets:
        the calls above have checked them). ``use_start``: queued, then started at once
        where the carrier can; else each as it is sent."""

    @abstractmethod
    def emergency_stop(self) -> None:
        """Stop everything and hold; never raises. Sets ``stop_sent``, clears
        ``_unstopped``."""

    @abstractmethod
    def close(self) -> None:
        """Release the carrier's port."""

    @abstractmethod
    def read_budget_s(self, command: Command) -> float:
        """The longest a read of ``command`` can take before it returns or raises."""

    @abstractmethod
    def wire_time_s(self, tx_bytes: int, rx_bytes: int) -> float:
        """The time the wire needs for a request and its reply of these LX sizes."""

    @abstractmethod
    def set_limits_deg(self, servo_id: int, min_deg: float, max_deg: float) -> None:
        """Software limits (``ServoMotion``'s)."""

    # ------------------------------------------------------------------ shared

    @property
    def name(self) -> str:
        """Where the port is open (its transport's name)."""
        return self.transport.name

    def check_write(self, servo_id: int, command: Command, args: tuple[int, ...]) -> None:
        """ConfigError for a read command or a broadcast ID_WRITE; HaltedError while
        halted (for anything but a stop). Nothing is sent."""
        if SPECS[command].is_read:
            raise ConfigError(f"{command.name} is a read command: use query()")
        if command is Command.ID_WRITE and servo_id == BROADCAST_ID:
            raise ConfigError(
                "refusing to broadcast ID_WRITE: it would renumber every servo on the bus"
            )
        self.check_not_halted(command, args)

    def check_not_halted(self, command: Command, args: tuple[int, ...]) -> None:
        """HaltedError if the port is halted and ``command`` is not a stop."""
        if self._halted is None or command is Command.MOVE_STOP or (
                command is Command.OR_MOTOR_MODE_WRITE and args[-1:] == (0,)):
            return
        raise HaltedError(f"{command.name} refused: the robot is halted ({self._halted}); "
                          "re-arm it first")

    def _mark_written(self, servo_ids: Iterable[int]) -> None:
        # Marked before sending: a write that fails half-way may have reached the servo.
        self.wrote = self._unstopped = True
        self.written_ids.update(sid for sid in servo_ids if sid != BROADCAST_ID)

    def _read(self, servo_id: int, command: Command, kind: type[_R]) -> _R:
        reply = self.query(servo_id, command)
        assert isinstance(reply, kind)
        return reply

    # ------------------------------------------------------------------ lifecycle

    def halt(self, why: str = "e-stop") -> None:
        """Latch an emergency stop: MOVE_STOP now (``emergency_stop``), and every later
        write but a stop raises HaltedError, from any thread, until ``rearm()``.

        A move being sent by another thread is cut short: its remaining writes (and the
        MOVE_START of a synchronised move) are refused, and a wait for a move to arrive
        ends with HaltedError. Reads go on (a halted robot can still be watched).
        """
        self._halted = why  # first: a write racing the stop below is refused, or precedes it
        self.emergency_stop()

    def rearm(self) -> None:
        """Allow writes again after ``halt`` (the servos still hold where they stopped)."""
        self._halted = None

    @property
    def halted(self) -> str | None:
        """Why the port is halted (what ``halt`` was given), or None."""
        return self._halted

    @property
    def lock(self) -> threading.RLock:
        """Held for each transaction: whoever else moves bytes on this port's transport (a
        remote client's requests, busarm.bus.zenoh_link) holds it too."""
        return self._lock

    def __enter__(self: _W) -> _W:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        try:
            if exc_type is not None and self._unstopped:
                self.emergency_stop()
        finally:
            self.close()
