"""A driver for the Slamtec RPLIDAR A1 on its USB serial port (the standard scan).

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
    SCAN_DESCRIPTOR,
    Cmd,
    Descriptor,
    DeviceInfo,
    Health,
    HealthStatus,
    Node,
    NodeParser,
    decode_health,
    decode_info,
    encode_request,
    find_descriptor,
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


def open_lidar(port: str | Transport, *,
               timeout_s: float = IDENTIFY_TIMEOUT_S) -> RplidarA1:
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
        return RplidarA1(transport, timeout_s=timeout_s)
    except BaseException:
        transport.close()
        raise


class RplidarA1:
    """One A1 on an open transport; a ``LidarSource``. Not thread-safe."""

    def __init__(self, transport: Transport, *, timeout_s: float = IDENTIFY_TIMEOUT_S) -> None:
        self.transport = transport
        self.clock = transport.clock
        self.name = transport.name
        self._parser = NodeParser()
        self._queue: deque[tuple[Node, float]] = deque()
        self._revolution: list[Node] | None = None
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
        """The next complete revolution (from a node with S = 1 to the next); a
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

    @property
    def noise_bytes(self) -> int:
        """Bytes skipped so far while looking for measurements (line noise)."""
        return self._parser.skipped_bytes

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
        self._queue.clear()
        self._revolution = None

    def _await_descriptor(self, cmd: Cmd, want: Descriptor, timeout_s: float) -> bytes:
        """Send ``cmd``; the bytes after the reply descriptor ``want``."""
        self.transport.write(encode_request(cmd))
        deadline = self.clock.now() + timeout_s
        got = bytearray()
        while True:
            found = find_descriptor(bytes(got))
            if found is not None:
                descriptor, end = found
                if descriptor != want:
                    raise self._not_lidar(cmd, f"it answered with descriptor {descriptor}, "
                                               f"not {want}")
                return bytes(got[end:])
            remaining = deadline - self.clock.now()
            if remaining <= 0:
                heard = f"{len(got)} bytes of something else" if got else "nothing"
                raise self._not_lidar(cmd, f"{heard} in {timeout_s:g} s")
            got += self.transport.read(4096, min(remaining, _READ_CHUNK_S))

    def _ask(self, cmd: Cmd, want: Descriptor, decode: Callable[[bytes], T],
             timeout_s: float) -> T:
        data = self._await_descriptor(cmd, want, timeout_s)
        deadline = self.clock.now() + timeout_s
        while len(data) < want.length:
            remaining = deadline - self.clock.now()
            if remaining <= 0:
                raise self._not_lidar(cmd, f"its reply stopped after {len(data)} of "
                                           f"{want.length} bytes")
            data += self.transport.read(4096, min(remaining, _READ_CHUNK_S))
        return decode(data[: want.length])

    def _not_lidar(self, cmd: Cmd, what: str) -> NotALidarError:
        return NotALidarError(
            f"{self.name} does not answer like an RPLIDAR: to {cmd.name} {what}; is it the "
            "Lidar's port? (`busarm ports` lists this computer's serial ports)")

    def _start_scan(self, timeout_s: float) -> None:
        rest = self._await_descriptor(Cmd.SCAN, SCAN_DESCRIPTOR, timeout_s)
        self._scanning = True
        self._feed(rest)

    def _feed(self, data: bytes) -> None:
        at = self.clock.now() - self.transport.latency_s
        # An angle past 360 degrees is noise that passed the check bits.
        nodes = [n for n in self._parser.feed(data) if n.angle_q6 < 360 * 64]
        # Nodes read together arrived one after another: each is dated back by the line
        # time of the nodes behind it (a long read would otherwise give a revolution 0 s).
        node_s = NODE_SIZE * 10.0 / self.transport.baudrate if self.transport.baudrate else 0.0
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
                if node.start:
                    done = self._revolution
                    started = self._revolution_start_s
                    self._revolution, self._revolution_start_s = [node], at
                    if done and self._whole(at - started):
                        return _scan(done, started, at - started)
                elif self._revolution is not None:
                    self._revolution.append(node)
            remaining = deadline - self.clock.now()
            if remaining <= 0:
                raise BusTimeoutError(
                    f"no complete scan from the Lidar on {self.name} in {timeout_s:g} s "
                    f"({self._parser.skipped_bytes} bytes skipped as noise so far)",
                    timeout_s=timeout_s)
            self._feed(self.transport.read(4096, min(remaining, _READ_CHUNK_S)))


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
