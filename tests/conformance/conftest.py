"""The conformance suites' fixtures: every servo port backend and Lidar source
(``backends.py``), each test on fresh servos or a fresh Lidar, and the wall-clock mark
for those served in real time."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from busarm.bus.servo_port import SERVO_PORTS
from conformance.backends import (
    EXAMPLE_FAMILY,
    LIDAR_BACKENDS,
    SERVO_BACKENDS,
    Backend,
    LidarBackend,
    close_zenoh_sessions,
)


@pytest.fixture(scope="module")
def zenoh_sessions() -> Iterator[None]:
    """The Zenoh backend's two loopback sessions live for a module (opened by the first
    test that uses them)."""
    yield
    close_zenoh_sessions()


@pytest.fixture(params=sorted(SERVO_BACKENDS))
def backend(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch,
            zenoh_sessions: None) -> Iterator[Backend]:
    """Each backend in turn, its servos fresh for each test."""
    for kind, target in EXAMPLE_FAMILY.items():
        monkeypatch.setitem(SERVO_PORTS, kind, target)
    with SERVO_BACKENDS[request.param]() as made:
        yield made


@pytest.fixture(params=sorted(LIDAR_BACKENDS))
def lidar(request: pytest.FixtureRequest) -> Iterator[LidarBackend]:
    """Each Lidar source in turn, opened afresh for each test."""
    with LIDAR_BACKENDS[request.param]() as made:
        yield made


WALL_CLOCK_BACKENDS = {"lx-pty-noecho", "lx-pty-echo", "board-pty", "zenoh", "a1-pty"}


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The backends on the wall clock (a pty, a Zenoh link) carry the wallclock mark."""
    here = Path(__file__).parent
    for item in items:
        if here not in item.path.parents:
            continue
        spec = getattr(item, "callspec", None)
        params = spec.params if spec is not None else {}
        if WALL_CLOCK_BACKENDS & {params.get("backend"), params.get("lidar")}:
            item.add_marker(pytest.mark.wallclock(
                "a device on a pty or a loopback Zenoh link, served in wall-clock time"))
