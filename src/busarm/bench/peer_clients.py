"""The libraries ``busarm.bench.peers`` compares, behind one small interface, and the
guarded call that runs each of their calls on a watchdog thread with its output captured
(so a peer that prints, raises or hangs is recorded and the bench goes on).

The peers (pylx16a, lewansoul-lx16a) are imported only when a client opens; they are
installed only for ``make bench-peers`` (the ``peers`` extra; lewansoul-lx16a is also a
dev dependency).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from busarm.bus.driver import ServoBus

__all__ = [
    "AFTER_GLITCH",
    "BAUD",
    "CALL_LIMIT_S",
    "CLIENTS",
    "GLITCH_POSITIONS",
    "LOG_CAPTURE",
    "OPEN_LIMIT_S",
    "POS_REPLY_BYTES",
    "REQUEST_BYTES",
    "TURNAROUND_MS",
    "WIRE_LIMIT",
    "WIRE_S",
    "BusarmClient",
    "Client",
    "LewansoulClient",
    "LogCapture",
    "Outcome",
    "PylxClient",
    "close_client",
    "guarded",
    "open_client",
]


BAUD = 115200
TURNAROUND_MS = 0.5
REQUEST_BYTES = 6
POS_REPLY_BYTES = 8
CALL_LIMIT_S = 2.0
"""Watchdog: a single call taking longer than this is a hang."""
OPEN_LIMIT_S = 10.0
WIRE_S = (REQUEST_BYTES + POS_REPLY_BYTES) * 10 / BAUD + TURNAROUND_MS / 1000
WIRE_LIMIT = 1.0 / WIRE_S
"""Position reads per second the wire allows: request, turnaround, reply."""
GLITCH_POSITIONS = {1: 100, 2: 700}
"""Where servos 1 and 2 stand in the glitch tests."""
AFTER_GLITCH = (2, 1, 1, 2, 1)
"""Servos read after each glitch: alternating shows a reply shifted by one transaction,
the repeat shows a stale reply of the same servo."""


# ---------------------------------------------------------------------- guarded calls


@dataclass
class Outcome:
    """What one guarded call did: "ok" with a value, "error" with a message, or "hang"."""

    kind: str
    value: Any = None
    error: str = ""
    seconds: float = 0.0
    output: str = ""


class LogCapture(logging.Handler):
    """Collects what libraries log (lewansoul-lx16a logs warnings on odd replies)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        with contextlib.suppress(Exception):
            self.lines.append(f"{record.name}: {record.getMessage()}")


LOG_CAPTURE = LogCapture()


def guarded(fn: Callable[[], Any], limit_s: float) -> Outcome:
    """Run ``fn`` on a daemon thread; give up on it after ``limit_s`` (a hang).

    stdout and stderr are captured while the main thread waits (and restored even if
    the call never returns), so a chatty peer cannot garble the tables.
    """
    box: dict[str, Any] = {}

    def run() -> None:
        t0 = time.perf_counter()
        try:
            box["value"] = fn()
        except BaseException as exc:  # peers raise anything, SystemExit included
            box["error"] = f"{type(exc).__name__}: {exc}".strip()
        box["seconds"] = time.perf_counter() - t0

    out = io.StringIO()
    thread = threading.Thread(target=run, name="peer-call", daemon=True)
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        thread.start()
        thread.join(limit_s)
    if thread.is_alive():
        return Outcome("hang", seconds=time.perf_counter() - t0, output=out.getvalue())
    seconds = box.get("seconds", 0.0)
    if "error" in box:
        return Outcome("error", error=box["error"], seconds=seconds, output=out.getvalue())
    return Outcome("ok", box.get("value"), seconds=seconds, output=out.getvalue())


# ---------------------------------------------------------------------- the libraries


class Client:
    """One library's position read, in pulses, for one port."""

    name = ""
    package = ""

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        raise NotImplementedError

    def read_pulses(self, servo_id: int) -> int:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError

    def describe(self) -> str:
        return ""


class BusarmClient(Client):
    name = "busarm"
    package = "busarm"

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        # busarm's defaults: echo detected at open, baud-derived timeouts, 2 retries.
        bus = ServoBus.open(path, baudrate=BAUD, turnaround_s=TURNAROUND_MS / 1000)
        assert isinstance(bus, ServoBus)  # the simulator's pty: the LX line itself
        self.bus = bus
        self.read_pulses = self.bus.read_position_pulses  # type: ignore[method-assign]

    def close(self) -> None:
        self.bus.close()

    def describe(self) -> str:
        plan_timeout = self.bus.timeout_s(REQUEST_BYTES, POS_REPLY_BYTES)
        return (f"ServoBus.read_position_pulses; timeout {plan_timeout * 1e3:.1f} ms per attempt, "
                f"{self.bus.retries} retries, echo {'on' if self.bus.echo else 'off'}")


class PylxClient(Client):
    """pylx16a: a class-wide serial port, LX16A(id) objects reading angles in degrees."""

    name = "pylx16a"
    package = "pylx16a==1.1.1"

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        lx16a: Any = importlib.import_module("pylx16a.lx16a")  # optional, untyped

        self.cls = lx16a.LX16A
        self.cls.initialize(path, timeout_s)
        # The constructor reads a dozen registers and enables torque.
        self.servos = {sid: self.cls(sid) for sid in ids}

    def read_pulses(self, servo_id: int) -> int:
        degrees: float = self.servos[servo_id].get_physical_angle()
        return round(degrees * 25 / 6)

    def close(self) -> None:
        port = self.cls._controller
        self.cls._controller = None
        if port is not None:
            port.close()

    def describe(self) -> str:
        return (f"LX16A(id).get_physical_angle(); timeout {self.cls.get_timeout() * 1e3:.0f} ms "
                "(LX16A.initialize)")


class LewansoulClient(Client):
    """lewansoul-lx16a: ServoController(serial.Serial(...)).get_position(id)."""

    name = "lewansoul-lx16a"
    package = "lewansoul-lx16a==0.1"

    def open(self, path: str, timeout_s: float, ids: Sequence[int]) -> None:
        lewansoul_lx16a: Any = importlib.import_module("lewansoul_lx16a")  # untyped
        import serial

        self.timeout_s = timeout_s
        self.port = serial.Serial(path, BAUD, timeout=timeout_s)
        self.ctrl = lewansoul_lx16a.ServoController(self.port, timeout=timeout_s)

    def read_pulses(self, servo_id: int) -> int:
        return int(self.ctrl.get_position(servo_id))

    def close(self) -> None:
        self.port.close()

    def describe(self) -> str:
        return (f"ServoController.get_position(id); timeout {self.timeout_s * 1e3:.0f} ms "
                "(ServoController(timeout=...))")


CLIENTS: tuple[type[Client], ...] = (BusarmClient, PylxClient, LewansoulClient)


def open_client(
    cls: type[Client], path: str, timeout_s: float, ids: Sequence[int]
) -> tuple[Client | None, Outcome]:
    """A client of ``cls`` opened on ``path`` (None if opening failed), and how it went."""
    client = cls()
    outcome = guarded(lambda: client.open(path, timeout_s, ids), OPEN_LIMIT_S)
    if outcome.kind != "ok":
        guarded(client.close, CALL_LIMIT_S)
        return None, outcome
    return client, outcome


def close_client(client: Client | None) -> None:
    if client is not None:
        guarded(client.close, CALL_LIMIT_S)
