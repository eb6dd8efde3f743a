"""Incremental frame finder: feed it any byte stream, get back the valid frames.

Garbage between frames, split reads, corrupted checksums and truncated frames are
skipped; the parser resynchronises on the next header. It never raises.
"""

from __future__ import annotations

from collections.abc import Callable

from busarm.protocol.commands import BROADCAST_ID, HEADER, VALID_LENGTHS
from busarm.protocol.frames import Frame, checksum

__all__ = [
    "FrameParser",
]


class FrameParser:
    """Finds frames in a byte stream fed in chunks of any size.

    ``lengths`` restricts the Length bytes taken as plausible (default: those of
    the manual, 3..7), which makes resynchronisation after garbage quick. Counters
    tell how many bytes were skipped and how many candidates failed their checksum;
    ``on_bad_checksum``, if given, is called with each such candidate's bytes.
    """

    def __init__(
        self, lengths: frozenset[int] = VALID_LENGTHS,
        on_bad_checksum: Callable[[bytes], None] | None = None,
    ) -> None:
        self._buf = bytearray()
        self._lengths = lengths
        self._on_bad_checksum = on_bad_checksum
        self.skipped_bytes = 0
        self.checksum_failures = 0

    @property
    def pending(self) -> bytes:
        """Bytes held back, waiting for the rest of a possible frame."""
        return bytes(self._buf)

    def feed(self, data: bytes | bytearray | memoryview) -> list[Frame]:
        """Add bytes; return every complete valid frame now found, in order."""
        buf = self._buf
        buf += data
        out: list[Frame] = []
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # Keep a trailing 0x55: it may be the first half of a header.
                keep = 1 if buf[-1:] == b"\x55" else 0
                self.skipped_bytes += len(buf) - keep
                del buf[: len(buf) - keep]
                return out
            if start:
                self.skipped_bytes += start
                del buf[:start]
            if len(buf) < 4:
                return out
            sid, length = buf[2], buf[3]
            if sid > BROADCAST_ID or length not in self._lengths:
                self._skip_one()
                continue
            end = length + 3
            if len(buf) < end:
                # Incomplete: wait for more, unless a complete frame already follows,
                # in which case this candidate was a truncated frame or noise.
                if self._complete_frame_after(1):
                    self._skip_one()
                    continue
                return out
            if buf[end - 1] != checksum(memoryview(buf)[2 : end - 1]):
                self.checksum_failures += 1
                if self._on_bad_checksum is not None:
                    self._on_bad_checksum(bytes(buf[:end]))
                self._skip_one()
                continue
            out.append(Frame(sid, buf[4], bytes(buf[5 : end - 1])))
            del buf[:end]

    def flush(self) -> list[Frame]:
        """Give up on a held-back partial frame (the line went idle); return frames behind it."""
        out: list[Frame] = []
        while self._buf:
            self._skip_one()
            out += self.feed(b"")
        return out

    def _skip_one(self) -> None:
        self.skipped_bytes += 1
        del self._buf[:1]

    def _complete_frame_after(self, offset: int) -> bool:
        buf = self._buf
        i = buf.find(HEADER, offset)
        while i >= 0:
            if len(buf) >= i + 4:
                length = buf[i + 3]
                end = i + length + 3
                if (
                    buf[i + 2] <= BROADCAST_ID
                    and length in self._lengths
                    and len(buf) >= end
                    and buf[end - 1] == checksum(memoryview(buf)[i + 2 : end - 1])
                ):
                    return True
            i = buf.find(HEADER, i + 1)
        return False
