"""The servos behind the vendor's controller board: the ``board`` servo port.

``BoardServoBus`` is a peer of ``ServoBus`` (the LX line), not its subclass: both are
``LxServoPort``s (busarm.bus.lx_port) sharing the LX calls in the user's units (moves,
reads, limits, torque, offsets, the halt) over the carrier seam
(busarm.bus.servo_wire.ServoWire), which this one implements on a ``BoardLink``
(``send``, ``query``, ``read_values``, ``send_moves``, ``emergency_stop``). So ``Arm``,
``Robot`` and every command take ``--port board://...`` unchanged. Differences, by the
board's design:

- A synchronised move is one multi-servo move frame (sub-command 0x01); the board sends
  each servo its move at once, so there is no queued MOVE_TIME_WAIT_WRITE/MOVE_START.
- Torque off is sub-command 0x0B and torque on 0x0C, as the firmware means them (the
  vendor's Python SDK has the names the other way round).
- What the board cannot pass to the servos raises UnsupportedError before anything is
  sent: motor mode, the servos' LEDs and alarm masks, MOVE_TIME_READ/WAIT reads.
- A scan asks each ID for itself through the board; two servos sharing an ID cannot be
  told from one (the board hands back a value, not the line's bytes).
- The emergency stop stops the servos (MOVE_STOP to every ID, twice) and every wheel motor;
  the halt latches the wheels as well as the servos (a base driven from another thread
  is refused until the re-arm).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from types import TracebackType
from typing import Any

from busarm.bus.board import BoardLink
from busarm.bus.driver import EchoMode
from busarm.bus.id_scan import ScanResult
from busarm.bus.lx_port import LxServoPort
from busarm.bus.transport import Transport
from busarm.errors import (
    BusConflictError,
    BusTimeoutError,
    ConfigError,
    ProtocolError,
    UnsupportedError,
)
from busarm.protocol import (
    BROADCAST_ID,
    MAX_SERVO_ID,
    SERVO_TURNAROUND_S,
    SPECS,
    Command,
    Frame,
    Reply,
    check_servo_id,
    decode_reply,
)
from busarm.protocol.board import (
    READ_FORMATS,
    ServoMove,
    ServoStop,
    ServoSub,
    ServoWrite,
)

__all__ = [
    "SCAN_RETRIES",
    "BoardServoBus",
    "unsupported",
]


log = logging.getLogger(__name__)

_READS: dict[Command, ServoSub] = {
    Command.POS_READ: ServoSub.READ_POSITION,
    Command.VIN_READ: ServoSub.READ_VOLTAGE,
    Command.TEMP_READ: ServoSub.READ_TEMPERATURE,
    Command.LOAD_OR_UNLOAD_READ: ServoSub.READ_TORQUE,
    Command.ID_READ: ServoSub.READ_ID,
    Command.ANGLE_OFFSET_READ: ServoSub.READ_OFFSET,
    Command.ANGLE_LIMIT_READ: ServoSub.READ_ANGLE_LIMITS,
    Command.VIN_LIMIT_READ: ServoSub.READ_VOLTAGE_LIMITS,
    Command.TEMP_MAX_LIMIT_READ: ServoSub.READ_TEMP_LIMIT,
}
_WRITES: dict[Command, ServoSub] = {
    Command.ID_WRITE: ServoSub.SET_ID,
    Command.ANGLE_OFFSET_ADJUST: ServoSub.SET_OFFSET,
    Command.ANGLE_OFFSET_WRITE: ServoSub.SAVE_OFFSET,
    Command.ANGLE_LIMIT_WRITE: ServoSub.SET_ANGLE_LIMITS,
    Command.VIN_LIMIT_WRITE: ServoSub.SET_VOLTAGE_LIMITS,
    Command.TEMP_MAX_LIMIT_WRITE: ServoSub.SET_TEMP_LIMIT,
}
_WHAT: dict[Command, str] = {
    Command.OR_MOTOR_MODE_WRITE: "motor (continuous rotation) mode",
    Command.OR_MOTOR_MODE_READ: "reading the servo's mode",
    Command.LED_CTRL_WRITE: "the servos' LEDs",
    Command.LED_CTRL_READ: "the servos' LEDs",
    Command.LED_ERROR_WRITE: "the servos' alarm masks",
    Command.LED_ERROR_READ: "the servos' alarm masks",
    Command.MOVE_TIME_WAIT_WRITE: "queued moves (MOVE_TIME_WAIT_WRITE; its moves are "
                                  "synchronised by one multi-servo frame instead)",
    Command.MOVE_START: "MOVE_START (its moves are synchronised by one multi-servo frame)",
    Command.MOVE_TIME_READ: "reading back the last move command",
    Command.MOVE_TIME_WAIT_READ: "reading back a queued move",
}
SCAN_RETRIES = 0
"""A scan asks each ID once: an absent ID costs one board timeout."""


def unsupported(command: Command) -> UnsupportedError:
    what = _WHAT.get(command, command.name)
    return UnsupportedError(f"the controller board cannot do {what}: it has no command for "
                            "it and no raw pass-through to the servo line (use a plain LX "
                            "bus adapter for this)")


class BoardServoBus(LxServoPort):
    """LX bus servos behind a controller board. Thread-safe; a context manager."""

    def __init__(self, link: BoardLink, *,
                 limits_deg: Mapping[int, tuple[float, float]] | None = None) -> None:
        # No LX line here (no echo, no LX timing); the shared state (limits, halt, what
        # was written) is every LX-family port's.
        self.link = link
        self.transport = link.transport
        self.echo = False
        self.turnaround_s = SERVO_TURNAROUND_S
        self._targets: dict[int, int] = {}  # servo ID -> the last target sent (pulses)
        self._init_state(link.clock, link.retries, limits_deg)

    @classmethod
    def on(cls, transport: Transport, *, echo: EchoMode | str = EchoMode.AUTO,
           retries: int | None = None, timeout_margin_s: float | None = None,
           limits_deg: Mapping[int, tuple[float, float]] | None = None,
           **lx_only: Any) -> BoardServoBus:
        """The servos behind the board on ``transport``; LX line options (echo on,
        turnaround) are refused, as they mean nothing here."""
        if EchoMode(echo) is EchoMode.ON:
            raise ConfigError("echo on: the controller board's link does not echo (use "
                              "--echo auto or off with board://)")
        unknown = sorted(k for k in lx_only if k != "turnaround_s")
        if unknown:
            raise ConfigError(f"unknown option(s) for a board's servos: {', '.join(unknown)}")
        turnaround_s = float(lx_only.get("turnaround_s", SERVO_TURNAROUND_S))
        link_options: dict[str, Any] = {}
        if retries is not None:
            link_options["retries"] = retries
        if timeout_margin_s is not None:
            link_options["timeout_margin_s"] = timeout_margin_s
        bus = cls(BoardLink(transport, **link_options), limits_deg=limits_deg)
        bus.turnaround_s = turnaround_s  # the servos' own, behind the board: for wire times
        return bus

    def close(self) -> None:
        self.link.close()

    def halt(self, why: str = "e-stop") -> None:
        """As every LX port's ``halt``, and the wheels too: a speed other than 0 is refused
        (HaltedError) until ``rearm()``, whichever thread drives the base."""
        self.link.wheels_halted = why  # first: a drive racing the stop is refused or precedes it
        super().halt(why)

    def rearm(self) -> None:
        super().rearm()
        self.link.wheels_halted = None

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc_type is not None and self.link.wheels_turning:
            self._unstopped = True  # the wheels are written too: the exit's stop is theirs
        super().__exit__(exc_type, exc, tb)

    # ------------------------------------------------------------------ the wire

    def emergency_stop(self) -> None:
        """Stop every servo (held where it is) and every wheel motor; never raises."""
        for request in (ServoStop((BROADCAST_ID,)), ServoStop((BROADCAST_ID,))):
            try:
                self.link.write(request)
            except Exception as exc:  # the link may be what failed
                log.warning("emergency stop: %s", exc)
        try:
            self.link.stop_motors()
        except Exception as exc:
            log.warning("emergency stop (wheels): %s", exc)
        self.stop_sent, self._unstopped = True, False

    def send(self, servo_id: int, command: Command, *args: int) -> None:
        """A write command in LX terms (``Command``), as the board's sub-command for it;
        UnsupportedError, sending nothing, for one it has none for."""
        self.check_write(servo_id, command, args)
        request = self._encode(servo_id, command, args)
        self._mark_written((servo_id,))
        self._write(request)

    def _encode(self, servo_id: int, command: Command, args: tuple[int, ...]) -> bytes:
        """The board's frame for an LX write command (checked: nothing is sent)."""
        if command is Command.MOVE_TIME_WRITE:
            request = ServoMove(args[1], ((servo_id, args[0]),)).encode()
            self._targets[servo_id] = args[0]
            return request
        if command is Command.MOVE_STOP:
            return ServoStop((servo_id,)).encode()
        if command is Command.LOAD_OR_UNLOAD_WRITE:
            sub = ServoSub.TORQUE_ON if args[0] else ServoSub.TORQUE_OFF
            return ServoWrite(sub, servo_id).encode()
        sub_for = _WRITES.get(command)
        if sub_for is None:
            raise unsupported(command)
        return ServoWrite(sub_for, servo_id, args).encode()

    def _write(self, request: bytes) -> None:
        with self._lock:
            self.transport.write(request)

    def send_moves(self, pulses: Mapping[int, int], time_ms: int, *, use_start: bool) -> None:
        """One frame moves them all: the board sends each servo its move at once (so
        ``use_start`` changes nothing: there is no queued move to start)."""
        self.check_not_halted(Command.MOVE_TIME_WRITE, ())
        request = ServoMove(time_ms, tuple(pulses.items())).encode()
        self._targets.update(pulses)
        self._mark_written(pulses)
        self._write(request)

    def query(self, servo_id: int, command: Command) -> Reply:
        """A read in LX terms (``Command``): the board's answer as the LX reply type."""
        sub = self._sub(servo_id, command)
        reply = self.link.servo_read(sub, servo_id)
        self._answered.add(servo_id)
        return decode_reply(Frame(servo_id, int(command), reply.value_bytes))

    def read_values(self, servo_id: int, command: Command) -> tuple[int, ...]:
        reply = self.link.servo_read(self._sub(servo_id, command), servo_id)
        self._answered.add(servo_id)
        return reply.values

    def _sub(self, servo_id: int, command: Command) -> ServoSub:
        sub = _READS.get(command)
        if sub is None:
            if isinstance(command, Command) and SPECS[command].is_read:
                raise unsupported(command)
            raise ConfigError(f"{command!r} is not a read command")
        check_servo_id(servo_id, allow_broadcast=command is Command.ID_READ)
        return sub

    def last_target_pulses(self, servo_id: int) -> int | None:
        """Where this bus last told the servo to go (pulses), or None: the board cannot
        read it back from the servo."""
        return self._targets.get(check_servo_id(servo_id))

    def _forget(self, *servo_ids: int) -> None:
        for sid in servo_ids:  # the target told to the old ID is not the new ID's
            self._targets.pop(sid, None)

    def read_budget_s(self, command: Command) -> float:
        return self.link.read_budget_s(self._sub(1, command))

    def wire_time_s(self, tx_bytes: int, rx_bytes: int) -> float:
        """Time both legs need for a request and its reply of these LX sizes: the board's
        link and the servo line behind it (with the servo's turnaround)."""
        servo_line = (tx_bytes + rx_bytes) * self.link.servo_byte_s + (
            self.turnaround_s if rx_bytes else 0.0)
        return self.link_time_s(tx_bytes, rx_bytes) + servo_line

    def link_time_s(self, tx_bytes: int, rx_bytes: int) -> float:
        """The board's link alone for the same exchange: a board read request is one byte
        longer than the LX one (7 bytes against 6), its reply two (10 against 8 for a
        position)."""
        return (tx_bytes + rx_bytes + 3) * 10.0 / self.transport.baudrate

    # ------------------------------------------------------------------ IDs

    def read_id(self, servo_id: int = BROADCAST_ID) -> int:
        """ID_READ through the board; on the broadcast ID only one servo on the bus can
        answer (several answer at once, and the board says none did)."""
        try:
            return super().read_id(servo_id)
        except (BusTimeoutError, ProtocolError) as exc:
            if servo_id != BROADCAST_ID:
                raise
            raise BusConflictError(
                "no single servo answered ID_READ on the broadcast ID through the controller "
                "board: none is connected, or more than one (they answer at once)") from exc

    def set_id(self, old_id: int, new_id: int) -> None:
        """Renumber the servo at ``old_id``, only when it is the one servo on the bus.

        Through the board two servos sharing an ID look like none (the board hands back
        "no answer", not the garbled bytes), so the plain bus's check cannot be made here:
        the broadcast ID read, which only a lone servo answers cleanly, is asked instead."""
        check_servo_id(old_id)
        check_servo_id(new_id)
        if old_id == new_id:
            raise ConfigError(f"servo already has ID {new_id}")
        try:
            only = self.read_id(BROADCAST_ID)
        except BusConflictError as exc:
            raise BusConflictError(
                f"{exc}: through the controller board, renumbering needs exactly one servo "
                "on the bus (a shared ID cannot be seen through it); disconnect the others"
            ) from exc
        if only != old_id:
            raise BusTimeoutError(f"the one servo on the bus has ID {only}, not {old_id}",
                                  servo_id=old_id)
        self.send(old_id, Command.ID_WRITE, new_id)
        self.written_ids.discard(old_id)
        self.written_ids.add(new_id)
        self._forget(old_id, new_id)
        if self.read_id(new_id) != new_id:
            raise ProtocolError(f"servo did not take ID {new_id}")

    # ------------------------------------------------------------------ scan

    def scan(self, servo_ids: Iterable[int] = range(MAX_SERVO_ID + 1), *,
             margin_s: float = 0.0, progress: Callable[[int], None] | None = None
             ) -> ScanResult:
        """Ask every ID in ``servo_ids`` for itself through the board; who answered.
        (``conflicts`` stays empty: through the board two servos on one ID look like
        one, or like none.)"""
        ids = [check_servo_id(s) for s in servo_ids]
        started = self._now()
        found: list[int] = []
        for sid in ids:
            try:
                reply = self.link.servo_read(ServoSub.READ_ID, sid, retries=SCAN_RETRIES)
            except (BusTimeoutError, ProtocolError):
                reply = None
            if reply is not None and reply.values[0] == sid:
                found.append(sid)
                self._answered.add(sid)
            if progress is not None:
                progress(sid)
        return ScanResult(sorted(found), [], self._now() - started)  # as ServoBus.scan: sorted


assert set(_READS.values()) == set(READ_FORMATS)
