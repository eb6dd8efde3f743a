"""A pure codec of the Slamtec RPLIDAR A1 serial protocol (the standard scan,
the sample rate and the scan modes' configuration).

Bytes only: no I/O, no clock. From the public protocol document:

- A request is ``A5 cmd``; a command with a payload (cmd >= 0x80) adds
  ``size payload checksum``, the checksum the XOR of every byte before it.
- A reply starts with a 7-byte descriptor ``A5 5A`` + 32 bits little-endian (the low 30
  bits the length of each data reply, the top 2 the send mode: 0 one reply, 1 a stream)
  + a data type byte.
- GET_INFO (0x50) answers type 0x04 with 20 bytes: model, firmware minor, firmware major,
  hardware, 16-byte serial number. GET_HEALTH (0x52) answers type 0x06 with 3 bytes:
  status (0 good, 1 warning, 2 error) and a 16-bit error code. SCAN (0x20) answers type
  0x81 in stream mode, then 5-byte measurement nodes until STOP (0x25) or RESET (0x40),
  which have no reply. GET_SAMPLERATE (0x59) answers type 0x15 with 4 bytes: the
  standard and the express scan's time per sample, in us (16 bits each).
- GET_LIDAR_CONF (0x84) carries a 32-bit little-endian configuration type (0x70 scan mode
  count, 0x71 a mode's us per sample, 0x74 its max distance, 0x75 its answer type, 0x7C
  the typical mode, 0x7F a mode's name), then for a mode's entry its 16-bit id; the
  answer (type 0x20) repeats the type, then the value: a 16-bit count or id, a 32-bit
  Q8 number (us, m), a byte, or the name's characters (NUL-terminated).
- EXPRESS_SCAN (0x82): busarm.protocol.rplidar_express.
- A measurement node: byte 0 = quality (6 bits) << 2 | not-S << 1 | S, where S = 1 marks
  the first node of a new revolution; bytes 1-2 (little-endian) = angle_q6 (15 bits,
  degrees x 64) << 1 | C, the check bit, always 1; bytes 3-4 = distance_q2 (mm x 4),
  0 when there was no return.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

from busarm.errors import ConfigError, ProtocolError

__all__ = [
    "A1_RANGE_MAX_M",
    "A1_RANGE_MIN_M",
    "DESCRIPTOR_SIZE",
    "HEALTH_DESCRIPTOR",
    "HEALTH_SIZE",
    "INFO_DESCRIPTOR",
    "INFO_SIZE",
    "MAX_ANGLE_Q6",
    "MAX_DISTANCE_Q2",
    "MAX_QUALITY",
    "NODE_SIZE",
    "REPLY_SYNC",
    "RPLIDAR_BAUDRATE",
    "SAMPLERATE_DESCRIPTOR",
    "SCAN_DESCRIPTOR",
    "SYNC",
    "Cmd",
    "ConfType",
    "DataType",
    "Descriptor",
    "DeviceInfo",
    "Health",
    "HealthStatus",
    "Node",
    "NodeFields",
    "NodeParser",
    "Request",
    "RequestParser",
    "SampleRate",
    "ScanMode",
    "SendMode",
    "conf_descriptor",
    "conf_payload",
    "decode_conf",
    "decode_descriptor",
    "decode_health",
    "decode_info",
    "decode_node",
    "decode_q8",
    "decode_samplerate",
    "encode_request",
    "find_descriptor",
    "is_node",
    "node_from_si",
    "pack_nodes",
]


SYNC = 0xA5
"""First byte of every request and of every reply descriptor."""
REPLY_SYNC = 0x5A
"""Second byte of a reply descriptor."""
DESCRIPTOR_SIZE = 7
NODE_SIZE = 5
INFO_SIZE = 20
HEALTH_SIZE = 3
RPLIDAR_BAUDRATE = 115200
"""The A1's fixed serial rate."""
A1_RANGE_MIN_M = 0.15
A1_RANGE_MAX_M = 12.0
"""The A1's rated range (its data sheet: 0.15-12 m); nearer or farther, no return."""

MAX_ANGLE_Q6 = 0x7FFF
MAX_DISTANCE_Q2 = 0xFFFF
MAX_QUALITY = 0x3F


class Cmd(IntEnum):
    """Request codes of the standard protocol."""

    STOP = 0x25
    RESET = 0x40
    SCAN = 0x20
    EXPRESS_SCAN = 0x82
    GET_INFO = 0x50
    GET_HEALTH = 0x52
    GET_SAMPLERATE = 0x59
    GET_LIDAR_CONF = 0x84


class DataType(IntEnum):
    """The data type byte of a reply descriptor."""

    INFO = 0x04
    HEALTH = 0x06
    SAMPLERATE = 0x15
    LIDAR_CONF = 0x20
    MEASUREMENT = 0x81
    CAPSULE = 0x82
    ULTRA_CAPSULE = 0x84


class SendMode(IntEnum):
    SINGLE = 0
    MULTIPLE = 1


class HealthStatus(IntEnum):
    GOOD = 0
    WARNING = 1
    ERROR = 2


def encode_request(cmd: int, payload: bytes = b"") -> bytes:
    """``A5 cmd``, or ``A5 cmd size payload checksum`` when there is a payload."""
    if not 0 <= cmd <= 0xFF:
        raise ConfigError(f"RPLIDAR command {cmd!r} is out of range 0..255")
    if not payload:
        return bytes((SYNC, cmd))
    if len(payload) > 0xFF:
        raise ConfigError(f"RPLIDAR payload of {len(payload)} bytes; at most 255")
    body = bytes((SYNC, cmd, len(payload))) + payload
    checksum = 0
    for b in body:
        checksum ^= b
    return body + bytes((checksum,))


@dataclass(frozen=True)
class Request:
    cmd: int
    payload: bytes = b""


class RequestParser:
    """Finds requests in what a host writes (the device's side). Never raises: bytes
    before ``A5`` and payload requests with a wrong checksum are skipped."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.rejected = 0

    def feed(self, data: bytes) -> list[Request]:
        buf = self._buf
        buf += data
        out: list[Request] = []
        while True:
            start = buf.find(SYNC)
            if start < 0:
                buf.clear()
                return out
            del buf[:start]
            if len(buf) < 2:
                return out
            cmd = buf[1]
            if cmd < 0x80:
                out.append(Request(cmd))
                del buf[:2]
                continue
            if len(buf) < 3 or len(buf) < 4 + buf[2]:
                return out
            size = buf[2]
            frame = bytes(buf[: 4 + size])
            if encode_request(cmd, frame[3 : 3 + size]) == frame and size:
                out.append(Request(cmd, frame[3 : 3 + size]))
                del buf[: 4 + size]
            else:
                self.rejected += 1
                del buf[:1]


@dataclass(frozen=True)
class Descriptor:
    """A reply descriptor: the size of each data reply, the send mode, the data type."""

    length: int
    mode: int
    data_type: int

    def encode(self) -> bytes:
        if not 0 <= self.length < 1 << 30:
            raise ConfigError(f"descriptor length {self.length} is out of range 0..2**30-1")
        if not 0 <= self.mode <= 3 or not 0 <= self.data_type <= 0xFF:
            raise ConfigError(f"descriptor mode {self.mode} (0..3) or type {self.data_type} "
                              "(0..255) out of range")
        word = self.length | (self.mode << 30)
        return bytes((SYNC, REPLY_SYNC)) + word.to_bytes(4, "little") + bytes((self.data_type,))


INFO_DESCRIPTOR = Descriptor(INFO_SIZE, SendMode.SINGLE, DataType.INFO)
HEALTH_DESCRIPTOR = Descriptor(HEALTH_SIZE, SendMode.SINGLE, DataType.HEALTH)
SCAN_DESCRIPTOR = Descriptor(NODE_SIZE, SendMode.MULTIPLE, DataType.MEASUREMENT)
SAMPLERATE_DESCRIPTOR = Descriptor(4, SendMode.SINGLE, DataType.SAMPLERATE)


def decode_descriptor(data: bytes) -> Descriptor:
    """The descriptor in exactly 7 bytes; ProtocolError if they are not one."""
    if len(data) != DESCRIPTOR_SIZE:
        raise ProtocolError(f"a reply descriptor is 7 bytes, got {len(data)}", data)
    if data[0] != SYNC or data[1] != REPLY_SYNC:
        raise ProtocolError(f"a reply descriptor starts A5 5A, got {data[:2].hex(' ')}", data)
    word = int.from_bytes(data[2:6], "little")
    return Descriptor(word & ((1 << 30) - 1), word >> 30, data[6])


def find_descriptor(buffer: bytes) -> tuple[Descriptor, int] | None:
    """The first descriptor in ``buffer`` and the index just after it, or None if there
    is none yet. Bytes before it are the caller's to discard (noise, old scan data)."""
    at = bytes(buffer).find(bytes((SYNC, REPLY_SYNC)))
    if at < 0 or len(buffer) - at < DESCRIPTOR_SIZE:
        return None
    return decode_descriptor(bytes(buffer[at : at + DESCRIPTOR_SIZE])), at + DESCRIPTOR_SIZE


@dataclass(frozen=True)
class DeviceInfo:
    model: int
    firmware: tuple[int, int]
    """(major, minor)."""
    hardware: int
    serial_number: bytes

    def encode(self) -> bytes:
        if len(self.serial_number) != 16:
            raise ConfigError(f"serial number of {len(self.serial_number)} bytes; must be 16")
        major, minor = self.firmware
        return bytes((self.model, minor, major, self.hardware)) + self.serial_number

    @property
    def serial_hex(self) -> str:
        return self.serial_number.hex().upper()


def decode_info(data: bytes) -> DeviceInfo:
    if len(data) != INFO_SIZE:
        raise ProtocolError(f"device info is {INFO_SIZE} bytes, got {len(data)}", data)
    return DeviceInfo(data[0], (data[2], data[1]), data[3], bytes(data[4:]))


@dataclass(frozen=True)
class SampleRate:
    """GET_SAMPLERATE's answer: the time of one sample (us) in the standard scan and in
    the express scan, two 16-bit little-endian words."""

    standard_us: int
    express_us: int

    def encode(self) -> bytes:
        if not (0 < self.standard_us <= 0xFFFF and 0 < self.express_us <= 0xFFFF):
            raise ConfigError(f"sample times {self.standard_us}, {self.express_us} us out of "
                              "range 1..65535")
        return self.standard_us.to_bytes(2, "little") + self.express_us.to_bytes(2, "little")


def decode_samplerate(data: bytes) -> SampleRate:
    if len(data) != 4:
        raise ProtocolError(f"a sample rate is 4 bytes, got {len(data)}", data)
    return SampleRate(int.from_bytes(data[0:2], "little"), int.from_bytes(data[2:4], "little"))


@dataclass(frozen=True)
class Health:
    status: HealthStatus
    error_code: int

    def encode(self) -> bytes:
        return bytes((int(self.status),)) + self.error_code.to_bytes(2, "little")


def decode_health(data: bytes) -> Health:
    if len(data) != HEALTH_SIZE:
        raise ProtocolError(f"health is {HEALTH_SIZE} bytes, got {len(data)}", data)
    if data[0] > HealthStatus.ERROR:
        raise ProtocolError(f"health status {data[0]} is not one of 0 (good), 1 (warning), "
                            "2 (error)", data)
    return Health(HealthStatus(data[0]), int.from_bytes(data[1:3], "little"))


@dataclass(frozen=True)
class Node:
    """One measurement, in the wire's fixed-point units."""

    start: bool
    """The first node of a new revolution."""
    quality: int
    angle_q6: int
    distance_q2: int

    @property
    def angle_rad(self) -> float:
        return math.radians(self.angle_q6 / 64.0)

    @property
    def distance_m(self) -> float:
        """Metres; 0.0 means no return."""
        return self.distance_q2 / 4000.0

    def encode(self) -> bytes:
        return pack_nodes(((self.start, self.quality, self.angle_q6, self.distance_q2),))


NodeFields = tuple[bool, int, int, int]
"""A node as (start, quality, angle_q6, distance_q2): what ``pack_nodes`` takes."""


def pack_nodes(nodes: Sequence[NodeFields]) -> bytes:
    """The wire bytes of nodes given as (start, quality, angle_q6, distance_q2), one
    after another (``Node.encode`` of each, joined; a simulated A1 sends thousands a
    second). ConfigError for a field out of the wire's range."""
    words: list[int] = []
    for start, quality, angle_q6, distance_q2 in nodes:
        if not (0 <= quality <= MAX_QUALITY and 0 <= angle_q6 <= MAX_ANGLE_Q6
                and 0 <= distance_q2 <= MAX_DISTANCE_Q2):
            raise ConfigError(f"node out of range: quality {quality} (0..63), angle_q6 "
                              f"{angle_q6} (0..32767), distance_q2 {distance_q2} "
                              "(0..65535)")
        s = int(start)
        words += (quality << 2 | (1 - s) << 1 | s, angle_q6 << 1 | 1, distance_q2)
    return struct.pack("<" + "BHH" * len(nodes), *words)


def node_from_si(start: bool, quality: int, angle_rad: float, distance_m: float) -> Node:
    """The node nearest to ``angle_rad`` (wrapped to 0..2 pi) and ``distance_m`` (0 or
    NaN/inf: no return; capped at the largest the wire carries, 16.38 m)."""
    angle_q6 = round(math.degrees(angle_rad % (2 * math.pi)) * 64.0) % (360 * 64)
    if not math.isfinite(distance_m) or distance_m <= 0:
        distance_q2 = 0
    else:
        distance_q2 = min(round(distance_m * 4000.0), MAX_DISTANCE_Q2)
    return Node(start, quality, angle_q6, distance_q2)


def is_node(data: bytes) -> bool:
    """Whether 5 bytes can be a node: S differs from not-S and the check bit is 1."""
    b0 = data[0]
    return (b0 & 1) != ((b0 >> 1) & 1) and (data[1] & 1) == 1


def decode_node(data: bytes) -> Node:
    if len(data) != NODE_SIZE:
        raise ProtocolError(f"a measurement node is 5 bytes, got {len(data)}", data)
    if not is_node(data):
        raise ProtocolError(f"not a measurement node (S == not-S or check bit 0): "
                            f"{data.hex(' ')}", data)
    word = int.from_bytes(data[1:3], "little")
    return Node(bool(data[0] & 1), data[0] >> 2, word >> 1, int.from_bytes(data[3:5], "little"))


class NodeParser:
    """Measurement nodes from a byte stream, resynchronising after garbage.

    At each position a 5-byte window that passes ``is_node`` is taken as a node (and the
    parser moves on 5 bytes); any other byte is skipped. Never raises. The flag and the
    check bit are all the protocol offers: a window of noise passes them by chance (1 in
    8 for random bytes), so a node may be invented in garbage, and a run of noise whose
    last 4 bytes start no passing window always leaves the parser aligned on the next
    real node (tests/property/test_rplidar_properties.py states this exactly).
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.skipped_bytes = 0

    def feed(self, data: bytes) -> list[Node]:
        buf = self._buf
        buf += data
        out: list[Node] = []
        i = 0
        n = len(buf)
        # is_node and decode_node on the buffer in place: a Lidar's stream is thousands
        # of nodes a second, and a copy of each window costs more than its decoding.
        while n - i >= NODE_SIZE:
            b0, b1 = buf[i], buf[i + 1]
            if (b0 & 1) != ((b0 >> 1) & 1) and (b1 & 1) == 1:
                out.append(Node(bool(b0 & 1), b0 >> 2, (b1 | buf[i + 2] << 8) >> 1,
                                buf[i + 3] | buf[i + 4] << 8))
                i += NODE_SIZE
            else:
                i += 1
                self.skipped_bytes += 1
        del buf[:i]
        return out

    def reset(self) -> None:
        self._buf.clear()


class ConfType(IntEnum):
    """GET_LIDAR_CONF's configuration types (the scan modes)."""

    SCAN_MODE_COUNT = 0x70
    SCAN_MODE_US_PER_SAMPLE = 0x71
    SCAN_MODE_MAX_DISTANCE = 0x74
    SCAN_MODE_ANS_TYPE = 0x75
    SCAN_MODE_TYPICAL = 0x7C
    SCAN_MODE_NAME = 0x7F


_PER_MODE = frozenset((ConfType.SCAN_MODE_US_PER_SAMPLE, ConfType.SCAN_MODE_MAX_DISTANCE,
                       ConfType.SCAN_MODE_ANS_TYPE, ConfType.SCAN_MODE_NAME))


def conf_payload(conf: ConfType, mode: int | None = None) -> bytes:
    """GET_LIDAR_CONF's payload: the type, and the mode's id for a per-mode entry."""
    if (mode is not None) != (conf in _PER_MODE):
        raise ConfigError(f"{conf.name} {'needs' if conf in _PER_MODE else 'takes no'} a "
                          "scan mode id")
    body = int(conf).to_bytes(4, "little")
    if mode is None:
        return body
    if not 0 <= mode <= 0xFFFF:
        raise ConfigError(f"scan mode id {mode} is out of range 0..65535")
    return body + mode.to_bytes(2, "little")


def conf_descriptor(value_size: int) -> Descriptor:
    """The descriptor of a GET_LIDAR_CONF answer whose value is ``value_size`` bytes."""
    return Descriptor(4 + value_size, SendMode.SINGLE, DataType.LIDAR_CONF)


@dataclass(frozen=True)
class ScanMode:
    """One scan mode as GET_LIDAR_CONF describes it."""

    id: int
    name: str
    us_per_sample: float
    max_distance_m: float
    answer_type: int
    """The data type its scan answers with (0x81 nodes, 0x82 capsules, ...)."""

    @property
    def sample_hz(self) -> float:
        return 1e6 / self.us_per_sample

    def value(self, conf: ConfType) -> bytes:
        """The answer's value for a per-mode entry (Q8 numbers, as the wire has them)."""
        if conf is ConfType.SCAN_MODE_US_PER_SAMPLE:
            return round(self.us_per_sample * 256).to_bytes(4, "little")
        if conf is ConfType.SCAN_MODE_MAX_DISTANCE:
            return round(self.max_distance_m * 256).to_bytes(4, "little")
        if conf is ConfType.SCAN_MODE_ANS_TYPE:
            return bytes((self.answer_type,))
        if conf is ConfType.SCAN_MODE_NAME:
            return self.name.encode("ascii") + b"\0"
        raise ConfigError(f"{conf.name} is not a scan mode's entry")


def decode_conf(data: bytes, want: ConfType) -> bytes:
    """The value of a GET_LIDAR_CONF answer to ``want`` (ProtocolError if it answers
    another type)."""
    if len(data) < 4:
        raise ProtocolError(f"a configuration answer is at least 4 bytes, got {len(data)}",
                            data)
    got = int.from_bytes(data[:4], "little")
    if got != want:
        raise ProtocolError(f"asked configuration 0x{int(want):02X}, got 0x{got:02X}", data)
    return bytes(data[4:])


def decode_q8(value: bytes) -> float:
    """A 32-bit little-endian Q8 number (us, m)."""
    if len(value) != 4:
        raise ProtocolError(f"a Q8 value is 4 bytes, got {len(value)}", value)
    return int.from_bytes(value, "little") / 256.0

