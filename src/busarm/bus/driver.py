"""The servo bus driver: one locked request/reply transaction at a time.

``ServoBus`` turns the protocol into calls in the user's units (degrees from the
servo's mid-point, seconds, volts, deg C), with raw-pulse variants named so. It
derives every timeout from the baud rate and packet lengths, handles adapters that
echo what they send (on, off, or detected at open), retries reads a bounded number
of times, and accepts a reply only if its header, ID, command, length and checksum
are those expected: a stray frame, a late reply from another servo or line noise is
never taken as the answer.

This module opens, stops and closes the bus; its calls come from its parts: the
transaction core on the line (``busarm.bus.bus_core``), the servo's registers
(``busarm.bus.servo_registers``), moves and motor mode (``busarm.bus.servo_motion``),
and the ID scan and renumbering (``busarm.bus.id_scan``). It is the ``lx`` backend of
``busarm.bus.servo_port`` (a ``ServoPort``), and an ``LxServoPort`` (busarm.bus.lx_port)
beside its peer behind the controller board (``BoardServoBus``).
"""

from __future__ import annotations

import enum
import logging
from collections.abc import Mapping

from busarm.bus.id_scan import IdScan
from busarm.bus.lx_port import LxServoPort
from busarm.bus.ports import PortSpec, open_transport
from busarm.bus.transport import DEFAULT_BAUDRATE, Transport
from busarm.errors import ConfigError
from busarm.protocol import (
    BROADCAST_ID,
    SERVO_TURNAROUND_S,
    Command,
    ServoMode,
    encode_request,
)
from busarm.units import check_int_range, check_range

__all__ = [
    "DEFAULT_RETRIES",
    "DEFAULT_TIMEOUT_MARGIN_S",
    "EchoMode",
    "ServoBus",
    "open_bus",
    "servo_bus_on",
]


log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_MARGIN_S = 0.004
"""Slack on top of the wire time for OS scheduling and adapter jitter."""
DEFAULT_RETRIES = 2


class EchoMode(str, enum.Enum):
    """Whether the adapter hands back every byte we send before the reply."""

    ON = "on"
    OFF = "off"
    AUTO = "auto"


class ServoBus(IdScan, LxServoPort):
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
        # A serial device's descriptor: the reads' one-frame path (BusCore.read_values).
        fd = getattr(transport, "fd", None)
        self._fd = fd if isinstance(fd, int) else None
        self._plans = {}
        self._line_free_at = 0.0
        # (servo ID, command) -> when a request of it last timed out: its reply may come late.
        self._late = {}
        self._trouble = None  # the last reply seen late or damaged
        self._echo_warned = False  # said that our own bytes come back with echo off
        self._init_state(transport.clock, retries, limits_deg)
        self.echo = echo_mode is EchoMode.ON
        if echo_mode is EchoMode.AUTO:
            self.echo = self._detect_echo()

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

    # ------------------------------------------------------------------ lifecycle

    @classmethod
    def open(cls, port: PortSpec | str, *, baudrate: int = DEFAULT_BAUDRATE,
             **kwargs: object) -> LxServoPort:
        """Open ``port`` (a ``PortSpec``, or a serial device's path or pyserial URL)
        and return a bus on it: the servos behind a controller board (its peer,
        ``BoardServoBus``) for ``board://``."""
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


def servo_bus_on(transport: Transport, **kwargs: object) -> LxServoPort:
    """The servo bus on an open ``transport``: the LX driver, or for a controller board's
    link (``transport.framing == "board"``) the servos behind the board."""
    if transport.framing == "board":
        from busarm.bus.board_bus import BoardServoBus  # its module imports this one

        return BoardServoBus.on(transport, **kwargs)  # type: ignore[arg-type]
    return ServoBus(transport, **kwargs)  # type: ignore[arg-type]


def open_bus(port: str, **kwargs: object) -> LxServoPort:
    """Open a ServoBus on a device path, a pyserial URL or ``sim``: see ServoBus.open."""
    return ServoBus.open(port, **kwargs)  # type: ignore[arg-type]
