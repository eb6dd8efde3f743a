"""Shared fixtures: simulated arms reachable in-process and through a real pseudo-terminal.

Every driver test runs five ways: in-process and over a pty, each with the simulated
adapter echoing and not echoing, and through the simulated controller board on a pty
(the same simulated servos behind it). A test of the LX wire itself (echo, raw frames,
replies the board never passes on) says so with ``lx_wire_only``, one of LX commands the
board cannot pass on with ``lx_commands_only``. Leaked threads fail the test that leaked
them.

Time: in-process, the simulated servos live on a simulated clock (``arm.sim.clock``):
a move or a reply waited for costs only the CPU it takes, and the time a test reads is
the simulation's, whatever else the computer is doing. Through a pty they answer in
wall-clock time (another program could be at the other end), so those buses get a
generous reply margin (``PTY_MARGIN_S``): a busy computer may hear a reply late, which
is not what these tests are about. A test whose subject is a deadline on the wall clock
gives its own margin and says why. Tests on the wall clock carry the ``wallclock``
marker with that reason (``pytest -m wallclock --collect-only`` lists them).
"""

from __future__ import annotations

import fcntl
import gc
import importlib.util
import os
import shutil
import signal
import subprocess
import threading
import traceback
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from click.testing import Result
from hypothesis import HealthCheck, settings

from busarm.bus.board_bus import BoardServoBus
from busarm.bus.driver import ServoBus
from busarm.bus.ports import SerialPort
from busarm.clock import WALL_CLOCK, Clock
from busarm.protocol import SPECS, Command, FrameParser
from busarm.sim.board import SimBoard
from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport

# Hypothesis's own wall-clock checks (an example's deadline, data generation "too slow")
# fail on a busy computer for no fault of the code: off for every test.
settings.register_profile("busy", deadline=None, suppress_health_check=[HealthCheck.too_slow])
# CI explores the same examples every run (a red CI is then a real regression, reproduced
# by the next run); developers' runs keep drawing new ones.
settings.register_profile("ci", parent=settings.get_profile("busy"), derandomize=True,
                          print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "busy")


PTY_MARGIN_S = 0.3
"""The reply margin of a bus on a pty whose deadline is not what the test checks: the
driver's default (4 ms) is for a computer that does nothing else; a test machine running
other tests beside it (or two CPU-bound programs) may hear a reply tens, at times hundreds,
of ms late. It costs time only where a reply never comes."""
PTY_REASON = "bytes through a real pseudo-terminal, served by a thread in wall-clock time"

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
lx_commands_only = pytest.mark.parametrize("arm", LX_WAYS, indirect=True)
"""For a test of LX commands the board has no sub-command for (motor mode, the servos'
LEDs and alarm masks, queued moves, reading moves back): the LX ways only. That the
board's bus refuses them, sending nothing, is test_driver's
test_the_board_refuses_what_it_cannot_pass_on."""


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
    """A bus on simulated servos: in-process (``kind`` "inproc", on a simulated clock) or
    on a pty ("pty", the wall clock, with ``PTY_MARGIN_S`` unless ``timeout_margin_s``
    is given), through a simulated controller board on that pty if ``board``."""
    on_pty = board or kind == "pty"
    sim = SimBus.with_ids(ids, timing=WireTiming(), echo=echo,
                          clock=WALL_CLOCK if on_pty else None)
    if on_pty:
        bus_kwargs.setdefault("timeout_margin_s", PTY_MARGIN_S)
    if board:
        board_bus, sim_board, server = open_board_bus(sim, **bus_kwargs)
        return SimArm(board_bus, sim, kind, sim_board), server
    if kind == "pty":
        server = PtyServer(sim)
        path = server.start()
        bus = ServoBus.open(path, **bus_kwargs)  # type: ignore[arg-type]
        return SimArm(bus, sim, kind), server
    return SimArm(ServoBus(SimTransport(sim), **bus_kwargs), sim, kind), None  # type: ignore[arg-type]


def open_board_bus(sim: SimBus, **bus_kwargs: object
                   ) -> tuple[BoardServoBus, SimBoard, PtyServer]:
    """A simulated controller board in front of ``sim`` (on the wall clock), served on a
    pty and opened as ``board:///dev/pts/N`` (with ``PTY_MARGIN_S`` unless
    ``timeout_margin_s`` is given): the bus, the board, and the server to stop."""
    bus_kwargs.setdefault("timeout_margin_s", PTY_MARGIN_S)
    board = SimBoard(sim)
    server = PtyServer(board)
    try:
        bus = ServoBus.open(SerialPort(server.start(), board=True), **bus_kwargs)  # type: ignore[arg-type]
    except BaseException:
        server.stop()
        raise
    assert isinstance(bus, BoardServoBus)
    return bus, board, server


@contextmanager
def sim_bus_on(sim: SimBus, way: str = "inproc", **bus_kwargs: object) -> Iterator[ServoBus]:
    """A bus on ``sim`` for a ``with`` block: in-process, or behind the simulated board
    on a pty (``way`` BOARD_WAY)."""
    if way != BOARD_WAY:
        with ServoBus(SimTransport(sim), **bus_kwargs) as bus:  # type: ignore[arg-type]
            yield bus
        return
    board_bus, _, server = open_board_bus(sim, **bus_kwargs)
    try:
        with board_bus:
            yield board_bus
            # Answered, so every write before it has reached the servos: the server may
            # stop (it would drop bytes still in the pty, unread).
            board_bus.read_temp_c(next(s.servo_id for s in sim.servos))
    finally:
        server.stop()


def make_sim_arm_way(way: str, **kwargs: Any) -> tuple[SimArm, PtyServer | None]:
    """``make_sim_arm`` for one of ``WAYS``; checks the echo the bus detected."""
    kind, line = way.split("-")
    sim_arm, server = make_sim_arm(kind, echo=line == "echo", board=line == "board", **kwargs)
    assert sim_arm.bus.echo is (line == "echo"), "echo auto-detection failed"
    return sim_arm, server


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--wallclock-reasons", action="store_true",
                     help="with --collect-only: list the tests on the wall clock, each "
                          "group with its reason (docs/benchmarks.md keeps the list)")


def pytest_report_collectionfinish(config: pytest.Config, items: list[pytest.Item]
                                   ) -> list[str]:
    """The tests on the wall clock, grouped by file and reason (--wallclock-reasons)."""
    if not config.getoption("--wallclock-reasons"):
        return []
    groups: dict[tuple[str, str], list[str]] = {}
    for item in items:
        mark = item.get_closest_marker("wallclock")
        if mark is not None:
            reason = str(mark.args[0]) if mark.args else "(no reason given)"
            groups.setdefault((item.nodeid.split("::")[0], reason), []).append(item.name)
    lines = [f"{len(names):4d}  {path}: {reason}" for (path, reason), names in sorted(
        groups.items())]
    return [f"{sum(len(n) for n in groups.values())} tests on the wall clock:", *lines]


def pytest_itemcollected(item: pytest.Item) -> None:
    """The ``arm`` fixture's pty ways run on the wall clock: marked so (here, before ``-m``
    selects by marks)."""
    spec = getattr(item, "callspec", None)
    way = spec.params.get("arm", spec.params.get("way")) if spec is not None else None
    if isinstance(way, str) and way.startswith("pty"):
        item.add_marker(pytest.mark.wallclock(PTY_REASON))


@pytest.hookimpl(trylast=True)  # after the other conftests have marked theirs
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The slow tests go first (in their order otherwise): pytest-xdist's workers start
    the long ones early and share the short ones at the end, rather than one worker
    finishing a whole job alone while the others wait."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


@contextmanager
def sim_arm_way(way: str, **kwargs: Any) -> Iterator[SimArm]:
    """``make_sim_arm_way`` for a ``with`` block: the bus closed, the pty stopped after."""
    sim_arm, server = make_sim_arm_way(way, **kwargs)
    try:
        yield sim_arm
    finally:
        sim_arm.bus.close()
        if server is not None:
            server.stop()


@pytest.fixture(params=WAYS)
def arm(request: pytest.FixtureRequest) -> Iterator[SimArm]:
    """The simulated 6-servo arm behind a ServoBus, five ways (echo detected at open)."""
    with sim_arm_way(request.param) as sim_arm:
        yield sim_arm


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
    tests' objects (tens of ms, late in a full run) is not the driver's time. No collection
    first: with the collector off none can start during the test, and a full one here
    (0.2 s late in a run, before each of some 250 tests) only cost time; the garbage frozen
    with the rest goes back to the oldest generation afterwards, collected as usual."""
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
    from busarm.robot import CameraSpec, Robot, RobotConfig

    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        folder = tmp_path_factory.mktemp("twin-calibration")
    else:  # one calibration for all of pytest-xdist's workers: the first makes it
        folder = tmp_path_factory.getbasetemp().parent / "twin-calibration"
    folder.mkdir(exist_ok=True)
    files = folder / "camera.json", folder / "hand_eye.json"
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not all(f.exists() for f in files):
            with Robot.open(RobotConfig(camera=CameraSpec(folder=folder))):
                pass
    return files


@pytest.fixture
def twin_config_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                     twin_calibration: tuple[Path, Path]) -> Path:
    """``$XDG_CONFIG_HOME`` of this test, with the twin's camera calibration kept there (as
    a first run leaves it): what is opened there does not make it again."""
    home = tmp_path / "config"
    keep_twin_calibration(home, twin_calibration)
    monkeypatch.setenv("XDG_CONFIG_HOME", str(home))
    return home


def keep_twin_calibration(config_home: Path, files: tuple[Path, Path]) -> Path:
    """Keep ``files`` (``twin_calibration``'s) for robot ``twin`` in the XDG config folder
    ``config_home``, where a twin's ``pick-sort`` would keep the calibration it made
    (busarm.robot.calibration_store), so the commands run there do not make it again.
    Making and keeping it is test_cli_calibrations'. The robot's folder is returned."""
    from busarm.twin.spec import TwinSpec

    folder = config_home / "busarm" / TwinSpec().robot_key
    folder.mkdir(parents=True, exist_ok=True)
    for file in files:
        shutil.copy2(file, folder / file.name)
    return folder


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


def wait_for(predicate: Callable[[], bool], timeout_s: float = 10.0,
             clock: Clock = WALL_CLOCK) -> bool:
    """Poll until ``predicate()`` holds (True) or ``timeout_s`` of ``clock`` pass (False).
    On the wall clock the budget is generous: only a failing test waits it out."""
    deadline = clock.now() + timeout_s
    while not predicate():
        if clock.now() > deadline:
            return False
        clock.sleep(0.002)
    return True


IN_PROCESS_PORT = "sim://?seed=31337"


def in_process_port(monkeypatch: pytest.MonkeyPatch, sim: SimBus) -> str:
    """The port by which commands run in this process (click's runner) open ``sim``, the
    test's own simulated servos, kept from one command to the next as a served arm is
    (and on its clock: simulated unless it was made on another)."""
    from busarm.sim.spec import SimSpec

    made = SimSpec.build
    monkeypatch.setattr(SimSpec, "build", lambda spec, baudrate=115200:
                        sim if spec.seed == 31337 else made(spec, baudrate))
    return IN_PROCESS_PORT


def process_env(env: dict[str, str | None]) -> dict[str, str]:
    """``env`` (None: unset) as the whole environment of a process: this one's, with
    ``env`` over it."""
    base = {k: v for k, v in os.environ.items() if k not in env}
    return {**base, **{k: v for k, v in env.items() if v is not None},
            "PYTHONUNBUFFERED": "1"}


def not_crashed(result: Result) -> None:
    """No exception but the exit's (click's runner keeps the traceback a process would
    print)."""
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        "".join(traceback.format_exception(*result.exc_info)) if result.exc_info else "")
    assert "Traceback" not in result.stdout + result.stderr


# tests/with_lerobot need LeRobot, which lives in its own environment (`make lerobot`):
# `make test` runs them there, beside this suite; here they are not collected.
collect_ignore = [] if importlib.util.find_spec("lerobot") else ["with_lerobot"]
