"""The controller board's frames: ``AA 55 | func | len | data | crc8``, pure, no I/O.

The vendor's STM32 board ("ros_robot_controller") talks to the host over USB serial at
1,000,000 baud. Every frame carries a function code (what part of the board it is
for), up to 255 data bytes and a CRC-8/MAXIM (Dallas 1-Wire: reflected polynomial
0x8C, init 0, no final XOR) over func, len and data. ``BoardFrameParser`` finds frames
in any byte stream and resynchronises after garbage; it never raises.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from busarm.errors import ChecksumError, ProtocolError

__all__ = [
    "BOARD_BAUDRATE",
    "BOARD_HEADER",
    "FRAME_OVERHEAD",
    "FUNC_LIMIT",
    "MAX_DATA_LEN",
    "BoardFrame",
    "BoardFrameParser",
    "Func",
    "crc8_maxim",
    "decode_frame",
    "encode_frame",
]


BOARD_HEADER = b"\xaa\x55"
BOARD_BAUDRATE = 1_000_000
"""The board's fixed USB serial rate."""
MAX_DATA_LEN = 255
FRAME_OVERHEAD = 5
"""Header (2), func, len and crc bytes around the data."""


class Func(enum.IntEnum):
    """The board's function codes; the firmware rejects anything from 12 up."""

    SYS = 0
    LED = 1
    BUZZER = 2
    MOTOR = 3
    PWM_SERVO = 4
    BUS_SERVO = 5
    KEY = 6
    IMU = 7
    GAMEPAD = 8
    SBUS = 9
    OLED = 10
    RGB = 11


FUNC_LIMIT = len(Func)


def _crc8_table() -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x8C if crc & 1 else crc >> 1
        table.append(crc)
    return tuple(table)


_CRC8 = _crc8_table()


def crc8_maxim(data: bytes | bytearray | memoryview) -> int:
    """CRC-8/MAXIM of ``data`` (check value: 0xA1 for b"123456789")."""
    crc = 0
    for byte in data:
        crc = _CRC8[crc ^ byte]
    return crc


@dataclass(frozen=True)
class BoardFrame:
    """One frame: a function code and its data bytes."""

    func: int
    data: bytes

    def to_bytes(self) -> bytes:
        return encode_frame(self.func, self.data)

    @property
    def name(self) -> str:
        """The function's name (``BUS_SERVO``), or its number if unknown."""
        return Func(self.func).name if self.func < FUNC_LIMIT else f"func {self.func}"


def encode_frame(func: int, data: bytes | bytearray) -> bytes:
    """The bytes of one frame; ProtocolError for a function code or length the board
    does not take."""
    if not isinstance(func, int) or not 0 <= func < FUNC_LIMIT:
        raise ProtocolError(f"function code {func!r} is not one of the board's "
                            f"(0..{FUNC_LIMIT - 1})")
    if len(data) > MAX_DATA_LEN:
        raise ProtocolError(f"{len(data)} data bytes do not fit one board frame "
                            f"(0..{MAX_DATA_LEN})")
    body = bytes((func, len(data))) + bytes(data)
    return BOARD_HEADER + body + bytes((crc8_maxim(body),))


def decode_frame(raw: bytes | bytearray) -> BoardFrame:
    """Exactly one whole frame from ``raw``; typed ProtocolError naming what is wrong."""
    raw = bytes(raw)
    if len(raw) < FRAME_OVERHEAD or not raw.startswith(BOARD_HEADER):
        raise ProtocolError(f"not a board frame (needs AA 55 and at least {FRAME_OVERHEAD} "
                            f"bytes): {raw.hex(' ') or 'nothing'}", raw)
    func, length = raw[2], raw[3]
    if func >= FUNC_LIMIT:
        raise ProtocolError(f"unknown function code {func} (the board's are 0..{FUNC_LIMIT - 1})",
                            raw)
    if len(raw) != length + FRAME_OVERHEAD:
        raise ProtocolError(f"frame says {length} data bytes but has {len(raw) - FRAME_OVERHEAD}",
                            raw)
    want = crc8_maxim(raw[2:-1])
    if raw[-1] != want:
        raise ChecksumError(f"bad CRC-8 {raw[-1]:02X} (expected {want:02X})", raw)
    return BoardFrame(func, raw[4:-1])


class BoardFrameParser:
    """Finds board frames in a byte stream fed in chunks of any size.

    A candidate is taken only if its function code is a board's and its CRC matches;
    otherwise the search goes on one byte later, so a frame hidden behind garbage (even
    behind a false header announcing a long frame) is still found. ``max_data_len``
    bounds the lengths believed (the board's own reports are short), which makes
    resynchronisation quick. Counters tell what was skipped.
    """

    def __init__(self, max_data_len: int = MAX_DATA_LEN) -> None:
        self._buf = bytearray()
        self._max = max_data_len
        self.skipped_bytes = 0
        self.crc_failures = 0
        self.unknown_funcs = 0
        """Headers followed by a function code no board has (the firmware drops those)."""

    @property
    def pending(self) -> bytes:
        """Bytes held back, waiting for the rest of a possible frame."""
        return bytes(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[BoardFrame]:
        """Add bytes; return every complete valid frame now found, in order."""
        buf = self._buf
        buf += data
        out: list[BoardFrame] = []
        while True:
            start = buf.find(BOARD_HEADER)
            if start < 0:
                keep = 1 if buf[-1:] == b"\xaa" else 0  # half a header
                self.skipped_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                return out
            if start:
                self.skipped_bytes += start
                del buf[:start]
            if len(buf) < 4:
                return out
            if buf[2] >= FUNC_LIMIT or buf[3] > self._max:
                self.unknown_funcs += buf[2] >= FUNC_LIMIT
                self._skip_one()
                continue
            end = buf[3] + FRAME_OVERHEAD
            if len(buf) < end:
                if self._valid_frame_at_or_after(1):  # this one was noise or cut short
                    self._skip_one()
                    continue
                return out
            if buf[end - 1] != crc8_maxim(memoryview(buf)[2 : end - 1]):
                self.crc_failures += 1
                self._skip_one()
                continue
            out.append(BoardFrame(buf[2], bytes(buf[4 : end - 1])))
            del buf[:end]

    def flush(self) -> list[BoardFrame]:
        """The line went quiet: give up on a held-back partial frame and return the frames
        found behind it."""
        out: list[BoardFrame] = []
        while self._buf:
            self._skip_one()
            out += self.feed(b"")
        return out

    def _skip_one(self) -> None:
        self.skipped_bytes += 1
        del self._buf[:1]

    def _valid_frame_at_or_after(self, offset: int) -> bool:
        buf = self._buf
        i = buf.find(BOARD_HEADER, offset)
        while i >= 0:
            if len(buf) >= i + 4 and buf[i + 2] < FUNC_LIMIT and buf[i + 3] <= self._max:
                end = i + buf[i + 3] + FRAME_OVERHEAD
                complete = len(buf) >= end
                if complete and buf[end - 1] == crc8_maxim(memoryview(buf)[i + 2 : end - 1]):
                    return True
            i = buf.find(BOARD_HEADER, i + 1)
        return False
