"""A servo bus on another computer, over Zenoh: ``--port zenoh://HOST[:PORT][?robot=NAME]``.

The serial port stays on the robot's computer, where ``busarm ros bridge`` serves its
transport (``serve_bus``); another computer opens ``zenoh://HOST`` and gets a
``Transport`` whose every operation (exchange, write, read, reset) is one Zenoh query to
it, carried out there whole, between the robot's own transactions. The driver above it
is the usual one, with the link's round trip added to every reply's deadline.

The robot's side keeps it safe from what comes over the link: while its bus is halted
(an e-stop), writes other than a stop are refused; a position command outside the
joints' limits is refused before it reaches the line (``check`` is given by the robot).
The caller holds a liveliness token while connected; when it goes (the caller ended, or
its link dropped: Zenoh's lease, busarm.bus.zenoh_session.LEASE_MS) the robot's side
stops every servo (``on_lost``).

Wire of one query on ``busarm/<robot>/bus``: an op byte, then ``X`` exchange: timeout
(float64 s, little-endian) and the request; ``W`` write: the bytes; ``R`` read: max bytes
(uint32) and timeout; ``Z`` reset input. The reply's payload is the bytes read (empty for
W and Z); an error reply is its message, raised here as TransportError.
"""

from __future__ import annotations

import math
import statistics
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from busarm.bus.transport import Transport
from busarm.bus.zenoh_session import DEFAULT_PORT, open_session
from busarm.clock import WALL_CLOCK, Clock
from busarm.errors import BusArmError, ConfigError, TransportError
from busarm.units import check_int_range, short_repr

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "DEFAULT_ROBOT",
    "LINK_MARGIN_S",
    "BusServer",
    "Check",
    "ZenohPort",
    "ZenohTransport",
    "bus_key",
    "client_key",
]


DEFAULT_ROBOT = "busarm"
_TIMED = struct.Struct("<d")
_READ = struct.Struct("<Id")
LINK_MARGIN_S = 3.0
"""A query's answer may take this long beyond what the bus itself takes, before the
link is called silent (a busy robot computer answers late, not never: one running a
real-time twin beside other work was seen to take over 1 s; a link that went silent is
known sooner anyway, by its lease: busarm.bus.zenoh_session.LEASE_MS)."""


def bus_key(robot: str) -> str:
    return f"busarm/{robot}/bus"


def client_key(robot: str, client: str) -> str:
    return f"busarm/{robot}/clients/{client}"


@dataclass(frozen=True)
class ZenohPort:
    """A robot served on another computer (``busarm ros bridge`` there): the Zenoh
    endpoint ``host``:``port`` (TCP) and the robot's name there."""

    __repr__ = short_repr

    host: str
    port: int = DEFAULT_PORT
    robot: str = DEFAULT_ROBOT
    label: str = field(default="", compare=False)
    """The port in the user's own words (for messages), if given that way."""

    def __post_init__(self) -> None:
        if not isinstance(self.host, str) or not self.host.strip():
            raise ConfigError(f"zenoh: host must be a host name or address, got {self.host!r}")
        check_int_range("zenoh: port", self.port, 1, 65535)
        if not isinstance(self.robot, str) or not self.robot.strip() or "/" in self.robot:
            raise ConfigError(f"zenoh: robot must be a name without '/', got {self.robot!r}")

    @property
    def endpoint(self) -> str:
        """The Zenoh endpoint to connect to (``tcp/HOST:PORT``)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"tcp/{host}:{self.port}"

    @property
    def name(self) -> str:
        return self.label or f"the robot {self.robot!r} on Zenoh at {self.endpoint}"

    @property
    def robot_key(self) -> str:
        return f"zenoh-{self.host}-{self.port}-{self.robot}"

    @property
    def through_board(self) -> bool:
        return False  # whatever it is, the served robot relays LX bytes

    def check(self) -> None:
        """Nothing to check before opening: the link says when the robot is not there."""

    def open(self, baudrate: int = 115200) -> ZenohTransport:
        session = open_session(connect=[self.endpoint])
        try:
            return ZenohTransport(session, self.robot, self.name, baudrate=baudrate)
        except BaseException:
            session.close()
            raise


class ZenohTransport:
    """The transport of a robot served on a Zenoh session (see the module docstring)."""

    framing = "lx"
    clock: Clock = WALL_CLOCK

    def __init__(self, session: zenoh.Session, robot: str, name: str, *,
                 owns_session: bool = True, baudrate: int = 115200) -> None:
        self.session = session
        self.robot = robot
        self.name = name
        self.baudrate = baudrate
        self._owns = owns_session
        self._key = bus_key(robot)
        self._token = session.liveliness().declare_token(
            client_key(robot, str(session.zid())))
        self.latency_s = 0.0
        self.latency_s = self._measure_round_trip()

    def _measure_round_trip(self) -> float:
        """The link's round trip (the slowest of a few), added to every reply's wait."""
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            self._query(b"Z", timeout_s=2.0)
            times.append(time.perf_counter() - t0)
        return max(times) + statistics.median(times)

    def _query(self, payload: bytes, timeout_s: float) -> bytes:
        replies = self.session.get(self._key, payload=payload,
                                   timeout=timeout_s + LINK_MARGIN_S)
        for reply in replies:
            if reply.ok is not None:
                return bytes(reply.ok.payload.to_bytes())
            raise TransportError(f"{self.name}: {reply.err.payload.to_string()}")
        raise TransportError(f"{self.name}: no answer from robot {self.robot!r} within "
                             f"{timeout_s + LINK_MARGIN_S:.2f} s (is `busarm ros bridge` "
                             "running there, and the link up?)")

    def write(self, data: bytes) -> None:
        self._query(b"W" + bytes(data), timeout_s=1.0)

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        return self._query(b"R" + _READ.pack(max_bytes, max(0.0, timeout_s)), timeout_s)

    def reset_input(self) -> None:
        self._query(b"Z", timeout_s=1.0)

    def exchange(self, request: bytes, timeout_s: float) -> bytes:
        return self._query(b"X" + _TIMED.pack(max(0.0, timeout_s)) + bytes(request),
                           timeout_s)

    def close(self) -> None:
        self._token.undeclare()
        if self._owns:
            self.session.close()


Check = Callable[[bytes], None]
"""Raises BusArmError when a request must not reach the line."""


class BusServer:
    """Serves ``transport`` on ``busarm/<robot>/bus`` (see the module docstring): each op
    under ``lock`` (the robot's own driver's), after ``check``. ``on_lost`` runs when a
    client that was connected goes."""

    def __init__(self, session: zenoh.Session, robot: str, transport: Transport,
                 lock: threading.RLock, check: Check, on_lost: Callable[[str], None]
                 ) -> None:
        import zenoh

        self.transport = transport
        self._lock = lock
        self._check = check
        self._on_lost = on_lost
        self.served = 0
        self.refused = 0
        self._queryable = session.declare_queryable(bus_key(robot), self._on_query)
        self._clients = session.liveliness().declare_subscriber(
            client_key(robot, "*"), self._on_client, history=True)
        self._kind = zenoh.SampleKind

    def _on_query(self, query: zenoh.Query) -> None:
        payload = bytes(query.payload.to_bytes()) if query.payload is not None else b""
        try:
            query.reply(query.key_expr, self._serve(payload))
            self.served += 1
        except (BusArmError, struct.error, ValueError) as exc:
            self.refused += 1
            query.reply_err(str(exc))

    def _serve(self, payload: bytes) -> bytes:
        op, body = payload[:1], payload[1:]
        with self._lock:
            if op == b"X":
                (timeout_s,) = _TIMED.unpack_from(body)
                _check_timeout(timeout_s)
                self._check(body[_TIMED.size:])
                return self.transport.exchange(body[_TIMED.size:], timeout_s)
            if op == b"W":
                self._check(body)
                self.transport.write(body)
                return b""
            if op == b"R":
                max_bytes, timeout_s = _READ.unpack_from(body)
                _check_timeout(timeout_s)
                return self.transport.read(min(max_bytes, 4096), timeout_s)
            if op == b"Z":
                self.transport.reset_input()
                return b""
        raise ConfigError(f"unknown bus op {op!r}; allowed: X, W, R, Z")

    def _on_client(self, sample: zenoh.Sample) -> None:
        if sample.kind == self._kind.DELETE:
            self._on_lost(str(sample.key_expr).rsplit("/", 1)[-1])

    def close(self) -> None:
        self._clients.undeclare()
        self._queryable.undeclare()


def _check_timeout(timeout_s: float) -> None:
    if not (math.isfinite(timeout_s) and 0.0 <= timeout_s <= 5.0):
        raise ConfigError(f"bus op timeout {timeout_s!r} s; allowed: 0..5 s")
