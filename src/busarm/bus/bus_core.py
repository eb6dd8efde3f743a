"""The LX serial line as a carrier of LX commands: one locked request/reply transaction
at a time.

``BusCore`` derives every timeout from the baud rate and packet lengths, handles
adapters that echo what they send, retries reads a bounded number of times, and accepts
a reply only if its header, ID, command, length and checksum are those expected: a
stray frame, a late reply from another servo or line noise is never taken as the
answer. It implements the carrier seam (``busarm.bus.servo_wire.ServoWire``) on which
``ServoBus`` (busarm.bus.driver) builds the user's calls.
"""

from __future__ import annotations

import os
import select
import termios
import warnings
from collections.abc import Callable, Mapping
from typing import NamedTuple

from busarm.bus.no_reply import LineSighting, final_error, unexplained_error
from busarm.bus.servo_wire import ServoWire
from busarm.bus.transport import Transport
from busarm.errors import (
    BusTimeoutError,
    ChecksumError,
    ConfigError,
    EchoMismatchError,
    ProtocolError,
    TransportError,
)
from busarm.protocol import (
    BROADCAST_ID,
    SPECS,
    Command,
    Frame,
    FrameParser,
    Reply,
    check_servo_id,
    decode_reply,
    encode_request,
)

__all__ = [
    "NO_ECHO_HINT",
    "STALE_REPLY_S",
    "BusCore",
]


STALE_REPLY_S = 1.0
"""How long after a timeout its reply is still expected to turn up late."""
NO_ECHO_HINT = "the replies look like the adapter does not echo: try --echo off (or auto)"

_HEADER = b"\x55\x55"
_SUM_OK = (0xFF + sum(_HEADER)) & 0xFF
"""The low byte of the sum of a whole valid reply: its checksum is ~(ID + length +
command + parameters), so with the header those sum to 0xFF + 0x55 + 0x55 (mod 256).
Checked this way when the header, ID, length and command are known to match: no slice
of the reply is made on the hot path."""
_TCIFLUSH = termios.TCIFLUSH


class _ReadPlan(NamedTuple):
    """One (servo, read command)'s request and how to check and decode its reply; a
    tuple, so that the hot path unpacks it in one step."""

    request: bytes
    prefix: bytes
    reply_bytes: int
    timeout_s: float
    unpack_from: Callable[[bytes | bytearray, int], tuple[int, ...]]


class BusCore(ServoWire):
    """Timing, raw writes and validated reads on the LX line (the carrier of ``ServoBus``).

    The line's state is set by ``ServoBus.__init__``; what every LX-family port keeps,
    by ``ServoWire._init_state``.
    """

    transport: Transport
    turnaround_s: float
    timeout_margin_s: float
    byte_s: float
    echo: bool
    _plans: dict[tuple[int, Command], _ReadPlan]
    _line_free_at: float
    _late: dict[tuple[int, int], float]
    _trouble: LineSighting | None
    _echo_warned: bool
    _fd: int | None = None
    """The transport's file descriptor (a serial device on POSIX), for ``read_values``'s
    single-frame path; None: every exchange goes through ``transport.exchange``."""

    # ------------------------------------------------------------------ timing

    def wire_time_s(self, tx_bytes: int, rx_bytes: int) -> float:
        """Time the line needs for a request and its reply, plus the servo's turnaround."""
        return (tx_bytes + rx_bytes) * self.byte_s + (self.turnaround_s if rx_bytes else 0.0)

    def timeout_s(self, tx_bytes: int, rx_bytes: int, margin_s: float | None = None) -> float:
        """The deadline of one attempt: wire time + adapter latency + margin."""
        margin = self.timeout_margin_s if margin_s is None else margin_s
        return self.wire_time_s(tx_bytes, rx_bytes) + self.transport.latency_s + margin

    def follow_s(self, rx_bytes: int) -> float:
        """How long to keep listening after a reply that may be a stale one (see _scan_reply)."""
        return self.turnaround_s + rx_bytes * self.byte_s + self.timeout_margin_s

    def read_budget_s(self, command: Command) -> float:
        """The longest a read of ``command`` can take before it returns or raises
        (on an idle line): every attempt, each with its possible wait for a late reply."""
        spec = SPECS[command]
        if spec.reply_length is None:
            raise ConfigError(f"{command.name} is not a read command")
        rx = spec.reply_length + 3
        attempt = self.timeout_s(spec.request_length + 3, rx) + self.follow_s(rx)
        return (self.retries + 1) * attempt

    # ------------------------------------------------------------------ raw transactions

    def send(self, servo_id: int, command: Command, *args: int) -> None:
        """Send a write command (no reply expected). ``servo_id`` may be 254 (broadcast)."""
        self.check_write(servo_id, command, args)
        request = encode_request(servo_id, command, *args)
        self._mark_written((servo_id,))
        self._send(request)

    def send_moves(self, pulses: Mapping[int, int], time_ms: int, *, use_start: bool) -> None:
        """Every servo to its target (pulses) in ``time_ms``: MOVE_TIME_WAIT_WRITE to each,
        then one broadcast MOVE_START (``use_start``); or MOVE_TIME_WRITE to each."""
        with self._lock:
            if not use_start:
                for sid, p in pulses.items():
                    self.send(sid, Command.MOVE_TIME_WRITE, p, time_ms)
            else:
                for sid, p in pulses.items():
                    self.send(sid, Command.MOVE_TIME_WAIT_WRITE, p, time_ms)
                self.send(BROADCAST_ID, Command.MOVE_START)

    def query(self, servo_id: int, command: Command) -> Reply:
        """Send a read command and return the validated, typed reply (with retries)."""
        plan = self._plans.get((servo_id, command)) or self._plan(servo_id, command)
        buf, at = self._transact(plan, servo_id, command)
        params = bytes(buf[at : at + plan.reply_bytes - 6])
        return decode_reply(Frame(servo_id, int(command), params))

    def read_values(self, servo_id: int, command: Command) -> tuple[int, ...]:
        """A read's reply as its wire values: the hot path of the unit-level reads.

        After every wait for a reply the CPU's caches are cold, and each Python frame,
        call and temporary object then costs a microsecond or so (measured on a pty,
        beside the same four syscalls made bare). So on a serial device's file
        descriptor the common case (no echo, no late reply pending, the whole reply and
        only it in the first read) is done here in one frame, with the same syscalls as
        ``SerialTransport.exchange``: flush the input, write, select, read. Anything
        else goes through ``_finish``.
        """
        plan = self._plans.get((servo_id, command)) or self._plan(servo_id, command)
        fd = self._fd
        with self._lock:
            if fd is None or self._late or self.echo:
                return plan.unpack_from(*self._transact(plan, servo_id, command))
            request, prefix, n, timeout_s, unpack_from = plan
            now = self._now()
            if self._line_free_at > now:
                timeout_s += self._line_free_at - now
            try:
                termios.tcflush(fd, _TCIFLUSH)
                if os.write(fd, request) < len(request):
                    raise TransportError(f"{self.transport.name}: short write")
                data = os.read(fd, 256) if select.select((fd,), (), (), timeout_s)[0] else None
            except TransportError:
                raise
            except Exception as exc:  # as SerialTransport.exchange says it
                raise TransportError(f"{self.transport.name}: {exc}") from exc
            if data is None:
                data = b""
            elif not data:
                raise TransportError(f"{self.transport.name}: device disconnected")
            elif (len(data) == n and prefix and data.startswith(prefix)
                  and sum(data) & 0xFF == _SUM_OK):
                self._answered.add(servo_id)
                return unpack_from(data, 5)
            return unpack_from(*self._finish(plan, servo_id, command, data, now + timeout_s))

    def _plan(self, servo_id: int, command: Command) -> _ReadPlan:
        spec = SPECS.get(command) if isinstance(command, Command) else None
        if spec is None or not spec.is_read:
            raise ConfigError(f"{command!r} is not a read command")
        check_servo_id(servo_id, allow_broadcast=command is Command.ID_READ)
        request = encode_request(servo_id, command)
        assert spec.reply_length is not None
        reply_bytes = spec.reply_length + 3
        prefix = _HEADER + bytes((servo_id, spec.reply_length, int(command)))
        if servo_id == BROADCAST_ID:
            # The one servo answers with its own ID, which we do not know yet.
            prefix = b""
        assert spec.reply_struct is not None
        plan = _ReadPlan(
            request, prefix, reply_bytes, self.timeout_s(len(request), reply_bytes),
            spec.reply_struct.unpack_from,
        )
        self._plans[(servo_id, command)] = plan
        return plan

    def _send(self, request: bytes, *, await_echo: bool = True) -> None:
        with self._lock:
            t = self.transport
            t.write(request)
            # The OS returns before the bytes are on the wire; a reply to the next
            # request cannot start until they are, so its deadline must wait for them.
            now = self._now()
            self._line_free_at = max(now, self._line_free_at) + len(request) * self.byte_s
            if self.echo and await_echo:
                self._await_echo(request, self.timeout_s(len(request), 0))

    def _await_echo(self, request: bytes, timeout_s: float) -> None:
        deadline = self._now() + timeout_s
        buf = bytearray()
        while request not in buf:
            remaining = deadline - self._now()
            chunk = self.transport.read(64, remaining) if remaining > 0 else b""
            if not chunk:
                raise BusTimeoutError(
                    f"sent {request.hex(' ')}, but its echo did not come back within "
                    f"{timeout_s * 1e3:.1f} ms: is the adapter really echoing? "
                    "(try echo 'auto' or 'off')",
                    timeout_s=timeout_s,
                )
            buf += chunk

    def _transact(
        self, plan: _ReadPlan, servo_id: int, command: Command
    ) -> tuple[bytes | bytearray, int]:
        """One request and its validated reply, retried up to ``self.retries`` times.

        Returns a buffer and the offset of the reply's parameters in it. This is the
        hot path: after each wait for a reply the CPU caches are cold, so the common
        case (no recent timeout, no echo, the whole reply and only it in the first
        read) is accepted in a few lines; everything else goes through ``_finish``.
        """
        with self._lock:
            if self._late:
                return self._finish(plan, servo_id, command)
            now = self._now()
            timeout_s = plan.timeout_s
            if self._line_free_at > now:
                timeout_s += self._line_free_at - now
            data = self.transport.exchange(plan.request, timeout_s)
            n = plan.reply_bytes
            if (
                len(data) == n and plan.prefix and not self.echo
                and data.startswith(plan.prefix) and sum(data) & 0xFF == _SUM_OK
            ):
                self._answered.add(servo_id)
                return data, 5
            return self._finish(plan, servo_id, command, data, now + timeout_s)

    def _finish(
        self, plan: _ReadPlan, servo_id: int, command: Command,
        first: bytes | None = None, deadline: float = 0.0,
    ) -> tuple[bytes, int]:
        """The general case (lock held): keep reading this attempt, then retry."""
        key = (servo_id, int(command))
        errors: list[BusTimeoutError | ProtocolError] = []
        for attempt in range(self.retries + 1):
            if attempt:
                self.stats["retries"] += 1
            if first is None:
                now = self._now()
                deadline = now + plan.timeout_s + max(self._line_free_at - now, 0.0)
                first = self.transport.exchange(plan.request, deadline - now)
            try:
                params = self._scan_reply(plan, servo_id, command, first, deadline,
                                          self._expect_late(key))
                self._late.pop(key, None)
                self._answered.add(servo_id)
                return params, 0
            except BusTimeoutError as exc:
                self.stats["timeouts"] += 1
                if servo_id != BROADCAST_ID:
                    self._late[key] = self._now()
                errors.append(exc)
            except ProtocolError as exc:
                self.stats["bad_replies"] += 1
                errors.append(exc)
                self._trouble = LineSighting(self._now(), servo_id, int(command), late=False)
            first = None
        # Said by what came back: nothing, damaged replies, or nothing on a bad line.
        seen = self._trouble
        if seen is not None and self._now() - seen.at_s > STALE_REPLY_S:
            seen = None
        raise final_error(errors, servo_id=servo_id, command_name=command.name, seen=seen,
                          answered_before=servo_id in self._answered)

    def _expect_late(self, key: tuple[int, int]) -> bool:
        """Whether a late reply to an earlier, timed-out request of ``key`` may still come."""
        since = self._late.get(key)
        if since is not None and self._now() - since > STALE_REPLY_S:
            del self._late[key]
            return False
        return since is not None

    def _scan_reply(
        self, plan: _ReadPlan, servo_id: int, command: Command, first: bytes,
        deadline: float, expect_late: bool,
    ) -> bytes:
        """Read until our valid reply or the deadline; return its parameters.

        Skipped: line noise, other servos' frames, and our own echo (before which
        nothing can be the answer: the servo had not heard us yet). When a late reply
        to an earlier request may still come (``expect_late``), a matching frame may be
        that stale answer: the line delivers in order, so ours would follow it. Then
        every matching frame is followed by a wait long enough for another to come,
        and the last one is ours. A doubt costs time, never a wrong value.
        """
        parser = FrameParser()
        echo_pending = self.echo
        want_length = plan.reply_bytes - 3
        follow_s = self.follow_s(plan.reply_bytes)
        latest = deadline + follow_s  # at most one follow-up window per attempt
        found: bytes | None = None
        chunk: bytes = first
        unexplained = 0  # bytes that were neither our echo nor a reply
        frames_seen = 0
        reply_first = False  # our reply, and nothing before it, while awaiting our echo
        while True:
            unexplained += len(chunk)
            for frame in parser.feed(chunk):
                frames_seen += 1
                is_reply = (
                    frame.command == command and frame.length == want_length
                    and (frame.servo_id == servo_id or servo_id == BROADCAST_ID)
                )
                if echo_pending:
                    if frame.to_bytes() == plan.request:
                        echo_pending = False
                        unexplained -= len(plan.request)
                    elif is_reply and frames_seen == 1 and not parser.skipped_bytes:
                        reply_first = True
                    continue
                if is_reply:
                    if not expect_late:
                        return frame.params
                    if found is not None:  # the one before answered an earlier request
                        self._saw_late(frame)
                    found = frame.params
                    unexplained -= want_length + 3
                    deadline = max(deadline, min(self._now() + follow_s, latest))
                elif not self.echo and frame.to_bytes() == plan.request:
                    self._warn_echo_off()
                else:  # a reply to an earlier request, which had given up on it: late
                    self._saw_late(frame)
                    unexplained -= frame.length + 3
            remaining = deadline - self._now()
            chunk = self.transport.read(256, remaining) if remaining > 0 else b""
            if not chunk:
                break
        if found is not None:
            return found
        raise self._no_reply_error(plan, servo_id, command, parser, unexplained,
                                   echo_pending, reply_first and echo_pending)

    def _no_reply_error(
        self, plan: _ReadPlan, servo_id: int, command: Command, parser: FrameParser,
        unexplained: int, echo_pending: bool, reply_without_echo: bool,
    ) -> BusTimeoutError | ProtocolError:
        """What an attempt that found no reply saw: silence, garbage, or a wrong echo setting."""
        name = command.name
        if reply_without_echo:
            # A non-echoing adapter: the servo's reply is all that came back, and with echo
            # on it is taken for a garbled echo on every read.
            return EchoMismatchError(
                f"servo {servo_id} answered {name}, but our own request did not come back "
                f"before the reply: {NO_ECHO_HINT}", parser.pending,
            )
        if parser.checksum_failures:
            return ChecksumError(f"servo {servo_id} {name}: garbled reply", parser.pending)
        if unexplained > 0:
            return unexplained_error(servo_id, name, unexplained, parser.pending, echo_pending)
        return BusTimeoutError(
            f"servo {servo_id} did not answer {name} within {plan.timeout_s * 1e3:.1f} ms",
            servo_id=servo_id, command=int(command), timeout_s=plan.timeout_s,
        )

    def _saw_late(self, frame: Frame) -> None:
        self._trouble = LineSighting(self._now(), frame.servo_id, frame.command, late=True)

    def _warn_echo_off(self) -> None:
        """Say once that our own request came back although echo is off (it still works:
        the copy is skipped, but the echo setting is wrong)."""
        if not self._echo_warned:
            self._echo_warned = True
            warnings.warn(
                f"{self.transport.name}: the adapter echoes what it sends, but echo is set "
                "off: use --echo on (or auto)", RuntimeWarning, stacklevel=2,
            )
