"""The simulator as an in-process transport: ``open_bus("sim://?ids=1,2,3")``.

URL query parameters (all optional):

=============== ==================================================== =================
``ids``         servo IDs on the bus, comma separated                1,2,3,4,5,10
``echo``        1 = the adapter echoes every byte sent               0
``timing``      0 = no wire timing (replies at once)                 1
``turnaround_ms`` servo reply delay in ms                            0.5
``drop``, ``corrupt`` probability per byte of a fault                0
``late``        probability per reply of arriving ``late_ms`` late   0
``late_ms``     how late                                             50
``seed``        fault generator seed                                 0
``state``       path of a power-off state file                       (none)
``block``       1 = a 3 cm block sits between the gripper's fingers  0
``realtime``    1 = the wall clock (replies and moves take real time) 0
``pace``        simulated seconds per wall second (unset: flat out)  (none)
=============== ==================================================== =================

The simulator runs on a simulated clock (``busarm.clock.SimClock``), as the twin does:
a move or a reply waited for costs only the CPU it takes to simulate, and every time
reported is simulated seconds. ``realtime=1`` puts it on the wall clock (to time a
program against a real line's pace); ``pace=1`` keeps simulated time no faster than the
wall clock, for a person watching.
"""

from __future__ import annotations

import threading
from pathlib import Path
from urllib.parse import parse_qs, urlsplit

from busarm.clock import WALL_CLOCK, Clock, SimClock
from busarm.errors import ConfigError, TransportError
from busarm.protocol import SERVO_TURNAROUND_S
from busarm.sim.bus import ARM_SERVO_IDS, FaultInjection, SimBus, SimLine, WireTiming
from busarm.units import check_range, listing, parse_ids

__all__ = [
    "SimTransport",
    "open_sim_transport",
    "query_flag",
    "query_float",
    "sim_bus_from_url",
]


_KNOWN = {"ids", "echo", "timing", "turnaround_ms", "drop", "corrupt", "late", "late_ms", "seed",
          "state", "block", "realtime", "pace"}


def query_float(q: dict[str, str], key: str, default: float, what: str = "sim URL") -> float:
    """A number from a URL query (``default`` when absent); ConfigError naming the key."""
    if key not in q:
        return default
    try:
        return float(q[key])
    except ValueError:
        raise ConfigError(f"{what}: {key}={q[key]!r} is not a number") from None


def query_flag(q: dict[str, str], key: str, default: bool, what: str = "sim URL") -> bool:
    """A 0/1 flag from a URL query (``default`` when absent); ConfigError naming the key."""
    if key not in q:
        return default
    if q[key] not in ("0", "1"):
        raise ConfigError(f"{what}: {key}={q[key]!r}; allowed: 0 or 1")
    return q[key] == "1"


def _query_rate(q: dict[str, str], key: str) -> float:
    """A fault probability from the URL, 0..1, checked under its URL key."""
    return check_range(f"sim URL: {key}", query_float(q, key, 0.0), 0.0, 1.0)


def sim_bus_from_url(url: str, baudrate: int = 115200) -> SimBus:
    """A SimBus configured by a ``sim://?...`` URL (``sim`` alone is the arm)."""
    query = urlsplit(url).query if "://" in url else ""
    raw = parse_qs(query, keep_blank_values=True)
    unknown = set(raw) - _KNOWN
    if unknown:
        raise ConfigError(
            f"sim URL: unknown parameter(s) {listing(sorted(unknown))}; known: "
            f"{listing(sorted(_KNOWN))}"
        )
    q = {k: v[-1] for k, v in raw.items()}
    ids = parse_ids(q["ids"]) if "ids" in q else list(ARM_SERVO_IDS)
    turnaround_ms = check_range("sim URL: turnaround_ms",
                                query_float(q, "turnaround_ms", SERVO_TURNAROUND_S * 1000),
                                0.0, 100.0, "ms")
    timing = WireTiming(baudrate, turnaround_ms / 1000.0, query_flag(q, "timing", True))
    # Checked here under the URL's own keys (FaultInjection would name its fields).
    faults = FaultInjection(
        drop_rate=_query_rate(q, "drop"),
        corrupt_rate=_query_rate(q, "corrupt"),
        late_rate=_query_rate(q, "late"),
        late_s=check_range("sim URL: late_ms", query_float(q, "late_ms", 50.0),
                           0.0, 10000.0, "ms") / 1000.0,
        seed=int(query_float(q, "seed", 0)),
    )
    state = Path(q["state"]) if q.get("state") else None
    bus = SimBus.with_ids(
        ids, timing=timing, echo=query_flag(q, "echo", False), faults=faults, state_file=state,
        clock=_url_clock(q),
    )
    if query_flag(q, "block", False):
        bus.put_block_in_gripper()
    return bus


def _url_clock(q: dict[str, str]) -> Clock:
    """The wall clock for ``realtime=1``, else a simulated one (paced by ``pace=``)."""
    realtime = query_flag(q, "realtime", False)
    if "pace" not in q:
        return WALL_CLOCK if realtime else SimClock()
    if realtime:
        raise ConfigError("sim URL: pace= and realtime=1 exclude each other: realtime is "
                          "the wall clock")
    return SimClock(pace=check_range("sim URL: pace", query_float(q, "pace", 1.0),
                                     0.01, 1000.0))


class SimTransport:
    """A transport whose other end is a simulated line in this process: a SimBus, or a
    SimBoard in front of one."""

    def __init__(self, bus: SimLine, name: str = "sim") -> None:
        self.bus = bus
        self.name = name
        self.framing = bus.framing
        self.baudrate = bus.timing.baudrate
        self.latency_s = 0.0
        self.clock = bus.clock
        self._closed = False
        self._lock = threading.Lock()

    def write(self, data: bytes) -> None:
        self._check_open()
        self.bus.receive(bytes(data))

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        self._check_open()
        clock = self.clock
        deadline = clock.now() + max(timeout_s, 0.0)
        with self._lock:
            while True:
                data = self.bus.pop_output(max_bytes)
                if data:
                    return data
                now = clock.now()
                due = self.bus.next_output_at()
                if now >= deadline:
                    return b""
                wake = deadline if due is None else min(max(due, now), deadline)
                clock.sleep(max(wake - now, 0.0))

    def reset_input(self) -> None:
        self._check_open()
        self.bus.pop_output()

    def exchange(self, request: bytes, timeout_s: float) -> bytes:
        self.reset_input()
        self.write(request)
        return self.read(256, timeout_s)

    def close(self) -> None:
        """Close; the servos power off, saving their state file (``state=``) with each
        horn where it is, as a real servo's horn stays where the power left it."""
        if not self._closed:
            self._closed = True
            self.bus.power_off()

    def _check_open(self) -> None:
        if self._closed:
            raise TransportError(f"{self.name}: transport is closed")


def open_sim_transport(url: str, baudrate: int = 115200) -> SimTransport:
    """Entry point used by ``busarm.bus.transport.open_transport`` for ``sim``/``sim://``."""
    return SimTransport(sim_bus_from_url(url, baudrate), name=url)
