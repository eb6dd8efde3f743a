"""The RPLIDAR A1's express scan: capsules of 32 measurements (a codec: bytes only).

From Slamtec's public protocol description:

EXPRESS_SCAN (0x82, payload: working mode byte + 4 reserved bytes; 0 the legacy
express mode) answers type 0x82 in stream mode with 84-byte capsules: byte 0 = 0xA << 4
| checksum low nibble, byte 1 = 0x5 << 4 | checksum high nibble (the XOR of bytes
2..83), bytes 2-3 = start angle q6 (15 bits) | S << 15 (the first capsule of a scan),
then 16 cabins of 5 bytes: two 16-bit words distance_mm << 2 | the high 2 bits of a
6-bit angle offset (q3, degrees x 8), and a byte with the offsets' low 4 bits (first
in the low nibble). A capsule's 32 samples lie between its start angle w_i and the
next capsule's w_i+1: sample k is at w_i + (w_i+1 - w_i) k / 32 - offset_k (so a
capsule is decoded when the next one comes).

The measurements come out as ``Node``s (busarm.protocol.rplidar), as the standard scan's.
"""

from __future__ import annotations

from dataclasses import dataclass

from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.rplidar import (
    MAX_ANGLE_Q6,
    DataType,
    Descriptor,
    Node,
    SendMode,
)

__all__ = [
    "CAPSULE_SAMPLES",
    "CAPSULE_SIZE",
    "EXPRESS_DESCRIPTOR",
    "MAX_DISTANCE_MM",
    "MAX_OFFSET_Q3",
    "Capsule",
    "CapsuleParser",
    "capsule_nodes",
    "decode_capsule",
    "express_payload",
    "is_capsule",
]


CAPSULE_SIZE = 84
CAPSULE_SAMPLES = 32
EXPRESS_DESCRIPTOR = Descriptor(CAPSULE_SIZE, SendMode.MULTIPLE, DataType.CAPSULE)
MAX_DISTANCE_MM = 0x3FFF
MAX_OFFSET_Q3 = 0x3F


def express_payload(working_mode: int = 0) -> bytes:
    """EXPRESS_SCAN's payload: the working mode (0 legacy express, else a scan mode id)."""
    if not 0 <= working_mode <= 0xFF:
        raise ConfigError(f"express working mode {working_mode} is out of range 0..255")
    return bytes((working_mode, 0, 0, 0, 0))


@dataclass(frozen=True)
class Capsule:
    """One express capsule: its start angle, S, and 32 (distance mm, angle offset q3)."""

    start: bool
    start_angle_q6: int
    distances_mm: tuple[int, ...]
    offsets_q3: tuple[int, ...]

    def encode(self) -> bytes:
        if not (len(self.distances_mm) == len(self.offsets_q3) == CAPSULE_SAMPLES
                and 0 <= self.start_angle_q6 <= MAX_ANGLE_Q6
                and all(0 <= d <= MAX_DISTANCE_MM for d in self.distances_mm)
                and all(0 <= o <= MAX_OFFSET_Q3 for o in self.offsets_q3)):
            raise ConfigError("capsule out of range: 32 distances 0..16383 mm, 32 offsets "
                              f"0..63, start angle_q6 {self.start_angle_q6} (0..32767)")
        body = bytearray((self.start_angle_q6 | int(self.start) << 15).to_bytes(2, "little"))
        for k in range(0, CAPSULE_SAMPLES, 2):
            (d1, d2), (o1, o2) = self.distances_mm[k : k + 2], self.offsets_q3[k : k + 2]
            body += (d1 << 2 | o1 >> 4).to_bytes(2, "little")
            body += (d2 << 2 | o2 >> 4).to_bytes(2, "little")
            body.append((o1 & 0xF) | (o2 & 0xF) << 4)
        checksum = 0
        for b in body:
            checksum ^= b
        return bytes((0xA0 | checksum & 0xF, 0x50 | checksum >> 4)) + bytes(body)


def is_capsule(data: bytes) -> bool:
    """Whether 84 bytes can be a capsule: the sync nibbles and the checksum hold."""
    if len(data) != CAPSULE_SIZE or data[0] >> 4 != 0xA or data[1] >> 4 != 0x5:
        return False
    checksum = 0
    for b in data[2:]:
        checksum ^= b
    return checksum == (data[0] & 0xF) | (data[1] & 0xF) << 4


def decode_capsule(data: bytes) -> Capsule:
    if not is_capsule(data):
        raise ProtocolError(f"not an express capsule (sync nibbles or checksum): "
                            f"{data[:4].hex(' ')}...", data)
    word = int.from_bytes(data[2:4], "little")
    distances, offsets = [], []
    for at in range(4, CAPSULE_SIZE, 5):
        w1, w2 = int.from_bytes(data[at : at + 2], "little"), int.from_bytes(
            data[at + 2 : at + 4], "little")
        distances += [w1 >> 2, w2 >> 2]
        offsets += [(data[at + 4] & 0xF) | (w1 & 0x3) << 4, data[at + 4] >> 4 | (w2 & 0x3) << 4]
    return Capsule(bool(word >> 15), word & 0x7FFF, tuple(distances), tuple(offsets))


def capsule_nodes(capsule: Capsule, following: Capsule) -> list[Node]:
    """The 32 measurements of ``capsule``, their angles spread towards ``following``'s
    start angle (wrapping past 360 degrees), less each one's offset. S marks the sample
    where the angle wraps. Quality: the capsule carries none; a return gets 47."""
    full_q6 = 360 * 64
    step_q6 = ((following.start_angle_q6 - capsule.start_angle_q6) % full_q6) / CAPSULE_SAMPLES
    out = []
    for k in range(CAPSULE_SAMPLES):
        raw = capsule.start_angle_q6 + step_q6 * k
        angle = round(raw - capsule.offsets_q3[k] * 8) % full_q6
        distance = capsule.distances_mm[k]
        wrapped = k > 0 and (raw % full_q6) < step_q6
        out.append(Node(wrapped, 47 if distance else 0, angle, distance * 4))
    return out


class CapsuleParser:
    """Measurement nodes from an express scan's byte stream, resynchronising after
    garbage (a window failing the sync nibbles or checksum is skipped a byte at a time).
    A capsule's nodes come out when the next one arrives; when a whole capsule's worth of
    bytes was skipped between two (one was lost), the first is dropped, its angles
    unknowable. Never raises."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._last: Capsule | None = None
        self._gap = 0
        """Bytes skipped since the last capsule."""
        self.skipped_bytes = 0

    def feed(self, data: bytes) -> list[Node]:
        buf = self._buf
        buf += data
        out: list[Node] = []
        i = 0
        while len(buf) - i >= CAPSULE_SIZE:
            window = bytes(buf[i : i + CAPSULE_SIZE])
            if not is_capsule(window):
                i += 1
                self.skipped_bytes += 1
                self._gap += 1
                continue
            capsule = decode_capsule(window)
            if self._last is not None and not capsule.start and self._gap < CAPSULE_SIZE:
                out += capsule_nodes(self._last, capsule)
            self._last, self._gap = capsule, 0
            i += CAPSULE_SIZE
        del buf[:i]
        return out

    def reset(self) -> None:
        self._buf.clear()
        self._last = None
        self._gap = 0
