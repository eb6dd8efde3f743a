"""Every servo port backend and every Lidar source, made for the conformance suites.

A backend is given to the tests as a ``Backend``: the ``ServoPort`` under test, opened
through the table (``open_servo_port``) as a user would, and the truth behind it, read
from the simulated servos (never through the port): where each servo really is, whether
its torque is on, how many write commands reached the servos; and a way to make a servo
fall silent. Adding a backend to the suite is one maker here (a context manager yielding
its ``Backend``) and one line in ``SERVO_BACKENDS``; a plugin's maker can be named
without editing this file: ``BUSARM_SERVO_PORT_BACKENDS=name=module:maker,...``.

The Zenoh backend serves each test's simulated servos on a loopback Zenoh session of its
own (no scouting, no multicast): the two sessions are opened once per module, the bus
server and the link once per test.

A Lidar source is given as a ``LidarBackend`` likewise: the source opened by model
(``open_lidar_source``), the ranges its simulated world really has, whether the device
scans, and a way to silence it (``LIDAR_BACKENDS``).
"""

from __future__ import annotations

import contextlib
import importlib
import os
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

from busarm.bus.servo_port import ServoPort, open_servo_port
from busarm.bus.servo_wire import LX_MODEL
from busarm.bus.transport import BOARD_BAUDRATE, DEFAULT_BAUDRATE, open_serial
from busarm.clock import WALL_CLOCK
from busarm.lidar.scan import LidarSource
from busarm.lidar.sources import open_lidar_source
from busarm.protocol import SPECS, Request
from busarm.sim.board import SimBoard
from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.rplidar import SimRplidar, rectangular_room
from busarm.sim.transport import SimTransport

PTY_MARGIN_S = 0.3
"""A busy computer hears a pty's reply late: the margin of every port on the wall clock
(as tests/conftest.py's)."""


@dataclass
class Backend:
    """A servo port under test and the truth behind it (see the module docstring)."""

    port: ServoPort
    ids: tuple[int, ...]
    truth_deg: Callable[[int], float]
    """Where the servo really is (deg from its mid-point), from the simulation."""
    is_loaded: Callable[[int], bool]
    """Whether the servo's torque is really on."""
    writes: Callable[[], int]
    """How many write commands have reached the servos so far."""
    silence: Callable[[int], None]
    """Make a servo stop answering (its power too low, say)."""
    closed: bool = False
    """Set by a test that closed the port itself (the maker then does not again)."""


@contextlib.contextmanager
def closed_after(backend: Backend) -> Iterator[Backend]:
    """``backend`` for a ``with`` block, its port closed after (unless a test did)."""
    try:
        yield backend
    finally:
        if not backend.closed:
            backend.port.close()


# ---------------------------------------------------------------------- the LX family


def _sim(on_wall_clock: bool, echo: bool = False) -> SimBus:
    return SimBus.with_ids(ARM_SERVO_IDS, timing=WireTiming(), echo=echo,
                           clock=WALL_CLOCK if on_wall_clock else None)


def _writes_of(sim: SimBus) -> Callable[[], int]:
    count = [0]
    lock = threading.Lock()

    def tap(request: Request) -> None:
        if not SPECS[request.command].is_read:
            with lock:
                count[0] += 1

    sim.taps.append(tap)
    return lambda: count[0]


def _sim_backend(port: ServoPort, sim: SimBus) -> Backend:
    writes = _writes_of(sim)

    def truth(sid: int) -> float:
        sim.advance()
        return LX_MODEL.deg_from_pulses(sim.servo(sid).position_pulses)

    def loaded(sid: int) -> bool:
        sim.advance()
        return sim.servo(sid).is_loaded

    def silence(sid: int) -> None:
        servo = sim.servo(sid)
        servo.supply_mv = servo.params.min_responsive_mv - 500

    return Backend(port, ARM_SERVO_IDS, truth, loaded, writes, silence)


@contextlib.contextmanager
def lx_in_process() -> Iterator[Backend]:
    """The LX line to simulated servos in this process, on a simulated clock."""
    sim = _sim(on_wall_clock=False)
    with closed_after(_sim_backend(open_servo_port("lx", SimTransport(sim)), sim)) as made:
        yield made


@contextlib.contextmanager
def _on_pty(line: SimBus | SimBoard | SimRplidar) -> Iterator[str]:
    server = PtyServer(line)
    try:
        yield server.start()
    finally:
        server.stop()


def lx_on_pty(echo: bool) -> Callable[[], contextlib.AbstractContextManager[Backend]]:
    @contextlib.contextmanager
    def make() -> Iterator[Backend]:
        """The LX line through a real pseudo-terminal, the adapter echoing or not."""
        sim = _sim(on_wall_clock=True, echo=echo)
        with _on_pty(sim) as path:
            transport = open_serial(path, DEFAULT_BAUDRATE, name=path, framing="lx")
            port = open_servo_port("lx", transport, timeout_margin_s=PTY_MARGIN_S)
            with closed_after(_sim_backend(port, sim)) as made:
                assert port.echo is echo  # type: ignore[attr-defined]  # detected at open
                yield made
    return make


@contextlib.contextmanager
def board_on_pty() -> Iterator[Backend]:
    """The same servos behind the simulated controller board, on a pty."""
    sim = _sim(on_wall_clock=True)
    with _on_pty(SimBoard(sim)) as path:
        transport = open_serial(path, BOARD_BAUDRATE, name=path, framing="board")
        port = open_servo_port("board", transport, timeout_margin_s=PTY_MARGIN_S)
        with closed_after(_sim_backend(port, sim)) as made:
            yield made


# ---------------------------------------------------------------------- over Zenoh


@dataclass
class _Sessions:
    server: Any
    client: Any
    robots: int = 0


_zenoh: dict[str, _Sessions] = {}


def close_zenoh_sessions() -> None:
    """Close the loopback sessions, if a test opened them (at the end of a module)."""
    sessions = _zenoh.pop("open", None)
    if sessions is not None:
        sessions.client.close()
        sessions.server.close()


def _sessions() -> _Sessions:
    if "open" not in _zenoh:
        from busarm.bench.ros import free_port
        from busarm.bus.zenoh_session import open_session

        endpoint = f"tcp/127.0.0.1:{free_port()}"
        server = open_session(listen=[endpoint])
        _zenoh["open"] = _Sessions(server, open_session(connect=[endpoint]))
    return _zenoh["open"]


def _until_served(session: Any, robot: str, timeout_s: float = 15.0) -> None:
    """Wait until the other session hears the robot's bus (a new queryable takes a moment
    to become known across sessions, more on a busy computer)."""
    from busarm.bus.zenoh_link import bus_key

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if any(r.ok is not None for r in session.get(bus_key(robot), payload=b"Z",
                                                      timeout=0.5)):
            return
        time.sleep(0.01)
    raise AssertionError(f"robot {robot!r} not served within {timeout_s:g} s")


@contextlib.contextmanager
def over_zenoh() -> Iterator[Backend]:
    """A robot's servos served on Zenoh (busarm.bus.zenoh_link.BusServer), reached by
    the ``zenoh`` port through a ZenohTransport."""
    from busarm.bus.zenoh_link import BusServer, ZenohTransport

    sessions = _sessions()
    sessions.robots += 1
    robot = f"conformance{sessions.robots}"
    sim = _sim(on_wall_clock=True)
    served = SimTransport(sim, name="served")
    server = BusServer(sessions.server, robot, served, threading.RLock(),
                       lambda request: None, lambda client: None)
    try:
        _until_served(sessions.client, robot)
        link = ZenohTransport(sessions.client, robot, f"zenoh robot {robot}",
                              owns_session=False)
        port = open_servo_port("zenoh", link, timeout_margin_s=PTY_MARGIN_S)
        with closed_after(_sim_backend(port, sim)) as made:
            yield made
    finally:
        server.close()


# ---------------------------------------------------------------------- the table

SERVO_BACKENDS: dict[str, Callable[[], contextlib.AbstractContextManager[Backend]]] = {
    "lx-inproc": lx_in_process,
    "lx-pty-noecho": lx_on_pty(echo=False),
    "lx-pty-echo": lx_on_pty(echo=True),
    "board-pty": board_on_pty,
    "zenoh": over_zenoh,
}
"""Name -> maker of every backend the suite runs on (the example family's is added
below, from its own module: written from docs/adding_a_backend.md alone)."""

EXAMPLE_FAMILY = {"toy": "conformance.example_backend:open_toy_port"}
"""The example family's line of the servo port table (SERVO_PORTS), registered for the
tests that use it."""


def _plugin_backends() -> dict[str, Callable[[], contextlib.AbstractContextManager[Backend]]]:
    """Makers named in BUSARM_SERVO_PORT_BACKENDS (``name=module:maker,...``)."""
    found = {}
    for item in filter(None, os.environ.get("BUSARM_SERVO_PORT_BACKENDS", "").split(",")):
        name, _, target = item.strip().partition("=")
        module, _, attr = target.partition(":")
        found[name] = getattr(importlib.import_module(module), attr)
    return found


def _toy() -> contextlib.AbstractContextManager[Backend]:
    from conformance.example_backend import conformance_backend

    return conformance_backend()


SERVO_BACKENDS["toy"] = _toy
SERVO_BACKENDS.update(_plugin_backends())




# ---------------------------------------------------------------------- Lidar sources


@dataclass
class LidarBackend:
    """A Lidar source under test (opened by model, ``open_lidar_source``) and the truth
    behind it: the ranges its world really has, whether the device is scanning, and a
    way to make it fall silent."""

    source: LidarSource
    true_ranges: Callable[[Any], Any]
    """Bearings (rad, the scan's convention) -> the world's ranges (m), without noise."""
    is_scanning: Callable[[], bool]
    silence: Callable[[], None]
    scan_hz: float
    noisy: bool
    """Whether the source adds range noise and dropouts (the twin's does)."""


@contextlib.contextmanager
def a1_on_pty() -> Iterator[LidarBackend]:
    """The simulated RPLIDAR A1 (busarm.sim.rplidar) in a rectangular room, on a pty,
    opened as model ``rplidar-a1`` by its device path."""
    import numpy as np

    device = SimRplidar(rectangular_room(), scan_hz=10.0, clock=WALL_CLOCK)
    with _on_pty(device) as path:
        source = open_lidar_source("rplidar-a1", path)
        try:
            yield LidarBackend(source, lambda b: np.array([device.world(x) for x in b]),
                               lambda: device.scanning, device.go_silent, 10.0, noisy=False)
        finally:
            source.close()


@contextlib.contextmanager
def twin_lidar() -> Iterator[LidarBackend]:
    """A twin's own A1, ray-cast in its arena (a twin of its own, on its simulated
    clock), opened as model ``twin`` given the twin."""
    from busarm.twin.arena_gen import random_arena
    from busarm.twin.twin import Twin

    with Twin(arena=random_arena(3), realtime=False) as twin:
        source = open_lidar_source("twin", twin)
        device = source.transport.bus  # type: ignore[attr-defined]  # its simulated A1
        try:
            yield LidarBackend(source, device.world.true_ranges, lambda: device.scanning,
                               device.go_silent, device.scan_hz, noisy=True)
        finally:
            source.close()


LIDAR_BACKENDS: dict[str, Callable[[], contextlib.AbstractContextManager[LidarBackend]]] = {
    "a1-pty": a1_on_pty,
    "twin": twin_lidar,
}
"""Name -> maker of every Lidar source the Lidar suite runs on."""
