"""The servo bus driver: one locked request/reply transaction at a time.

``ServoBus`` turns the protocol into calls in the user's units (degrees from the
servo's mid-point, seconds, volts, deg C), with raw-pulse variants named so. It
derives every timeout from the baud rate and packet lengths, handles adapters that
echo what they send (on, off, or detected at open), retries reads a bounded number
of times, and accepts a reply only if its header, ID, command, length and checksum
are those expected: a stray frame, a late reply from another servo or line noise is
never taken as the answer.
"""

from __future__ import annotations

import enum
import logging
import threading
import warnings
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from types import TracebackType
from typing import TypeVar

from busarm.bus.no_reply import LineSighting, final_error, unexplained_error
from busarm.bus.transport import DEFAULT_BAUDRATE, Transport, open_transport
from busarm.clock import Clock
from busarm.errors import (
    BusConflictError,
    BusTimeoutError,
    ChecksumError,
    ConfigError,
    EchoMismatchError,
    HaltedError,
    LimitError,
    MotionTimeoutError,
    ProtocolError,
)
from busarm.protocol import (
    BROADCAST_ID,
    MAX_SERVO_ID,
    SERVO_TURNAROUND_S,
    SPECS,
    AlarmFlag,
    AngleLimitReply,
    AngleOffsetReply,
    Command,
    Frame,
    FrameParser,
    IdReply,
    LedCtrlReply,
    LedErrorReply,
    LoadReply,
    ModeReply,
    MoveTimeReply,
    MoveTimeWaitReply,
    Reply,
    ServoMode,
    TempMaxLimitReply,
    VinLimitReply,
    check_servo_id,
    decode_reply,
    encode_request,
)
from busarm.units import (
    CENTER_PULSES,
    DEG_PER_PULSE,
    MOTOR_SPEED_MAX,
    MOVE_TIME_MAX_MS,
    check_int_range,
    check_range,
    deg_from_pulses,
    ms_from_s,
    mv_from_v,
    offset_pulses_from_deg,
    pulses_from_deg,
)

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_MARGIN_S = 0.004
"""Slack on top of the wire time for OS scheduling and adapter jitter."""
DEFAULT_RETRIES = 2
STALE_REPLY_S = 1.0
"""How long after a timeout its reply is still expected to turn up late."""
WAIT_SLACK_S = 2.0
"""wait_until_reached's default allowance beyond the end of the commanded move."""
CONFLICT_PROBES = 3
"""Position reads that decide whether a garbled ID is two servos or line noise."""
SCAN_MARGIN_S = 0.0012
"""Scans use a tighter margin: a late answer is still caught (see ``scan``)."""
NO_ECHO_HINT = "the replies look like the adapter does not echo: try --echo off (or auto)"

_HEADER = b"\x55\x55"
_R = TypeVar("_R", bound=Reply)


class EchoMode(str, enum.Enum):
    """Whether the adapter hands back every byte we send before the reply."""

    ON = "on"
    OFF = "off"
    AUTO = "auto"


@dataclass(frozen=True)
class ServoState:
    """One servo's live readings."""

    servo_id: int
    position_deg: float
    temp_c: int
    vin_v: float


@dataclass
class ScanResult:
    """IDs that answered, and IDs whose replies were garbled (two servos on one ID)."""

    found: list[int] = field(default_factory=list)
    conflicts: list[int] = field(default_factory=list)
    duration_s: float = 0.0


@dataclass(frozen=True)
class _ReadPlan:
    request: bytes
    prefix: bytes
    reply_bytes: int
    timeout_s: float
    unpack_from: Callable[[bytes | bytearray, int], tuple[int, ...]]


class ServoBus:
    """LX bus servos on one serial line. Thread-safe; use as a context manager.

    Leaving the ``with`` block because of an exception (Ctrl+C included) sends
    MOVE_STOP to every servo, which holds them where they are (those with torque on),
    if anything was written since the last stop; a bus that only read, or wrote nothing
    after its stop, leaves the servos as they are and sends nothing.
    """

    def __init__(
        self,
        transport: Transport,
        *,
        echo: EchoMode | str = EchoMode.AUTO,
        turnaround_s: float = SERVO_TURNAROUND_S,
        timeout_margin_s: float = DEFAULT_TIMEOUT_MARGIN_S,
        retries: int = DEFAULT_RETRIES,
        limits_deg: Mapping[int, tuple[float, float]] | None = None,
    ) -> None:
        try:
            echo_mode = EchoMode(echo)
        except ValueError:
            raise ConfigError(f"echo = {echo!r}; allowed: on, off, auto") from None
        check_range("turnaround_s", turnaround_s, 0.0, 0.1, "s")
        check_range("timeout_margin_s", timeout_margin_s, 0.0, 1.0, "s")
        check_int_range("retries", retries, 0, 10)
        self.transport = transport
        self.turnaround_s = float(turnaround_s)
        self.timeout_margin_s = float(timeout_margin_s)
        self.byte_s = 10.0 / transport.baudrate
        self._plans: dict[tuple[int, Command], _ReadPlan] = {}
        self._line_free_at = 0.0
        # (servo ID, command) -> when a request of it last timed out: its reply may come late.
        self._late: dict[tuple[int, int], float] = {}
        self._trouble: LineSighting | None = None  # the last reply seen late or damaged
        self._echo_warned = False  # said that our own bytes come back with echo off
        self._init_state(transport.clock, retries, limits_deg)
        self.echo = echo_mode is EchoMode.ON
        if echo_mode is EchoMode.AUTO:
            self.echo = self._detect_echo()

    def _init_state(self, clock: Clock, retries: int,
                    limits_deg: Mapping[int, tuple[float, float]] | None) -> None:
        """What every servo bus keeps, whatever its wire."""
        self.clock = clock
        self._now = clock.now  # the hot path's one clock read, bound once
        self.retries = retries
        self._lock = threading.RLock()
        self._limits: dict[int, tuple[float, float]] = {}
        self._spinning: set[int] = set()  # servos this bus set turning in motor mode
        self._answered: set[int] = set()  # servos that gave a valid reply on this bus
        self._move_ends: dict[int, float] = {}  # servo ID -> when its last move should end
        self.wrote = False
        """Whether a write command (one that can move or change a servo) has gone out."""
        self.written_ids: set[int] = set()
        """The servos written to by ID (broadcast writes are not counted here)."""
        self.stop_sent = False
        """Whether the emergency stop has been sent."""
        self._unstopped = False  # written since the last emergency stop
        self._halted: str | None = None  # why the bus is halted (``halt``), until ``rearm``
        for sid, (lo, hi) in (limits_deg or {}).items():
            self.set_limits_deg(sid, lo, hi)
        self.stats = {"retries": 0, "timeouts": 0, "bad_replies": 0}

    # ------------------------------------------------------------------ lifecycle

    @classmethod
    def open(cls, port: str, *, baudrate: int = DEFAULT_BAUDRATE, **kwargs: object) -> ServoBus:
        """Open ``port`` (device path, pyserial URL, ``sim``, ``twin`` or ``board://...``)
        and return a bus on it: the servos behind a controller board for ``board://``."""
        transport = open_transport(port, baudrate=baudrate)
        try:
            if transport.framing == "board":
                return servo_bus_on(transport, **kwargs)
            return cls(transport, **kwargs)  # type: ignore[arg-type]
        except BaseException:
            transport.close()
            raise

    def close(self) -> None:
        self.transport.close()

    def __enter__(self) -> ServoBus:
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

    def emergency_stop(self) -> None:
        """Stop everything and hold; never raises.

        MOVE_STOP to every servo (broadcast, twice), and speed 0 to each servo this
        bus set turning in motor mode (MOVE_STOP does not stop a motor).
        """
        frames = [encode_request(BROADCAST_ID, Command.MOVE_STOP)] * 2
        frames += [
            encode_request(sid, Command.OR_MOTOR_MODE_WRITE, int(ServoMode.MOTOR), 0, 0)
            for sid in sorted(self._spinning)
        ]
        for frame in frames:
            try:
                # Back to back, not waiting for echoes: a stop must not wait on the line
                # (nor fail on a wrong echo setting); a later exchange discards the copies.
                self._send(frame, await_echo=False)
            except Exception as exc:  # the bus may be what failed
                log.warning("emergency stop: %s", exc)
        self.stop_sent, self._unstopped = True, False

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
        """Why the bus is halted (what ``halt`` was given), or None."""
        return self._halted

    @property
    def lock(self) -> threading.RLock:
        """Held for each transaction: whoever else moves bytes on this bus's transport (a
        remote client's requests, busarm.bus.zenoh_link) holds it too."""
        return self._lock

    def check_not_halted(self, command: Command, args: tuple[int, ...]) -> None:
        """HaltedError if the bus is halted and ``command`` is not a stop."""
        if self._halted is None or command is Command.MOVE_STOP or (
                command is Command.OR_MOTOR_MODE_WRITE and args[-1:] == (0,)):
            return
        raise HaltedError(f"{command.name} refused: the robot is halted ({self._halted}); "
                          "re-arm it first")

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
        if SPECS[command].is_read:
            raise ConfigError(f"{command.name} is a read command: use query()")
        if command is Command.ID_WRITE and servo_id == BROADCAST_ID:
            raise ConfigError(
                "refusing to broadcast ID_WRITE: it would renumber every servo on the bus"
            )
        self.check_not_halted(command, args)
        request = self._encode_write(servo_id, command, args)
        self._mark_written((servo_id,))
        self._send(request)

    def _encode_write(self, servo_id: int, command: Command, args: tuple[int, ...]) -> bytes:
        """The bytes of a write command on this bus's wire (checked: nothing is sent)."""
        return encode_request(servo_id, command, *args)

    def _mark_written(self, servo_ids: Iterable[int]) -> None:
        # Marked before sending: a write that fails half-way may have reached the servo.
        self.wrote = self._unstopped = True
        self.written_ids.update(sid for sid in servo_ids if sid != BROADCAST_ID)

    def query(self, servo_id: int, command: Command) -> Reply:
        """Send a read command and return the validated, typed reply (with retries)."""
        plan = self._plans.get((servo_id, command)) or self._plan(servo_id, command)
        buf, at = self._transact(plan, servo_id, command)
        params = bytes(buf[at : at + plan.reply_bytes - 6])
        return decode_reply(Frame(servo_id, int(command), params))

    def _read(self, servo_id: int, command: Command, kind: type[_R]) -> _R:
        reply = self.query(servo_id, command)
        assert isinstance(reply, kind)
        return reply

    def _values(self, servo_id: int, command: Command) -> tuple[int, ...]:
        # The hot path of the unit-level reads: wire values straight from the buffer.
        # After every wait for a reply the CPU caches are cold, so fewer objects and
        # calls here is what keeps the client's CPU time per transaction low.
        plan = self._plans.get((servo_id, command)) or self._plan(servo_id, command)
        return plan.unpack_from(*self._transact(plan, servo_id, command))

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
                and data.startswith(plan.prefix) and data[n - 1] == (~sum(data[2 : n - 1])) & 0xFF
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

    def _detect_echo(self) -> bool:
        # A read to the broadcast ID that no servo answers (only ID_READ is answered):
        # whatever comes back is our own bytes.
        probe = encode_request(BROADCAST_ID, Command.POS_READ)
        with self._lock:
            self.transport.reset_input()
            self.transport.write(probe)
            deadline = self._now() + self.timeout_s(len(probe), 0) + 0.01
            buf = bytearray()
            while probe not in buf:
                remaining = deadline - self._now()
                chunk = self.transport.read(64, remaining) if remaining > 0 else b""
                if not chunk:
                    break
                buf += chunk
            echo = probe in buf
        log.info("%s: adapter echo %s", self.transport.name, "detected" if echo else "not detected")
        return echo

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
        self._send_moves(pulses, time_ms, use_start=use_start)
        self._moving_until(pulses, time_ms / 1000.0)
        return time_ms / 1000.0

    def _send_moves(self, pulses: Mapping[int, int], time_ms: int, *, use_start: bool) -> None:
        """Every servo to its target (pulses) in ``time_ms``: queued, then one MOVE_START
        (``use_start``), or each at once."""
        with self._lock:
            if not use_start:
                for sid, p in pulses.items():
                    self.send(sid, Command.MOVE_TIME_WRITE, p, time_ms)
            else:
                for sid, p in pulses.items():
                    self.send(sid, Command.MOVE_TIME_WAIT_WRITE, p, time_ms)
                self.send(BROADCAST_ID, Command.MOVE_START)

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

    # ------------------------------------------------------------------ readings

    def read_position_pulses(self, servo_id: int) -> int:
        """Current position in pulses (signed: may read below 0 near the end stop)."""
        return self._values(servo_id, Command.POS_READ)[0]

    def read_position_deg(self, servo_id: int) -> float:
        return (self._values(servo_id, Command.POS_READ)[0] - CENTER_PULSES) * DEG_PER_PULSE

    def read_positions_deg(self, servo_ids: Iterable[int]) -> dict[int, float]:
        return {sid: self.read_position_deg(sid) for sid in servo_ids}

    def read_temp_c(self, servo_id: int) -> int:
        return self._values(servo_id, Command.TEMP_READ)[0]

    def read_vin_v(self, servo_id: int) -> float:
        return self._values(servo_id, Command.VIN_READ)[0] / 1000.0

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

    # ------------------------------------------------------------------ scan and IDs

    def scan(
        self,
        servo_ids: Iterable[int] = range(MAX_SERVO_ID + 1),
        *,
        margin_s: float = SCAN_MARGIN_S,
        progress: Callable[[int], None] | None = None,
    ) -> ScanResult:
        """Ask every ID in ``servo_ids`` for itself (ID_READ); return who answered.

        Each ID gets a short, baud-derived deadline. A reply that arrives after its
        deadline is still recognised by the ID inside it, so a slow servo is not
        missed. Every ID that answered or garbled is then probed with CONFLICT_PROBES
        position reads: an ID whose replies stay garbled is reported in ``conflicts``
        (two servos sharing it), not in ``found``; one that answers once is found.
        A servo whose every request is lost to noise is not found: scan again.
        """
        ids = [check_servo_id(s) for s in servo_ids]
        request_len = 6
        timeout = self.timeout_s(request_len, 7, margin_s)
        parser = FrameParser()
        found: set[int] = set()
        garbled: set[int] = set()
        started = self._now()

        def collect(chunk: bytes, asked: int) -> None:
            # Bytes that make no valid frame, in the window of one ID: two servos
            # answering at once (their bits AND on the open-drain line).
            noise = parser.checksum_failures + parser.skipped_bytes
            for frame in parser.feed(chunk):
                if frame.command == Command.ID_READ and len(frame.params) == 1:
                    found.add(frame.servo_id)
            if parser.checksum_failures + parser.skipped_bytes > noise:
                garbled.add(asked)

        with self._lock:
            self.transport.reset_input()
            for sid in ids:
                request = encode_request(sid, Command.ID_READ)
                self.transport.write(request)
                deadline = self._now() + timeout
                while sid not in found:
                    remaining = deadline - self._now()
                    chunk = self.transport.read(256, remaining) if remaining > 0 else b""
                    if not chunk:
                        break
                    collect(chunk, sid)
                if progress is not None:
                    progress(sid)
            # Stragglers: anything still on its way.
            tail_deadline = self._now() + 4 * timeout
            while (remaining := tail_deadline - self._now()) > 0:
                chunk = self.transport.read(256, remaining)
                if not chunk:
                    break
                collect(chunk, ids[-1] if ids else 0)
        wanted = set(ids)
        found &= wanted
        # A garbled window may be two servos on one ID, or just line noise: ask again.
        # Two servos answering together garble nearly every time; noise rarely twice.
        conflicts: set[int] = set()
        for sid in sorted((garbled & wanted) | found):
            probes: list[str] = []
            while len(probes) < CONFLICT_PROBES and "ok" not in probes:
                probes.append(self._probe(sid))
            if "ok" in probes:
                found.add(sid)
            elif probes.count("no echo") == len(probes):
                raise EchoMismatchError(
                    f"servo {sid} answers, but every reply came without our request's echo "
                    f"before it: {NO_ECHO_HINT}"
                )
            elif probes.count("garbled") >= 2:
                conflicts.add(sid)
        return ScanResult(sorted(found - conflicts), sorted(conflicts),
                          self._now() - started)

    def _probe(self, servo_id: int) -> str:
        """One POS_READ attempt, no retry: "ok", "garbled" (bytes, no valid reply), "no echo"
        (a valid reply but not our echo before it, though echo is on) or "silent"."""
        plan = self._plans.get((servo_id, Command.POS_READ)) or self._plan(
            servo_id, Command.POS_READ
        )
        with self._lock:
            deadline = self._now() + plan.timeout_s
            first = self.transport.exchange(plan.request, plan.timeout_s)
            try:
                self._scan_reply(plan, servo_id, Command.POS_READ, first, deadline, False)
            except BusTimeoutError:
                return "silent"
            except EchoMismatchError:
                return "no echo"
            except ProtocolError:
                return "garbled"
            return "ok"

    def _forget(self, *servo_ids: int) -> None:
        """Drop what is cached about these IDs' requests (an ID changed hands)."""
        self._plans = {k: v for k, v in self._plans.items() if k[0] not in servo_ids}

    def set_id(self, old_id: int, new_id: int) -> None:
        """Renumber the servo at ``old_id`` to ``new_id``, safely.

        Refuses unless exactly one servo answers at ``old_id`` and none at ``new_id``;
        the ID write is addressed to ``old_id``, never broadcast. Verifies afterwards.
        """
        check_servo_id(old_id)
        check_servo_id(new_id)
        if old_id == new_id:
            raise ConfigError(f"servo already has ID {new_id}")
        result = self.scan([old_id, new_id])
        if old_id in result.conflicts:
            raise BusConflictError(
                f"more than one servo answers at ID {old_id}; disconnect all but one first"
            )
        if old_id not in result.found:
            raise BusTimeoutError(f"no servo answers at ID {old_id}", servo_id=old_id)
        if new_id in result.found or new_id in result.conflicts:
            raise BusConflictError(f"ID {new_id} is already taken by another servo")
        self.send(old_id, Command.ID_WRITE, new_id)
        self.written_ids.discard(old_id)  # it answers at its new ID from now on
        self.written_ids.add(new_id)
        self._forget(old_id, new_id)
        if self.read_id(new_id) != new_id:
            raise ProtocolError(f"servo did not take ID {new_id}")


def servo_bus_on(transport: Transport, **kwargs: object) -> ServoBus:
    """The servo bus on an open ``transport``: the LX driver, or for a controller board's
    link (``transport.framing == "board"``) the servos behind the board."""
    if transport.framing == "board":
        from busarm.bus.board_bus import BoardServoBus  # it builds on this module

        return BoardServoBus.on(transport, **kwargs)  # type: ignore[arg-type]
    return ServoBus(transport, **kwargs)  # type: ignore[arg-type]


def open_bus(port: str, **kwargs: object) -> ServoBus:
    """Open a ServoBus on a device path, a pyserial URL or ``sim``: see ServoBus.open."""
    return ServoBus.open(port, **kwargs)  # type: ignore[arg-type]
