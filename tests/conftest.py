"""Shared fixtures: simulated arms reachable in-process and through a real pseudo-terminal.

Every driver test runs five ways: in-process and over a pty, each with the simulated
adapter echoing and not echoing, and through the simulated controller board on a pty
(the same simulated servos behind it). A test of the LX wire itself (echo, raw frames,
replies the board never passes on) says so with ``lx_wire_only``. Leaked threads fail
the test that leaked them.
"""

from __future__ import annotations

import gc
import os
import signal
import subprocess
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from hypothesis import settings

from busarm.bus.board_bus import BoardServoBus
from busarm.bus.driver import ServoBus
from busarm.bus.transport import BOARD_PREFIX
from busarm.protocol import SPECS, Command, FrameParser
from busarm.sim.board import SimBoard
from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport

# CI explores the same examples every run (a red CI is then a real regression, reproduced
# by the next run); developers' runs keep drawing new ones.
settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


LX_WAYS = ["inproc-noecho", "inproc-echo", "pty-noecho", "pty-echo"]
"""The plain LX line: in-process or through a pty, the adapter echoing or not."""
BOARD_WAY = "pty-board"
"""The simulated controller board served on a pty, opened as ``board:///dev/pts/N`` (a
BoardServoBus), in front of the same simulated servos."""
WAYS = [*LX_WAYS, BOARD_WAY]

lx_wire_only = pytest.mark.parametrize("arm", LX_WAYS, indirect=True)
"""For a test of the LX wire itself (echo, raw frames, stray or late LX replies, two
servos' replies colliding): the board never passes those bytes on, so it runs the LX
ways only (deselected by parametrization, not skipped)."""


@dataclass
class SimArm:
    """A driver and the simulator behind it, for tests to inspect."""

    bus: ServoBus
    sim: SimBus
    kind: str
    board: SimBoard | None = None
    """The simulated controller board between the bus and ``sim``, if any."""


def make_sim_arm(
    kind: str, *, ids: tuple[int, ...] = ARM_SERVO_IDS, echo: bool = False,
    board: bool = False, **bus_kwargs: object
) -> tuple[SimArm, PtyServer | None]:
    """A bus on simulated servos: in-process (``kind`` "inproc") or on a pty ("pty"),
    through a simulated controller board on that pty if ``board``."""
    sim = SimBus.with_ids(ids, timing=WireTiming(), echo=echo)
    if board:
        sim_board = SimBoard(sim)
        server = PtyServer(sim_board)
        bus = ServoBus.open(BOARD_PREFIX + server.start(), **bus_kwargs)  # type: ignore[arg-type]
        assert isinstance(bus, BoardServoBus)
        return SimArm(bus, sim, kind, sim_board), server
    if kind == "pty":
        server = PtyServer(sim)
        path = server.start()
        bus = ServoBus.open(path, **bus_kwargs)  # type: ignore[arg-type]
        return SimArm(bus, sim, kind), server
    return SimArm(ServoBus(SimTransport(sim), **bus_kwargs), sim, kind), None  # type: ignore[arg-type]


def make_sim_arm_way(way: str, **kwargs: Any) -> tuple[SimArm, PtyServer | None]:
    """``make_sim_arm`` for one of ``WAYS``; checks the echo the bus detected."""
    kind, line = way.split("-")
    sim_arm, server = make_sim_arm(kind, echo=line == "echo", board=line == "board", **kwargs)
    assert sim_arm.bus.echo is (line == "echo"), "echo auto-detection failed"
    return sim_arm, server


@pytest.fixture(params=WAYS)
def arm(request: pytest.FixtureRequest) -> Iterator[SimArm]:
    """The simulated 6-servo arm behind a ServoBus, five ways (echo detected at open)."""
    sim_arm, server = make_sim_arm_way(request.param)
    try:
        yield sim_arm
    finally:
        sim_arm.bus.close()
        if server is not None:
            server.stop()


@pytest.fixture(autouse=True, scope="session")
def _private_runtime_dir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The tests' own runtime folder: a `busarm sim serve` the developer (or another test
    run) has running must not become the default port of the commands under test."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("BUSARM_RUNTIME_DIR", str(tmp_path_factory.mktemp("busarm-run")))
        yield


@pytest.fixture(autouse=True)
def _private_config_dir(tmp_path_factory: pytest.TempPathFactory,
                        monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test's own XDG config folder: kept camera calibrations
    (busarm.robot.calibration_store) never come from, or go to, the real home folder,
    nor from another test."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path_factory.mktemp("config")))


@pytest.fixture(autouse=True)
def _no_leaked_threads() -> Iterator[None]:
    before = set(threading.enumerate())
    yield
    leaked = [
        t for t in threading.enumerate()
        if t not in before and t.is_alive() and t.name.startswith("busarm")
    ]
    for t in leaked:
        t.join(timeout=2)
    still = [t.name for t in leaked if t.is_alive()]
    assert not still, f"test leaked threads: {still}"


@pytest.fixture
def no_gc_pauses() -> Iterator[None]:
    """For tests that time a call against the driver's budget: a collection of the earlier
    tests' objects (tens of ms, late in a full run) is not the driver's time."""
    gc.collect()
    gc.freeze()
    gc.disable()
    try:
        yield
    finally:
        gc.enable()
        gc.unfreeze()


@pytest.fixture(scope="session")
def twin_calibration(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The twin's camera calibration files (intrinsics, hand-eye), made once per test run
    by our own flows (a few seconds), for the tests that need a calibrated twin."""
    from busarm.robot import Robot

    folder = tmp_path_factory.mktemp("twin-calibration")
    with Robot.open("twin", calibration_dir=folder):
        pass
    return folder / "camera.json", folder / "hand_eye.json"


class ListeningSim(SimBus):
    """A simulated bus that keeps every command the host sent it, parsed from the bytes."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.heard: list[Command] = []
        self._wire = FrameParser()

    def receive(self, data: bytes) -> None:
        self.heard += [Command(frame.command) for frame in self._wire.feed(data)]
        super().receive(data)

    def writes(self) -> list[Command]:
        """The write commands heard so far (anything but a read)."""
        return [c for c in self.heard if not SPECS[c].is_read]


def sigint_and_wait(proc: subprocess.Popen[str], timeout_s: float = 30.0
                    ) -> tuple[int, str, str]:
    """Ctrl+C to a command run as a subprocess; its exit code, stdout and stderr."""
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        raise
    return proc.returncode, out, err
