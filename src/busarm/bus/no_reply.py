"""Why a read ended with no valid reply after every attempt: nothing came back (from a
servo never heard: power, cable, ID), the replies came back damaged or cut short
(cabling, noise, baud rate), or nothing came back from a servo that may well be there: it
answered on this bus before (its supply, a loose connector), or the line lately delivered
replies late (adapter latency, a busy computer) or damaged. ``ServoBus`` raises what
``final_error`` returns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from busarm.errors import (
    BusTimeoutError,
    ChecksumError,
    EchoMismatchError,
    ProtocolError,
    UnreliableLineError,
)
from busarm.protocol import Command

__all__ = [
    "CUT_SHORT_HINT",
    "DAMAGED_HINT",
    "LATE_HINT",
    "QUIET_HINT",
    "LineSighting",
    "final_error",
    "unexplained_error",
]


CUT_SHORT_HINT = ("bytes are lost on the line, or the replies come late: check the cabling and "
                  "its connectors, and a USB adapter's latency timer (`busarm ports`)")
DAMAGED_HINT = ("bytes are lost or corrupted on the line: check the cabling and its connectors, "
                "electrical noise near the bus, and the baud rate (--baud; LX servos use 115200)")
QUIET_HINT = ("check its supply (a servo short of voltage goes quiet), its cable and the "
              "connectors; on a busy computer, --timeout-margin-ms waits longer")
LATE_HINT = ("the line is slow to deliver: a USB adapter's latency timer (`busarm ports`), a "
             "busy computer, or a servo short of supply voltage; --timeout-margin-ms waits longer")


class _CutShort(ProtocolError):
    """The start of a reply came, not its end, by the deadline: a byte lost, or the reply
    still arriving (only ever an attempt's error: ``final_error`` says what it means)."""


def unexplained_error(servo_id: int, command_name: str, received: int, pending: bytes,
                      echo_pending: bool) -> ProtocolError:
    """An attempt that received ``received`` bytes but no valid reply; ``pending`` is what
    the parser holds back, waiting for the rest of a frame."""
    if pending[:1] == b"\x55" and len(pending) == received and not echo_pending:
        return _CutShort(f"servo {servo_id} {command_name}: {received} byte(s) of a reply "
                         "came, cut short at the deadline", pending)
    return ProtocolError(
        f"servo {servo_id} {command_name}: {received} byte(s) received, no valid reply"
        + (" (and our echo did not come back intact)" if echo_pending else ""), pending)


@dataclass(frozen=True)
class LineSighting:
    """A reply seen to arrive late (after its read had given up on it) or damaged."""

    at_s: float
    """When (the bus clock)."""
    servo_id: int
    command: int
    late: bool
    """True: it came late; False: it came damaged."""

    def text(self) -> str:
        try:
            name = Command(self.command).name
        except ValueError:
            name = f"command {self.command}"
        return (f"servo {self.servo_id}'s {name} reply "
                + ("arrived after its deadline" if self.late else "came back damaged"))


def final_error(
    errors: Sequence[BusTimeoutError | ProtocolError], *, servo_id: int, command_name: str,
    seen: LineSighting | None, answered_before: bool = False,
) -> BusTimeoutError | ProtocolError:
    """The one error for a read whose every attempt failed (``errors``, one per attempt),
    saying what came back; ``seen`` is the latest reply on this bus that came late or
    damaged, if one did lately; ``answered_before``: the servo answered on this bus."""
    last = errors[-1]
    tries = "" if len(errors) == 1 else f" (after {len(errors)} attempts)"
    echo = next((e for e in errors if isinstance(e, EchoMismatchError)), None)
    if echo is not None:  # the echo setting is wrong: that is what to fix first
        echo.args = (f"{echo.args[0]}{tries}",)
        return echo
    damaged = [e for e in errors if isinstance(e, ProtocolError)]
    if damaged:
        kind = ChecksumError if any(isinstance(e, ChecksumError) for e in damaged) \
            else ProtocolError
        short = all(isinstance(e, _CutShort) for e in damaged)
        hint = CUT_SHORT_HINT if short else DAMAGED_HINT
        if len(errors) == 1:  # its own words: how many bytes, or a bad checksum
            return kind(f"{last.args[0]}: {hint}", damaged[-1].raw)
        silent = len(errors) - len(damaged)
        return kind(f"servo {servo_id} {command_name}: no valid reply in {len(errors)} "
                    f"attempts: {len(damaged)} came back "
                    + ("cut short" if short else "damaged")
                    + (f", {silent} brought nothing" if silent else "") + f": {hint}",
                    damaged[-1].raw)
    assert isinstance(last, BusTimeoutError)
    text = f"{last.args[0]}{tries}"
    if seen is not None:
        said = (f"{text}, but this line is unreliable ({seen.text()}): "
                + (LATE_HINT if seen.late else DAMAGED_HINT))
    elif answered_before:
        said = f"{text}, though it answered on this bus before: {QUIET_HINT}"
    else:  # nothing came back, from a servo never heard, on a line with no sign of trouble
        return type(last)(text, servo_id=last.servo_id, command=last.command,
                          timeout_s=last.timeout_s)
    return UnreliableLineError(said, servo_id=last.servo_id, command=last.command,
                               timeout_s=last.timeout_s)
