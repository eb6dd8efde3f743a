"""A simulated Slamtec RPLIDAR A1 on its serial line: requests in, replies and scans out.

``SimRplidar`` is a line like ``SimBus`` (``busarm.sim.bus.SimLine``): serve it on a pty
(``PtyServer``) or in this process (``busarm.sim.spec.SimLidarSpec``).
It answers GET_INFO (as an A1M8 would) and GET_HEALTH, and after SCAN streams
measurement nodes of a 2D world (a callable: bearing, counter-clockwise in the Lidar's
frame, in rad -> range in m) at ``sample_hz`` nodes a second, ``scan_hz`` revolutions a
second (the A1: 2000 samples/s at 5.5 Hz, about 1 degree apart), until STOP or RESET.

Like the real unit its wire angles run clockwise; the first node of each revolution
carries S = 1. GET_SAMPLERATE and GET_LIDAR_CONF answer as an A1 on firmware 1.29
does (its scan modes: Standard and Express); EXPRESS_SCAN streams capsules of 32 samples
at twice the standard rate (4 kHz). Not modelled: the motor's spin-up, angle jitter
between revolutions, intensity beyond a fixed quality, the angle offsets of express
samples (sent as 0), and the Boost mode.

Its settings (the command line's ``lidar://sim?hz=10``): ``SimLidarSpec``.
"""

from __future__ import annotations

import math
import random
import threading
from collections.abc import Callable

from busarm.clock import Clock, SimClock
from busarm.errors import ConfigError
from busarm.protocol.rplidar import (
    A1_RANGE_MAX_M,
    A1_RANGE_MIN_M,
    HEALTH_DESCRIPTOR,
    INFO_DESCRIPTOR,
    MAX_DISTANCE_Q2,
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
    NodeFields,
    Request,
    RequestParser,
    SampleRate,
    ScanMode,
    conf_descriptor,
    node_from_si,
    pack_nodes,
)
from busarm.protocol.rplidar_express import (
    CAPSULE_SAMPLES,
    EXPRESS_DESCRIPTOR,
    MAX_DISTANCE_MM,
    Capsule,
)
from busarm.sim.bus import WireTiming, pop_due
from busarm.units import check_int_range, check_range

__all__ = [
    "A1_INFO",
    "A1_SAMPLE_HZ",
    "A1_TYPICAL_MODE",
    "BATCH_NODES",
    "GOOD_QUALITY",
    "MAX_BACKLOG_S",
    "RESET_BANNER",
    "SimRplidar",
    "World",
    "rectangular_room",
]


World = Callable[[float], float]
"""Bearing (rad, counter-clockwise from the Lidar's forward axis) -> range (m); inf or
NaN where nothing is in reach. A world that also has ``ranges(bearings) -> ranges`` is
asked for each batch of nodes at once (a ray caster casts them together)."""

A1_SAMPLE_HZ = 2000.0
"""The A1's standard-scan sample rate."""
A1_TYPICAL_MODE = 1
"""The mode GET_LIDAR_CONF calls typical: Express (a real 1.29 A1 names Boost)."""
GOOD_QUALITY = 47
"""The quality an A1 reports for a solid return (its usual 0xBC >> 2)."""
A1_INFO = DeviceInfo(model=0x18, firmware=(1, 29), hardware=7,
                     serial_number=bytes.fromhex("B2E0F8C3F3E29BD4C2E59EF70A5F4313"))
RESET_BANNER = b"RP LIDAR System.\r\nFirmware Ver 1.29 - rtm, HW Ver 7\r\nModel: 18\r\n"
"""What an A1 prints after RESET (text the host must skip)."""
BATCH_NODES = 32
"""Nodes delivered together (16 ms at 2000/s), as a USB serial adapter's latency timer
batches them (16 ms by default on FTDI's; the A1's CP2102 batches too)."""
MAX_BACKLOG_S = 0.5
"""Unread scan data older than this is lost, as a full serial buffer loses it."""


def rectangular_room(
    x_min_m: float = -1.5, x_max_m: float = 2.5, y_min_m: float = -1.0, y_max_m: float = 2.0,
) -> World:
    """The walls of a rectangle around the Lidar (which sits at 0, 0, facing +x)."""
    if not (x_min_m < 0 < x_max_m and y_min_m < 0 < y_max_m):
        raise ConfigError(f"room x {x_min_m:g}..{x_max_m:g} m, y {y_min_m:g}..{y_max_m:g} m "
                          "must contain the Lidar at 0, 0")

    def ray(bearing_rad: float) -> float:
        c, s = math.cos(bearing_rad), math.sin(bearing_rad)
        hits = []
        if c > 1e-12:
            hits.append(x_max_m / c)
        elif c < -1e-12:
            hits.append(x_min_m / c)
        if s > 1e-12:
            hits.append(y_max_m / s)
        elif s < -1e-12:
            hits.append(y_min_m / s)
        return min(hits)

    return ray


class SimRplidar:
    """A simulated A1 on one full-duplex serial line. Thread-safe."""

    framing = "rplidar"

    def __init__(
        self, world: World | None = None, *, scan_hz: float = 5.5,
        sample_hz: float = A1_SAMPLE_HZ, clock: Clock | None = None,
        health: Health | None = None, garbage_rate: float = 0.0,
        garbage_max_bytes: int = 6, seed: int = 0, silent: bool = False,
    ) -> None:
        self.world = world or rectangular_room()
        self.scan_hz = check_range("scan_hz", scan_hz, 2.0, 10.0, "Hz")
        self.sample_hz = check_range("sample_hz", sample_hz, 100.0, 2300.0, "Hz")
        self.express_hz = 2.0 * self.sample_hz
        """The express scan's sample rate (the A1's: 4 kHz, twice the standard scan's)."""
        self.nodes_per_rev = round(self.sample_hz / self.scan_hz)
        self.express_per_rev = round(self.express_hz / self.scan_hz)
        # Each node's wire angle (q6) and bearing, the same every revolution, for each
        # scan. Clockwise on the wire: wire angle a is bearing -a in the Lidar's own frame.
        self._angles_q6 = _wire_angles(self.nodes_per_rev)
        self._bearings = [-math.radians(q6 / 64.0) for q6 in self._angles_q6]
        self._express_q6 = _wire_angles(self.express_per_rev)
        self._express_bearings = [-math.radians(q6 / 64.0) for q6 in self._express_q6]
        self.express = False
        """Whether the scan under way (or the last) is the express scan."""
        self.scan_modes = (
            ScanMode(0, "Standard", 1e6 / self.sample_hz, A1_RANGE_MAX_M, DataType.MEASUREMENT),
            ScanMode(1, "Express", 1e6 / self.express_hz, A1_RANGE_MAX_M, DataType.CAPSULE))
        """What GET_LIDAR_CONF lists (Slamtec's SDK shows an A1's as Standard 2K and
        Express 4K samples/s, 12 m; firmware 1.24 on adds Boost, 8K samples/s in ultra
        capsules, which this simulation does not have)."""
        self._first_capsule = False
        self.clock: Clock = clock or SimClock(step_s=0.002)
        self.timing = WireTiming(RPLIDAR_BAUDRATE, 0.001)
        self.health = health or Health(HealthStatus.GOOD, 0)
        self.garbage_rate = check_range("garbage_rate", garbage_rate, 0.0, 1.0)
        self.garbage_max_bytes = check_int_range("garbage_max_bytes", garbage_max_bytes, 1, 64)
        """Each burst of noise is 1 to this many random bytes."""
        self.silent = silent
        self._rng = random.Random(seed)
        self._parser = RequestParser()
        self._lock = threading.Lock()
        self._out: list[tuple[float, bytes]] = []
        self._epoch_s = self.clock.now()
        self._next_node: int | None = None  # index of the next node to send, None: not scanning
        self._pending_garbage = b""
        self.requests: list[Request] = []
        """Every request received, in order (a probe for tests)."""

    @property
    def sample_rate(self) -> SampleRate:
        """GET_SAMPLERATE's answer: us per sample, standard and express."""
        return SampleRate(round(1e6 / self.sample_hz), round(1e6 / self.express_hz))

    @property
    def scanning(self) -> bool:
        with self._lock:
            return self._next_node is not None

    # ------------------------------------------------------------------ wire side

    def receive(self, data: bytes) -> None:
        """Bytes the host has written."""
        with self._lock:
            now = self.clock.now()
            done = now + len(data) * self.timing.byte_s
            for request in self._parser.feed(bytes(data)):
                self.requests.append(request)
                if not self.silent:
                    self._on_request(request, done)

    def pop_output(self, max_bytes: int | None = None) -> bytes:
        """The bytes due on the host's side by now (at most ``max_bytes``)."""
        with self._lock:
            now = self.clock.now()
            self._produce_nodes(now)
            return pop_due(self._out, now, max_bytes)

    def next_output_at(self) -> float | None:
        """When the next bytes are due (a batch of nodes while scanning), or None."""
        with self._lock:
            times = [self._out[0][0]] if self._out else []
            if self._next_node is not None:
                times.append(self._node_time(self._next_node + BATCH_NODES - 1))
            return min(times) if times else None

    def power_off(self) -> None:
        """Stop scanning (nothing survives power-off)."""
        with self._lock:
            self._next_node = None

    # ------------------------------------------------------------------ test hooks

    def inject_garbage(self, data: bytes) -> None:
        """Put ``data`` on the line just before the next node (line noise)."""
        with self._lock:
            self._pending_garbage += bytes(data)

    def go_silent(self) -> None:
        """Stop sending and answering anything (an unplugged or stalled unit)."""
        with self._lock:
            self.silent = True
            self._next_node = None
            self._out.clear()

    def node(self, index: int) -> Node:
        """The node with global index ``index`` (the same every revolution)."""
        return self._nodes([index])[0]

    def _nodes(self, indices: list[int], express: bool = False) -> list[Node]:
        """The nodes of these global indices (in the standard or the express scan)."""
        return [Node(*fields) for fields in self._node_fields(indices, express)]

    def _node_fields(self, indices: list[int], express: bool = False) -> list[NodeFields]:
        """The nodes of these global indices as (start, quality, angle_q6, distance_q2),
        their ranges asked of the world together when it can answer several bearings at
        once (``ranges``: one ray cast for all)."""
        per_rev, angles_q6, all_bearings = (
            (self.express_per_rev, self._express_q6, self._express_bearings) if express
            else (self.nodes_per_rev, self._angles_q6, self._bearings))
        ks = [index % per_rev for index in indices]
        bearings = [all_bearings[k] for k in ks]
        batch = getattr(self.world, "ranges", None)
        ranges = batch(bearings) if batch is not None else [self.world(b) for b in bearings]
        out: list[NodeFields] = []
        isfinite = math.isfinite
        for k, range_m in zip(ks, ranges, strict=True):
            range_m = float(range_m)
            if isfinite(range_m) and A1_RANGE_MIN_M <= range_m <= A1_RANGE_MAX_M:
                out.append((k == 0, GOOD_QUALITY, angles_q6[k],
                            min(round(range_m * 4000.0), MAX_DISTANCE_Q2)))
            else:
                out.append((k == 0, 0, angles_q6[k], 0))
        return out

    # ------------------------------------------------------------------ internals

    def _node_time(self, index: int) -> float:
        """When node ``index``'s last byte reaches the host."""
        return self._epoch_s + (index + 1) / self._rate_hz()

    def _rate_hz(self) -> float:
        return self.express_hz if self.express else self.sample_hz

    def _on_request(self, request: Request, done: float) -> None:
        at = done + self.timing.turnaround_s
        if request.cmd in (Cmd.STOP, Cmd.RESET):
            self._next_node = None
            self._out.clear()
            if request.cmd == Cmd.RESET:
                self._schedule(at + 0.002, RESET_BANNER)
        elif request.cmd == Cmd.GET_INFO:
            self._schedule(at, INFO_DESCRIPTOR.encode() + A1_INFO.encode())
        elif request.cmd == Cmd.GET_HEALTH:
            self._schedule(at, HEALTH_DESCRIPTOR.encode() + self.health.encode())
        elif request.cmd == Cmd.GET_SAMPLERATE:
            self._schedule(at, SAMPLERATE_DESCRIPTOR.encode() + self.sample_rate.encode())
        elif request.cmd == Cmd.GET_LIDAR_CONF:
            answer = _conf_answer(self.scan_modes, request.payload)
            if answer is not None:
                self._schedule(at, answer)
        elif request.cmd == Cmd.SCAN and self.health.status is not HealthStatus.ERROR:
            self._start(at, SCAN_DESCRIPTOR, express=False)
        elif (request.cmd == Cmd.EXPRESS_SCAN and request.payload[:1] in (b"\x00", b"\x01")
              and self.health.status is not HealthStatus.ERROR):
            # Working mode 0 (legacy express) or 1 (the Express scan mode's id).
            self._start(at, EXPRESS_DESCRIPTOR, express=True)
        # Anything else: an A1 ignores requests it does not know.

    def _start(self, at: float, descriptor: Descriptor, *, express: bool) -> None:
        self._schedule(at, descriptor.encode())
        self.express = express
        # The motor already turns: the stream joins the revolution where it is.
        first = math.ceil((at - self._epoch_s) * self._rate_hz())
        # Capsules hold samples 32k..32k+31 (so the angles run on across a new scan).
        self._next_node = -(-first // CAPSULE_SAMPLES) * CAPSULE_SAMPLES if express else first
        self._first_capsule = express

    def _produce_nodes(self, now: float) -> None:
        if self._next_node is None:
            return
        if self.express:
            self._produce_capsules(now)
            return
        due_last = math.floor((now - self._epoch_s) * self.sample_hz) - 1
        oldest = due_last - int(MAX_BACKLOG_S * self.sample_hz)
        self._next_node = max(self._next_node, oldest)
        chunk = bytearray()
        indices = list(range(self._next_node, due_last + 1))
        nodes = self._node_fields(indices) if indices else []
        if nodes and not self.garbage_rate:  # the bytes of the loop below, packed at once
            chunk += self._pending_garbage
            self._pending_garbage = b""
            chunk += pack_nodes(nodes)
            nodes = []
        for node in nodes:
            if self._pending_garbage:
                chunk += self._pending_garbage
                self._pending_garbage = b""
            if self.garbage_rate and self._rng.random() < self.garbage_rate:
                chunk += self._rng.randbytes(self._rng.randint(1, self.garbage_max_bytes))
            chunk += pack_nodes((node,))
        self._next_node = max(self._next_node, due_last + 1)
        if chunk:
            self._schedule(self._node_time(due_last), bytes(chunk))

    def _produce_capsules(self, now: float) -> None:
        """The express scan's capsules whose 32 samples are all measured by ``now``."""
        assert self._next_node is not None
        due_last = math.floor((now - self._epoch_s) * self.express_hz) - 1
        oldest = due_last - int(MAX_BACKLOG_S * self.express_hz)
        if self._next_node < oldest:
            self._next_node += (oldest - self._next_node) // CAPSULE_SAMPLES * CAPSULE_SAMPLES
        chunk = bytearray()
        while self._next_node + CAPSULE_SAMPLES - 1 <= due_last:
            nodes = self._nodes(list(range(self._next_node,
                                           self._next_node + CAPSULE_SAMPLES)), express=True)
            if self._pending_garbage:
                chunk += self._pending_garbage
                self._pending_garbage = b""
            # The rate is per measurement: a capsule carries 32.
            if self.garbage_rate and self._rng.random() < 1.0 - (
                    1.0 - self.garbage_rate) ** CAPSULE_SAMPLES:
                chunk += self._rng.randbytes(self._rng.randint(1, self.garbage_max_bytes))
            chunk += Capsule(self._first_capsule, nodes[0].angle_q6,
                             tuple(min((n.distance_q2 + 2) // 4, MAX_DISTANCE_MM) for n in nodes),
                             (0,) * CAPSULE_SAMPLES).encode()
            self._first_capsule = False
            self._next_node += CAPSULE_SAMPLES
        if chunk:
            self._schedule(self._node_time(self._next_node - 1), bytes(chunk))

    def _schedule(self, when: float, data: bytes) -> None:
        self._out.append((when, data))
        self._out.sort(key=lambda item: item[0])


def _wire_angles(per_rev: int) -> list[int]:
    """The wire angles (q6) of ``per_rev`` nodes evenly around a revolution."""
    return [node_from_si(k == 0, GOOD_QUALITY, 2.0 * math.pi * k / per_rev, 1.0).angle_q6
            for k in range(per_rev)]


def _conf_answer(modes: tuple[ScanMode, ...], payload: bytes) -> bytes | None:
    """The descriptor and answer to GET_LIDAR_CONF ``payload``; None for a type or mode
    this A1 does not have (it then answers nothing)."""
    if len(payload) < 4:
        return None
    kind = int.from_bytes(payload[:4], "little")
    if kind == ConfType.SCAN_MODE_COUNT:
        value = len(modes).to_bytes(2, "little")
    elif kind == ConfType.SCAN_MODE_TYPICAL:
        value = A1_TYPICAL_MODE.to_bytes(2, "little")
    elif kind in (ConfType.SCAN_MODE_US_PER_SAMPLE, ConfType.SCAN_MODE_MAX_DISTANCE,
                  ConfType.SCAN_MODE_ANS_TYPE, ConfType.SCAN_MODE_NAME) and len(payload) >= 6:
        mode = int.from_bytes(payload[4:6], "little")
        if mode >= len(modes):
            return None
        value = modes[mode].value(ConfType(kind))
    else:
        return None
    return conf_descriptor(len(value)).encode() + payload[:4] + value
