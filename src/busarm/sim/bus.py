"""A simulated servo bus: bytes in, the servos' reply bytes out, with wire timing.

``SimBus`` sits where the wire would be. It finds frames in whatever the host writes
(with the protocol's own parser), hands each to every servo it addresses, encodes
the replies with the protocol codec and schedules them when a real 115200-baud line
would have delivered them. It models what the field notes say of real buses: the
adapter echo, broadcast (only ID_READ answers), two servos on one ID garbling each
other (wired-AND of their bytes), silent servos under 6 V, and injected faults
(dropped, corrupted or late bytes) from a seeded random generator.

Not modelled: bit-level UART timing, partial overlap of colliding replies, brown-out
of the whole bus, and the host writing while a servo is still replying.
"""

from __future__ import annotations

import random
import threading
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from busarm.clock import Clock, SimClock
from busarm.errors import ConfigError, ProtocolError
from busarm.protocol import (
    BROADCAST_ID,
    SAVED_ON_POWER_OFF,
    SERVO_TURNAROUND_S,
    Command,
    Frame,
    FrameParser,
    Request,
    decode_request,
    encode_reply,
)
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import ServoParams
from busarm.sim.storage import load_state, record_from_servo, save_state, servo_from_record
from busarm.units import check_range

__all__ = [
    "ARM_SERVO_IDS",
    "BLOCK_GRIP_PULSES",
    "DUE_EPS_S",
    "GRIPPER_ID",
    "MAX_SKEW_BITS",
    "FaultInjection",
    "SimBus",
    "SimLine",
    "WireTiming",
    "pop_due",
]


ARM_SERVO_IDS = (1, 2, 3, 4, 5, 10)
"""The JetAuto Pro arm: five 35 kg joints and the 20 kg gripper on ID 10."""
GRIPPER_ID = 10
BLOCK_GRIP_PULSES = 540.0
"""Where the gripper stops when it closes on a 3 cm block (field notes: about 540)."""


@dataclass(frozen=True)
class WireTiming:
    """Line speed and servo turnaround. ``enabled=False`` delivers everything at once."""

    baudrate: int = 115200
    turnaround_s: float = SERVO_TURNAROUND_S
    enabled: bool = True

    @property
    def byte_s(self) -> float:
        """One byte on the wire: start bit, 8 data bits, stop bit."""
        return 10.0 / self.baudrate


@dataclass(frozen=True)
class FaultInjection:
    """Random faults, each a probability per byte (or per reply for ``late_rate``).

    ``directions`` says which way they apply: "rx" (host to servo), "tx" (servo to
    host) or "both".
    """

    drop_rate: float = 0.0
    corrupt_rate: float = 0.0
    late_rate: float = 0.0
    late_s: float = 0.05
    seed: int = 0
    directions: str = "both"

    def __post_init__(self) -> None:
        for name in ("drop_rate", "corrupt_rate", "late_rate"):
            check_range(name, getattr(self, name), 0.0, 1.0)
        if self.late_s < 0:
            raise ConfigError(f"late_s = {self.late_s!r} must be >= 0")
        if self.directions not in ("rx", "tx", "both"):
            raise ConfigError(f"directions = {self.directions!r}; allowed: rx, tx, both")

    @property
    def active(self) -> bool:
        return bool(self.drop_rate or self.corrupt_rate or self.late_rate)


MAX_SKEW_BITS = 24
"""Largest difference, in bit times, between two servos starting the same reply."""


def _uart_bits(data: bytes) -> list[int]:
    """Line levels for ``data``: per byte a start bit (0), 8 data bits LSB first, a stop bit."""
    bits: list[int] = []
    for b in data:
        bits.append(0)
        bits.extend((b >> i) & 1 for i in range(8))
        bits.append(1)
    return bits


def _uart_bytes(line: list[int]) -> bytes:
    """What a UART receiver makes of line levels: a byte per start bit, framing errors kept."""
    out = bytearray()
    i = 0
    while i < len(line):
        if line[i] == 1:
            i += 1
            continue
        data = (line[i + 1 : i + 9] + [1] * 8)[:8]
        out.append(sum(bit << k for k, bit in enumerate(data)))
        i += 10
    return bytes(out)


DUE_EPS_S = 1e-9
"""Bytes due this close after now count as due: a simulated clock may stop a rounding
error short of a time, and a reader waiting for them would then wait for nothing."""


def pop_due(queue: list[tuple[float, bytes]], now: float, max_bytes: int | None = None
            ) -> bytes:
    """Take from ``queue`` (due time, bytes; in time order) the bytes due by ``now``, at
    most ``max_bytes`` (the rest of a cut item stays at its place)."""
    out = bytearray()
    while queue and queue[0][0] <= now + DUE_EPS_S:
        when, data = queue.pop(0)
        if max_bytes is not None and len(out) + len(data) > max_bytes:
            keep = max_bytes - len(out)
            out += data[:keep]
            queue.insert(0, (when, data[keep:]))
            break
        out += data
    return bytes(out)


class SimLine(Protocol):
    """The host's end of a simulated line: what a transport or a pty serves."""

    framing: str
    """The protocol on the line: ``lx`` (servos) or ``board`` (a controller board)."""
    clock: Clock
    timing: WireTiming

    def receive(self, data: bytes) -> None: ...

    def pop_output(self, max_bytes: int | None = None) -> bytes: ...

    def next_output_at(self) -> float | None: ...

    def power_off(self) -> None: ...


class SimBus:
    """Simulated servos on one half-duplex line. Thread-safe.

    Its time is ``clock``'s: by default a simulated clock of its own (``SimClock``), so
    that waiting for a move or a reply costs only the CPU it takes to simulate; the
    servos given must have been made at ``clock.now()``. A bus served on a pty, which
    other programs talk to in wall-clock time, is given ``WALL_CLOCK``.
    """

    framing = "lx"

    def __init__(
        self,
        servos: Sequence[SimServo],
        *,
        timing: WireTiming | None = None,
        echo: bool = False,
        faults: FaultInjection | None = None,
        clock: Clock | None = None,
        state_file: Path | None = None,
    ) -> None:
        self.servos = list(servos)
        self.timing = timing or WireTiming()
        self.echo = echo
        self.faults = faults or FaultInjection()
        self.clock: Clock = clock if clock is not None else SimClock()
        self.state_file = state_file
        self._rng = random.Random(self.faults.seed)
        self._parser = FrameParser()
        self._lock = threading.Lock()
        self._out: list[tuple[float, bytes]] = []  # (ready time, bytes), in time order
        self._line_in_free = 0.0
        self._line_out_free = 0.0
        self._pending_stray = b""
        self._pending_delay = 0.0
        self.frames_received = 0
        self.frames_rejected = 0
        self.taps: list[Callable[[Request], None]] = []
        """Called with every request the servos receive, as it arrives (a probe on the
        line: tests and benchmarks time what reached the servos, and when)."""

    @classmethod
    def with_ids(
        cls,
        ids: Iterable[int] = ARM_SERVO_IDS,
        *,
        gripper_id: int | None = GRIPPER_ID,
        state_file: Path | None = None,
        clock: Clock | None = None,
        **kwargs: object,
    ) -> SimBus:
        """Servos with these IDs (the arm's by default). With ``state_file``, their stored
        settings are loaded from it if it exists and saved to it on every saved write.
        On a simulated clock of its own unless ``clock`` is given (``WALL_CLOCK`` for a
        bus served on a pty, which other programs talk to in wall-clock time)."""
        ids = list(ids)
        clock = clock if clock is not None else SimClock()
        now = clock.now()
        if state_file is not None and not state_file.parent.is_dir():
            raise ConfigError(
                f"state file {state_file}: directory {state_file.parent} does not exist"
            )
        stored = load_state(state_file) if state_file is not None else None
        servos: list[SimServo] = []
        if stored is not None:
            for record in stored:
                params = (
                    ServoParams.gripper() if record.get("id") == gripper_id else ServoParams()
                )
                servos.append(servo_from_record(record, params=params, now=now))
        else:
            for sid in ids:
                params = ServoParams.gripper() if sid == gripper_id else ServoParams()
                servos.append(SimServo(sid, params=params, now=now))
        return cls(servos, state_file=state_file, clock=clock, **kwargs)  # type: ignore[arg-type]

    # ------------------------------------------------------------------ wire side

    def receive(self, data: bytes) -> None:
        """Bytes the host has put on the line."""
        with self._lock:
            now = self.clock.now()
            t = self.timing
            done = max(now, self._line_in_free) + (len(data) * t.byte_s if t.enabled else 0.0)
            self._line_in_free = done
            if self.echo:
                self._schedule(done if t.enabled else now, bytes(data))
            if self.faults.directions in ("rx", "both"):
                data = self._mangle(data)
            for frame in self._parser.feed(data):
                self._on_frame(frame, done)

    def pop_output(self, max_bytes: int | None = None) -> bytes:
        """The bytes due on the host's side by now (at most ``max_bytes``; the rest stay)."""
        with self._lock:
            return pop_due(self._out, self.clock.now(), max_bytes)

    def next_output_at(self) -> float | None:
        """When the next bytes are due, or None if nothing is scheduled."""
        with self._lock:
            return self._out[0][0] if self._out else None

    @property
    def lock(self) -> threading.Lock:
        """The lock every bus operation holds; an outside model that advances or reads
        the servos (the twin's physics) holds it too."""
        return self._lock

    # ------------------------------------------------------------------ test hooks

    def inject_stray_bytes(self, data: bytes) -> None:
        """Put ``data`` on the line just before the next reply (line noise)."""
        with self._lock:
            self._pending_stray += data

    def delay_next_reply(self, delay_s: float) -> None:
        """Make the next reply arrive ``delay_s`` late (a servo busy, a slow adapter)."""
        with self._lock:
            self._pending_delay = delay_s

    def put_block_in_gripper(self, present: bool = True) -> None:
        """Put (or take away) a 3 cm block between the gripper's fingers: closing on it
        stops the gripper servo at BLOCK_GRIP_PULSES, as a real block would."""
        with self._lock:
            gripper = self.servo(GRIPPER_ID)
            gripper.advance(self.clock.now())
            gripper.set_obstacle(None, BLOCK_GRIP_PULSES if present else None)

    def servo(self, servo_id: int) -> SimServo:
        """The (first) simulated servo answering to ``servo_id``."""
        for s in self.servos:
            if s.servo_id == servo_id:
                return s
        raise ConfigError(f"no simulated servo with ID {servo_id}")

    def advance(self) -> None:
        """Bring every servo's motion and temperature up to the present."""
        with self._lock:
            now = self.clock.now()
            for s in self.servos:
                s.advance(now)

    # ------------------------------------------------------------------ internals

    def _on_frame(self, frame: Frame, done: float) -> None:
        try:
            request = decode_request(frame)
        except ProtocolError:
            # A real servo ignores what it cannot parse (replies are echoes, say).
            self.frames_rejected += 1
            return
        self.frames_received += 1
        for tap in self.taps:
            tap(request)
        targets = [
            s for s in self.servos
            if (request.servo_id == BROADCAST_ID or s.servo_id == request.servo_id)
        ]
        replies: list[bytes] = []
        for servo in targets:
            if not servo.is_responsive(done):
                continue
            reply = servo.handle(request, done)
            if reply is None:
                continue
            if request.servo_id == BROADCAST_ID and request.command is not Command.ID_READ:
                continue
            replies.append(encode_reply(servo.servo_id, reply))
        if request.command in SAVED_ON_POWER_OFF and targets and self.state_file is not None:
            self._save()
        if not replies:
            return
        data = replies[0] if len(replies) == 1 else self._collide(replies)
        t = self.timing
        start = max(done + (t.turnaround_s if t.enabled else 0.0), self._line_out_free)
        if self._pending_stray:
            data = self._pending_stray + data
            self._pending_stray = b""
        if self.faults.directions in ("tx", "both"):
            data = self._mangle(data)
        ready = start + (len(data) * t.byte_s if t.enabled else 0.0)
        if self._pending_delay:
            ready += self._pending_delay
            self._pending_delay = 0.0
        elif self.faults.late_rate and self._rng.random() < self.faults.late_rate:
            ready += self.faults.late_s
        # One wire: nothing said after a late reply can overtake it.
        self._line_out_free = ready
        if data:
            self._schedule(ready, data)

    def _collide(self, replies: list[bytes]) -> bytes:
        """What the host receives when several servos answer at once.

        The line is open-drain, so a 0 bit from any servo wins (wired-AND). The
        servos do not start in the same bit: each firmware answers after its own
        jitter, modelled as 1..MAX_SKEW_BITS bits after the first. Even identical
        replies therefore garble, as they do on a real bus.
        """
        streams = [_uart_bits(replies[0])]
        streams += [[1] * self._rng.randint(1, MAX_SKEW_BITS) + _uart_bits(r) for r in replies[1:]]
        length = max(len(s) for s in streams)
        line = [min(s[i] if i < len(s) else 1 for s in streams) for i in range(length)]
        return _uart_bytes(line)

    def _schedule(self, when: float, data: bytes) -> None:
        self._out.append((when, data))
        if len(self._out) > 1 and self._out[-2][0] > when:
            self._out.sort(key=lambda item: item[0])

    def _mangle(self, data: bytes) -> bytes:
        f = self.faults
        if not (f.drop_rate or f.corrupt_rate):
            return data
        rng = self._rng
        out = bytearray()
        for b in data:
            if f.drop_rate and rng.random() < f.drop_rate:
                continue
            if f.corrupt_rate and rng.random() < f.corrupt_rate:
                b ^= rng.randrange(1, 256)
            out.append(b)
        return bytes(out)

    def power_off(self) -> None:
        """Save what survives power-off (with a state file): stored settings and where
        each horn now is. Called when a server stops."""
        if self.state_file is not None:
            self.advance()
            with self._lock:
                self._save()

    def _save(self) -> None:
        assert self.state_file is not None
        save_state(self.state_file, [record_from_servo(s) for s in self.servos])
