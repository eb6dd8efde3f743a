"""A driver for the Slamtec RPLIDAR A1 on its USB serial port (the standard scan, or
the express scan with ``express=True``; the sample rate and the scan modes on request).

``open_lidar("/dev/ttyUSB1")`` opens the port at 115200 baud, starts the motor (the A1's
USB adapter runs it while DTR is *clear*, as Slamtec's SDK does), stops any scan left
running, checks that the device answers GET_HEALTH and GET_INFO like an RPLIDAR (else
one NotALidarError), starts scanning and hands out one ``LaserScan`` per revolution.
``open_lidar("lidar://sim")`` is the simulated A1 in this process.

Closing, and any exception while reading, sends STOP: the A1 never keeps streaming into
a port nobody reads.
"""

from __future__ import annotations

import contextlib
import math
import statistics
from collections import deque
from collections.abc import Callable
from enum import Enum
from types import TracebackType
from typing import TypeVar

import numpy as np

from busarm.bus.transport import Transport, open_serial
from busarm.errors import BusTimeoutError, ConfigError, LidarFaultError, NotALidarError
from busarm.errors import TransportError as _TransportError
from busarm.lidar.scan import LaserScan
from busarm.protocol.rplidar import (
    A1_RANGE_MAX_M,
    A1_RANGE_MIN_M,
    HEALTH_DESCRIPTOR,
    INFO_DESCRIPTOR,
    NODE_SIZE,
    RPLIDAR_BAUDRATE,
    SAMPLERATE_DESCRIPTOR,
    SCAN_DESCRIPTOR,
    Cmd,
    ConfType,
    DataType,
    Descriptor,
    DeviceInfo,
    Health,
    HealthStatus,
    Node,
    NodeParser,
    SampleRate,
    ScanMode,
    conf_payload,
    decode_conf,
    decode_health,
    decode_info,
    decode_q8,
    decode_samplerate,
    encode_request,
    find_descriptor,
)
from busarm.protocol.rplidar_express import (
    CAPSULE_SAMPLES,
    CAPSULE_SIZE,
    EXPRESS_DESCRIPTOR,
    CapsuleParser,
    express_payload,
)

MAX_REVOLUTION_S = 0.75
"""The longest a revolution takes (the A1 turns at 2 Hz at its slowest, with a margin): a
longer one was read across a pause and is passed over."""
IDENTIFY_TIMEOUT_S = 0.5
"""How long the A1 may take to answer GET_HEALTH or GET_INFO (it answers in ~1 ms)."""
STOP_SETTLE_S = 0.01
"""After STOP, how long bytes already on their way may still arrive (then discarded)."""
_READ_CHUNK_S = 0.05

T = TypeVar("T")


def open_lidar(port: str | Transport, *, timeout_s: float = IDENTIFY_TIMEOUT_S,
               express: bool = False) -> RplidarA1:
    """The A1 on ``port``: a serial device's path or pyserial URL, or an open transport
    (the simulated A1's: ``SimLidarSpec().open()``), closed if it does not answer."""
    if isinstance(port, str):
        if not port.strip():
            raise ConfigError(f"Lidar port must be a device path or a pyserial URL, got "
                              f"{port!r}")
        transport: Transport = open_serial(port, RPLIDAR_BAUDRATE, name=port, framing="rplidar")
    else:
        transport = port
    try:
        return RplidarA1(transport, timeout_s=timeout_s, express=express)
    except BaseException:
        transport.close()
        raise


class RplidarA1:
    """One A1 on an open transport; a ``LidarSource``. Not thread-safe."""

    def __init__(self, transport: Transport, *, timeout_s: float = IDENTIFY_TIMEOUT_S,
                 express: bool = False) -> None:
        self.transport = transport
        self.clock = transport.clock
        self.name = transport.name
        self._parser = NodeParser()
        self._capsules = CapsuleParser()
        self.express = express
        """Whether scans are read in the express scan (capsules, 4 kHz on an A1)."""
        self._queue: deque[tuple[Node, float]] = deque()
        self._revolution: list[Node] | None = None
        self._angles = _AngleTrack()
        self._revolution_start_s = math.nan
        self._spans: deque[float] = deque(maxlen=5)
        """How long the last revolutions took (s), whole or not."""
        self._scanning = False
        self._closed = False
        self.motor_line = self._set_motor(True)
        """Whether the port has a DTR line to run the motor with (a pty has none)."""
        try:
            self._send_stop()
            self.health = self._ask(Cmd.GET_HEALTH, HEALTH_DESCRIPTOR, decode_health, timeout_s)
            self.info: DeviceInfo = self._ask(Cmd.GET_INFO, INFO_DESCRIPTOR, decode_info,
                                              timeout_s)
            if self.health.status is HealthStatus.ERROR:
                raise LidarFaultError(
                    f"the Lidar on {self.name} reports health ERROR (code "
                    f"0x{self.health.error_code:04X}); power-cycle it")
            self._start_scan(timeout_s)
        except BaseException:
            self._set_motor(False)
            raise

    def __repr__(self) -> str:
        major, minor = self.info.firmware
        return (f"RplidarA1({self.name}, firmware {major}.{minor:02d}, health "
                f"{self.health.status.name}{', closed' if self._closed else ''})")

    # ------------------------------------------------------------------ public

    def read_scan(self, timeout_s: float = 1.0) -> LaserScan:
        """The next complete revolution (from where the angle wraps to where it next
        does: the S flag is not trusted, noise fakes it); a
        BusTimeoutError if none completes in ``timeout_s``. STOP is sent on any error."""
        if self._closed:
            raise _TransportError(f"{self.name}: the Lidar is closed")
        try:
            if not self._scanning:
                self._start_scan(IDENTIFY_TIMEOUT_S)
            return self._next_revolution(timeout_s)
        except BaseException:
            with contextlib.suppress(_TransportError):
                self._send_stop()
            raise

    def sample_rate(self) -> SampleRate:
        """GET_SAMPLERATE: us per sample in the standard and the express scan (a scan
        under way stops; the next read_scan starts it again)."""
        self._send_stop()
        return self._ask(Cmd.GET_SAMPLERATE, SAMPLERATE_DESCRIPTOR, decode_samplerate,
                         IDENTIFY_TIMEOUT_S)

    def scan_modes(self) -> tuple[list[ScanMode], int]:
        """GET_LIDAR_CONF, as Slamtec's SDK asks it: every scan mode and the typical one's
        id (a scan under way stops; the next read_scan starts it again)."""
        self._send_stop()
        count = int.from_bytes(self._conf(ConfType.SCAN_MODE_COUNT), "little")
        typical = int.from_bytes(self._conf(ConfType.SCAN_MODE_TYPICAL), "little")
        modes = [ScanMode(m, self._conf(ConfType.SCAN_MODE_NAME, m).split(b"\0")[0]
                          .decode("ascii", "replace"),
                          decode_q8(self._conf(ConfType.SCAN_MODE_US_PER_SAMPLE, m)),
                          decode_q8(self._conf(ConfType.SCAN_MODE_MAX_DISTANCE, m)),
                          self._conf(ConfType.SCAN_MODE_ANS_TYPE, m)[0])
                 for m in range(count)]
        return modes, typical

    @property
    def noise_bytes(self) -> int:
        """Bytes skipped so far while looking for measurements (line noise)."""
        return self._parser.skipped_bytes + self._capsules.skipped_bytes

    def use_express(self, express: bool) -> None:
        """Read the express scan (True) or the standard one from the next read_scan on."""
        if express != self.express:
            self._send_stop()
            self.express = express

    def close(self) -> None:
        """Send STOP, stop the motor, close the port (idempotent)."""
        if self._closed:
            return
        self._closed = True
        try:
            with contextlib.suppress(_TransportError):
                self._send_stop(settle=False)
                self._set_motor(False)
        finally:
            self.transport.close()

    def __enter__(self) -> RplidarA1:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ internals

    def _set_motor(self, on: bool) -> bool:
        set_dtr: Callable[[bool], bool] | None = getattr(self.transport, "set_dtr", None)
        # The A1's adapter drives the motor from the inverse of DTR (Slamtec's SDK clears
        # DTR to start it).
        return bool(set_dtr(not on)) if set_dtr is not None else False

    def _send_stop(self, settle: bool = True) -> None:
        self.transport.write(encode_request(Cmd.STOP))
        self._scanning = False
        if settle:
            self.clock.sleep(STOP_SETTLE_S)
            self.transport.reset_input()
        self._parser.reset()
        self._capsules.reset()
        self._queue.clear()
        self._revolution = None
        self._angles = _AngleTrack()

    def _await_descriptor(self, cmd: Cmd, want: Descriptor, timeout_s: float,
                          payload: bytes = b"") -> bytes:
        """Send ``cmd``; the bytes after the reply descriptor ``want``."""
        self.transport.write(encode_request(cmd, payload))
        descriptor, rest = self._await_any(cmd, want.data_type, timeout_s)
        if descriptor != want:
            raise self._not_lidar(cmd, f"it answered with descriptor {descriptor}, not {want}")
        return rest

    def _await_any(self, cmd: Cmd, data_type: int,
                   timeout_s: float) -> tuple[Descriptor, bytes]:
        """The next reply descriptor (of ``data_type``) and the bytes after it."""
        deadline = self.clock.now() + timeout_s
        got = bytearray()
        while True:
            found = find_descriptor(bytes(got))
            if found is not None:
                descriptor, end = found
                if descriptor.data_type != data_type:
                    raise self._not_lidar(cmd, f"it answered with descriptor {descriptor}")
                return descriptor, bytes(got[end:])
            remaining = deadline - self.clock.now()
            if remaining <= 0:
                heard = f"{len(got)} bytes of something else" if got else "nothing"
                raise self._not_lidar(cmd, f"{heard} in {timeout_s:g} s")
            got += self.transport.read(4096, min(remaining, _READ_CHUNK_S))

    def _ask(self, cmd: Cmd, want: Descriptor, decode: Callable[[bytes], T],
             timeout_s: float) -> T:
        data = self._await_descriptor(cmd, want, timeout_s)
        return decode(self._read_rest(cmd, data, want.length, timeout_s))

    def _read_rest(self, cmd: Cmd, data: bytes, length: int, timeout_s: float) -> bytes:
        """A reply of ``length`` bytes, of which ``data`` has come."""
        deadline = self.clock.now() + timeout_s
        while len(data) < length:
            remaining = deadline - self.clock.now()
            if remaining <= 0:
                raise self._not_lidar(cmd, f"its reply stopped after {len(data)} of "
                                           f"{length} bytes")
            data += self.transport.read(4096, min(remaining, _READ_CHUNK_S))
        return data[:length]

    def _conf(self, conf: ConfType, mode: int | None = None) -> bytes:
        """One GET_LIDAR_CONF entry's value."""
        self.transport.write(encode_request(Cmd.GET_LIDAR_CONF, conf_payload(conf, mode)))
        descriptor, data = self._await_any(Cmd.GET_LIDAR_CONF, DataType.LIDAR_CONF,
                                           IDENTIFY_TIMEOUT_S)
        return decode_conf(self._read_rest(Cmd.GET_LIDAR_CONF, data, descriptor.length,
                                           IDENTIFY_TIMEOUT_S), conf)

    def _not_lidar(self, cmd: Cmd, what: str) -> NotALidarError:
        return NotALidarError(
            f"{self.name} does not answer like an RPLIDAR: to {cmd.name} {what}; is it the "
            "Lidar's port? (`busarm ports` lists this computer's serial ports)")

    def _start_scan(self, timeout_s: float) -> None:
        if self.express:
            rest = self._await_descriptor(Cmd.EXPRESS_SCAN, EXPRESS_DESCRIPTOR, timeout_s,
                                          express_payload(0))
        else:
            rest = self._await_descriptor(Cmd.SCAN, SCAN_DESCRIPTOR, timeout_s)
        self._scanning = True
        self._feed(rest)

    def _feed(self, data: bytes) -> None:
        at = self.clock.now() - self.transport.latency_s
        # An angle past 360 degrees is noise that passed the check bits.
        parser = self._capsules if self.express else self._parser
        nodes = [n for n in parser.feed(data) if n.angle_q6 < 360 * 64]
        # Nodes read together arrived one after another: each is dated back by the line
        # time of the nodes behind it (a long read would otherwise give a revolution 0 s).
        node_bytes = CAPSULE_SIZE / CAPSULE_SAMPLES if self.express else NODE_SIZE
        node_s = node_bytes * 10.0 / self.transport.baudrate if self.transport.baudrate else 0.0
        for k, node in enumerate(nodes):
            self._queue.append((node, at - (len(nodes) - 1 - k) * node_s))

    def _whole(self, span_s: float) -> bool:
        """Whether a revolution that took ``span_s`` is one turn: one that took longer than
        the slowest turn, or half as long again as the recent ones (their median), spans
        a pause in the reading (nodes from before and after it, some lost between): it is
        passed over."""
        typical = statistics.median(self._spans) if self._spans else math.inf
        self._spans.append(span_s)
        return span_s <= min(MAX_REVOLUTION_S, 1.5 * typical)

    def _next_revolution(self, timeout_s: float) -> LaserScan:
        deadline = self.clock.now() + timeout_s
        while True:
            while self._queue:
                node, at = self._queue.popleft()
                step = self._angles.step(node.angle_q6)
                if step is _Step.WRAP:
                    done = self._revolution
                    started = self._revolution_start_s
                    self._revolution, self._revolution_start_s = [node], at
                    if done and self._whole(at - started):
                        return _scan(done, started, at - started)
                elif step is _Step.LOST:
                    self._revolution = None
                elif step is _Step.ON and self._revolution is not None:
                    self._revolution.append(node)
            remaining = deadline - self.clock.now()
            if remaining <= 0:
                raise BusTimeoutError(
                    f"no complete scan from the Lidar on {self.name} in {timeout_s:g} s "
                    f"({self._parser.skipped_bytes} bytes skipped as noise so far)",
                    timeout_s=timeout_s)
            self._feed(self.transport.read(4096, min(remaining, _READ_CHUNK_S)))


class _Step(Enum):
    ON = "on"
    """A node that follows the last one: same revolution."""
    WRAP = "wrap"
    """A node that follows the last one past 360 degrees: a new revolution."""
    ASTRAY = "astray"
    """A node far from the last one: noise that passed the check bits; dropped."""
    LOST = "lost"
    """Several astray in a row: the track itself was lost (a pause, or anchored on
    noise); the revolution under way is dropped and the track starts again here."""


MAX_STEP_FWD_Q6 = 30 * 64
"""How far (degrees x 64) a node may be ahead of the last one and still follow it: a few
nodes lost to noise at the A1's 1-degree spacing; random noise passes 1 time in 12."""
MAX_STEP_BACK_Q6 = 5 * 64
"""How far a node may be behind the last one (the A1's angles jitter a little)."""
ASTRAY_TO_LOST = 4
_HALF_TURN_Q6 = 180 * 64


class _AngleTrack:
    """Where a revolution starts: where the wire angle wraps (the S flag is not trusted:
    stray bytes make nodes whose S is set), among nodes that follow one another, and
    only past half a turn since the last wrap (so a noise node just past 0 degrees, then
    the real ones just before it, is not two wraps)."""

    def __init__(self) -> None:
        self._last_q6: int | None = None
        self._turned_q6 = _HALF_TURN_Q6
        """How far the angle has gone since the last wrap (from a new anchor: far enough,
        so the first wrap after it counts)."""
        self._astray = 0

    def step(self, angle_q6: int) -> _Step:
        last = self._last_q6
        if last is None:
            self._last_q6 = angle_q6
            return _Step.LOST
        # The signed step from the last node, -180..180 degrees.
        full = 360 * 64
        delta = (angle_q6 - last + full // 2) % full - full // 2
        if not -MAX_STEP_BACK_Q6 <= delta <= MAX_STEP_FWD_Q6:
            self._astray += 1
            if self._astray < ASTRAY_TO_LOST:
                return _Step.ASTRAY
            self._astray, self._last_q6, self._turned_q6 = 0, angle_q6, _HALF_TURN_Q6
            return _Step.LOST
        self._astray, self._last_q6 = 0, angle_q6
        self._turned_q6 += delta
        if delta > 0 and angle_q6 < last and self._turned_q6 >= _HALF_TURN_Q6:
            self._turned_q6 = angle_q6
            return _Step.WRAP
        return _Step.ON


def _scan(nodes: list[Node], stamp_s: float, scan_time_s: float) -> LaserScan:
    """A LaserScan of one revolution's nodes (counter-clockwise angles, ascending)."""
    q6 = np.array([n.angle_q6 for n in nodes], dtype=np.float64)
    # The A1 turns clockwise: a wire angle a is the bearing -a.
    angles = np.radians((-q6 / 64.0) % 360.0)
    ranges = np.array([n.distance_q2 for n in nodes], dtype=np.float64) / 4000.0
    ranges[(ranges < A1_RANGE_MIN_M) | (ranges > A1_RANGE_MAX_M)] = np.nan
    quality = np.array([n.quality for n in nodes], dtype=np.float64)
    order = np.argsort(angles, kind="stable")
    return LaserScan(angles[order], ranges[order], np.where(np.isnan(ranges), 0.0, quality)[order],
                     stamp_s=stamp_s, range_min_m=A1_RANGE_MIN_M, range_max_m=A1_RANGE_MAX_M,
                     scan_time_s=scan_time_s if scan_time_s > 0 else math.nan)


__all__ = ["MAX_REVOLUTION_S", "Health", "RplidarA1", "open_lidar"]
