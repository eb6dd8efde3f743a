"""What the command line says about the servos is what is true, read back (issue 13).

A refusal before any write says nothing about stopping (and writes nothing); a "no" at
a prompt is not an interruption; an error or a Ctrl+C after a write says each servo's
torque as the servo reports it (holding position with torque on, limp with it off);
pick-sort's stop is one line that says what the gripper really holds, and its report
stays valid JSON; a Ctrl+C at any moment, even while the program loads, ends with one
line and exit code 130. Each claim is checked against the simulated servos (or the
twin's ground truth), not only against the text.

The commands run in this process (click's runner) on simulated servos of the test's own,
on their simulated clock (``sim_arm``), or on the twin; a Ctrl+C is a real SIGINT to a
real process (``busarm``), at servos served on a real pseudo-terminal (``pty_arm``).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, cast

import pytest
from click.testing import CliRunner, Result

from busarm.bus.driver import ServoBus
from busarm.cli import stopping
from busarm.cli.main import cli
from busarm.clock import WALL_CLOCK
from busarm.errors import ConfigError, MotionTimeoutError
from busarm.protocol import Command
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.spec import SimSpec
from busarm.sim.transport import SimTransport
from conftest import PTY_MARGIN_S, ListeningSim, in_process_port, sigint_and_wait, wait_for

VENDOR = Path(__file__).resolve().parents[1] / "data" / "vendor" / "arm_action_1.d6a"
ARM_IDS = (1, 2, 3, 4, 5, 10)
ENV = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "120"}
MARGIN = ("--timeout-margin-ms", "200")
"""For a command at a pty (wall-clock time) on a computer that may be busy: a reply heard
late is not what these tests are about."""
SIGINT_REASON = "Ctrl+C (SIGINT) to a real process"


@pytest.fixture
def sim_arm(monkeypatch: pytest.MonkeyPatch) -> tuple[str, ListeningSim]:
    """The arm's six simulated servos (no wire timing) on their simulated clock: the port
    commands open them by, and the servos."""
    sim = ListeningSim.with_ids(timing=WireTiming(enabled=False))
    assert isinstance(sim, ListeningSim)
    return in_process_port(monkeypatch, sim), sim


@pytest.fixture
def pty_arm() -> Iterator[tuple[str, ListeningSim]]:
    """The arm's six simulated servos on a real pseudo-terminal (no wire timing), in
    wall-clock time."""
    sim = ListeningSim.with_ids(timing=WireTiming(enabled=False), clock=WALL_CLOCK)
    assert isinstance(sim, ListeningSim)
    server = PtyServer(sim)
    yield server.start(), sim
    server.stop()


def run(*args: str, port: str, input: str | None = None) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", port, *args], input=input)


def one_line(result: Result, code: int) -> str:
    """Exactly one line on stderr (no traceback), and exit code ``code``."""
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


def hold(servos: SimBus | str, *ids: int) -> None:
    """Torque on for ``ids``: each holds where it stands (a move there, time 0). The
    simulated servos in this process, or the path of the pty they are served on."""
    with (ServoBus.open(servos, timeout_margin_s=PTY_MARGIN_S) if isinstance(servos, str)
          else ServoBus(SimTransport(servos))) as bus:
        for sid in ids:
            bus.move_pulses(sid, bus.read_position_pulses(sid), 0)


def busarm(*args: str, env: dict[str, str] = ENV) -> subprocess.Popen[str]:
    """``python -m busarm ARGS`` with the default SIGINT (background test runs start
    children with SIGINT ignored)."""
    return subprocess.Popen(
        [sys.executable, "-m", "busarm", *args], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


LOADING_MARK = """\
import os, sys

class _Loading:
    \"\"\"Makes the file $BUSARM_TEST_LOADING as busarm's command line starts to load
    (its first import of busarm.cli: in busarm.__main__.main, which handles a Ctrl+C).\"\"\"

    def find_spec(self, name, path=None, target=None):
        if name == "busarm.cli":
            sys.meta_path.remove(self)
            open(os.environ["BUSARM_TEST_LOADING"], "w").close()
        return None

sys.meta_path.insert(0, _Loading())
"""
"""A ``sitecustomize`` for ``busarm``'s process: how a test knows, on the process's own
terms, that the program has started loading (Python's own start-up before it, tens of ms
idle, far more on a busy computer, is the interpreter's: a Ctrl+C there is Python's)."""


def busarm_loading(tmp_path: Path, *args: str) -> subprocess.Popen[str]:
    """``busarm(*args)``, returned once the program has started to load."""
    (tmp_path / "sitecustomize.py").write_text(LOADING_MARK)
    mark = tmp_path / "loading"
    path = os.pathsep.join(p for p in (str(tmp_path), ENV.get("PYTHONPATH")) if p)
    proc = busarm(*args, env={**ENV, "PYTHONPATH": path, "BUSARM_TEST_LOADING": str(mark)})
    if not wait_for(lambda: mark.exists() or proc.poll() is not None, timeout_s=60):
        proc.kill()
    assert mark.exists(), proc.communicate()
    return proc


def ctrl_c(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    return sigint_and_wait(proc, 20)


# ---------------------------------------------------------------------- refusals, prompts


def test_refusals_before_any_write_say_nothing_about_stopping(
        sim_arm: tuple[str, ListeningSim]) -> None:
    path, sim = sim_arm
    cases = [(["set-id", "1", "2"], "ID 2 is already taken"),
             (["arm", "move-joints", "0", "60", "0", "-90", "0"], "shoulder_pitch"),
             (["arm", "move-to", "200", "0", "-50"], "below the table"),
             (["actions", "play", str(VENDOR), "--speed-scale", "10"], "faster than")]
    for args, why in cases:
        sim.heard.clear()
        result = run(*args, port=path)
        assert result.exit_code in (1, 2), (args, result.stderr)
        line = one_line(result, result.exit_code)
        assert line.startswith("error: ") and why in line, line
        for claim in ("stop", "holding", "torque", "MOVE_STOP"):
            assert claim not in line, line
        assert sim.writes() == [], (args, sim.writes())  # not even a stop
    assert not any(sim.servo(sid).is_loaded for sid in ARM_IDS)


def test_declining_calibrate_is_not_an_interruption_and_changes_nothing(
        sim_arm: tuple[str, ListeningSim], tmp_path: Path) -> None:
    path, sim = sim_arm
    hold(sim, *ARM_IDS)
    out = tmp_path / "cal.json"
    for answers in ("n\n", "y\nn\n"):  # no at the first question, then at the second
        sim.heard.clear()
        result = run("arm", "calibrate", "--out", str(out), port=path, input=answers)
        assert result.exit_code == 0, result.stderr
        assert "interrupted" not in result.stdout + result.stderr
        assert "calibration declined: nothing written" in result.stdout
        # It was limp for the measurement; it holds where it stands again, as it says.
        assert "servos 1-5, 10 holding position (torque on)" in result.stdout
        assert all(sim.servo(sid).is_loaded for sid in ARM_IDS)
        assert not out.exists()
        offsets = {Command.ANGLE_OFFSET_ADJUST, Command.ANGLE_OFFSET_WRITE}
        assert not offsets & set(sim.heard), sim.heard


# ---------------------------------------------------------------------- errors, Ctrl+C


def test_an_error_after_a_move_says_stopped_and_holding(
        sim_arm: tuple[str, ListeningSim], monkeypatch: pytest.MonkeyPatch) -> None:
    path, sim = sim_arm

    def late(*args: object, **kwargs: object) -> None:
        raise MotionTimeoutError("servo 1 is late")

    monkeypatch.setattr(ServoBus, "wait_until_reached", late)
    line = one_line(run("move", "1", "100", "--time", "5", "--wait", port=path), 1)
    assert line == ("error: servo 1 is late: all servos stopped (MOVE_STOP); "
                    "servo 1 holding position (torque on)")
    servo = sim.servo(1)
    assert servo.is_loaded
    sim.advance()
    held = servo.position_pulses
    sim.clock.sleep(0.1)
    sim.advance()
    assert servo.position_pulses == held < 900  # stopped on its way, and holding there


def test_an_error_while_the_arm_is_limp_says_limp(
        sim_arm: tuple[str, ListeningSim], monkeypatch: pytest.MonkeyPatch) -> None:
    from busarm.cli import arm_cmds

    path, sim = sim_arm
    hold(sim, *ARM_IDS)

    def fails(*args: object, **kwargs: object) -> None:
        raise ConfigError("the readings make no sense")

    monkeypatch.setattr(arm_cmds, "solve_calibration", fails)
    line = one_line(run("arm", "calibrate", "--yes", port=path), 2)
    # Calibration turned the torque off: stopped, but limp, and it says so.
    assert line == ("error: the readings make no sense: all servos stopped (MOVE_STOP); "
                    "servos 1-5, 10 limp (torque off)")
    assert not any(sim.servo(sid).is_loaded for sid in ARM_IDS)


@pytest.mark.wallclock(SIGINT_REASON + ", a monitor at servos served on a real pty")
def test_monitor_ctrl_c_sends_and_says_nothing_of_stopping(
        pty_arm: tuple[str, ListeningSim]) -> None:
    path, sim = pty_arm
    hold(path, 2)  # servo 1 stays limp, as the simulated servos start
    # The hold's move, its last write, has reached the servos: nothing more will come.
    assert wait_for(lambda: sim.servo(2).is_loaded)
    sim.heard.clear()
    monitor = busarm("--port", path, *MARGIN, "monitor", "--ids", "1,2", "--interval", "0.05")
    assert monitor.stdout is not None
    while "refresh 2" not in monitor.stdout.readline():
        assert monitor.poll() is None, monitor.communicate()
    code, _, err = ctrl_c(monitor)
    assert code == 130, err  # Ctrl+C is how a monitor ends, and an interruption
    assert err.strip().splitlines() == ["interrupted: nothing was written to the servos"]
    assert sim.writes() == []  # it only read: not even a stop
    assert not sim.servo(1).is_loaded and sim.servo(2).is_loaded


@pytest.mark.wallclock(SIGINT_REASON + ", moving servos served on a real pty")
def test_ctrl_c_during_a_move_exits_130_with_one_true_line(
        pty_arm: tuple[str, ListeningSim]) -> None:
    path, sim = pty_arm
    move = busarm("--port", path, *MARGIN, "move", "1", "100", "--time", "5", "--wait")
    assert move.stdout is not None
    assert "moving" in move.stdout.readline()
    code, _, err = ctrl_c(move)
    assert code == 130, err
    assert err.strip().splitlines() == [
        "interrupted: all servos stopped (MOVE_STOP); servo 1 holding position (torque on)"]
    assert sim.servo(1).is_loaded


@pytest.mark.wallclock("SIGTERM to a real process, moving servos served on a real pty")
def test_sigterm_during_a_move_stops_as_ctrl_c_does_and_exits_143(
        pty_arm: tuple[str, ListeningSim]) -> None:
    """What `timeout`, systemd and container runtimes send: the servos held, one line
    saying so, 128 + 15."""
    path, sim = pty_arm
    move = busarm("--port", path, *MARGIN, "move", "1", "100", "--time", "5", "--wait")
    assert move.stdout is not None
    assert "moving" in move.stdout.readline()
    move.send_signal(signal.SIGTERM)
    try:
        _, err = move.communicate(timeout=20)
    finally:
        move.kill()
    assert move.returncode == 143, err
    assert err.strip().splitlines() == [
        "stopped by SIGTERM: all servos stopped (MOVE_STOP); servo 1 holding position "
        "(torque on)"]
    assert sim.servo(1).is_loaded


@pytest.mark.wallclock(SIGINT_REASON + " at a moment of the wall clock, as a person presses it")
@pytest.mark.parametrize("after_s", [0.0, 0.3, 0.6, 1.2])
def test_a_ctrl_c_at_any_moment_is_one_line_and_130(after_s: float, tmp_path: Path) -> None:
    """From while the program loads (about 0.4 s of imports) to the move itself (a 10 s
    move on the wall clock: ``realtime=1``, or the simulated one would be over first),
    ``after_s`` after the program started to load."""
    proc = busarm_loading(tmp_path, "--port", "sim://?realtime=1", *MARGIN, "move", "1",
                          "100", "--time", "10", "--wait")
    time.sleep(after_s)  # the moment of the Ctrl+C: the subject, not a wait for anything
    code, out, err = ctrl_c(proc)
    assert code == 130, (out, err)
    assert "Traceback" not in out + err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0] in ("interrupted: nothing was written to the servos",
                        "interrupted: all servos stopped (MOVE_STOP); servo 1 holding "
                        "position (torque on)"), err
    if after_s == 0.0:  # still loading: no port was even opened
        assert lines[0] == "interrupted: nothing was written to the servos"


# ---------------------------------------------------------------------- pick-sort


def pick_sort(calibration: tuple[Path, Path], report: Path) -> Result:
    return run("pick-sort", "--seed", "3", "--blocks", "5", "--intrinsics",
               str(calibration[0]), "--hand-eye", str(calibration[1]), "--report", str(report),
               port="twin")


def strict_json(path: Path) -> Any:
    """The file's JSON, refusing NaN and Infinity (which JSON does not have)."""
    def refuse(name: str) -> None:
        raise ValueError(f"{path}: {name} is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


def test_pick_sort_ctrl_c_as_the_gripper_opens_says_it_holds_the_block(
        twin_calibration: tuple[Path, Path], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Over the bin, about to let go: the block is still in the fingers, and so it says
    (it used to say "open", the fingers a block's width apart)."""
    from busarm.apps.pick_sort import job as pick_job
    from busarm.arm.arm import Arm
    from busarm.twin.twin import BlockState, Twin

    seen: dict[str, Any] = {}
    on_step, open_gripper = pick_job._Pictures.on_step, Arm.open_gripper

    def watch(self: pick_job._Pictures, step: str) -> None:
        seen["twin"] = getattr(self.camera, "twin", None)
        seen["carried"] = step == "carry"
        on_step(self, step)

    def opening(self: Arm, **kwargs: Any) -> int:
        if seen.get("carried"):  # the release: Ctrl+C before the fingers move
            twin: Twin = seen["twin"]
            seen["truth"], seen["gap_mm"] = twin.blocks(), twin.finger_gap_mm()
            raise KeyboardInterrupt
        return open_gripper(self, **kwargs)

    monkeypatch.setattr(pick_job._Pictures, "on_step", watch)
    monkeypatch.setattr(Arm, "open_gripper", opening)
    report = tmp_path / "report"
    line = one_line(pick_sort(twin_calibration, report), 130)
    truth: list[BlockState] = seen["truth"]
    held = max(truth, key=lambda b: b.z_mm)
    # Lifted off the table (a block on it stands at half its size): in the fingers.
    assert held.z_mm > held.size_mm, truth
    assert line.startswith("interrupted: all servos stopped (MOVE_STOP); servos 1-5, 10 "
                           f"holding position (torque on); the gripper: holding a "
                           f"{held.color} block ("), line
    assert f"; the report so far: {report}/" in line
    data = strict_json(report / "report.json")
    assert data["stopped"] == "interrupted (Ctrl+C)"
    assert data["gripper"].startswith(f"holding a {held.color} block (")
    said_mm = int(data["gripper"].split("(")[1].split(" mm")[0])
    assert abs(said_mm - seen["gap_mm"]) <= 2, (data["gripper"], seen["gap_mm"])
    assert data["totals"]["sorted"] == 0 and data["totals"]["median_cycle_s"] is None


def test_pick_sort_error_mid_run_is_one_line_that_names_the_silent_servo(
        twin_calibration: tuple[Path, Path], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The elbow browns out while a block is lifted: one error line, the others holding,
    the elbow not answering, the gripper holding the block; the report is valid JSON."""
    from busarm.apps.pick_sort import job as pick_job
    from busarm.twin.camera import TwinCamera

    on_step = pick_job._Pictures.on_step

    def brown_out(self: pick_job._Pictures, step: str) -> None:
        on_step(self, step)
        if step == "lift":
            twin = cast(TwinCamera, self.camera).twin
            twin.servos[2].supply_mv = 5000  # servo 3 goes silent (under 6 V)

    monkeypatch.setattr(pick_job._Pictures, "on_step", brown_out)
    report = tmp_path / "report"
    line = one_line(pick_sort(twin_calibration, report), 1)
    assert line.startswith("error: ") and "servo 3" in line, line
    assert ("all servos stopped (MOVE_STOP); servos 1, 2, 4, 5, 10 holding position "
            "(torque on); servo 3 not answering (torque unknown); the gripper: holding a "
            in line), line
    data = strict_json(report / "report.json")
    # A servo heard before that goes quiet: its supply is the first thing to check.
    assert data["gripper"].startswith("holding a ") and data["stopped"].startswith(
        "UnreliableLineError: servo 3 did not answer"), data["stopped"]
    assert "though it answered on this bus before: check its supply" in data["stopped"]
    assert data["totals"]["median_cycle_s"] is None


def test_a_stop_after_the_servos_were_let_go_does_not_say_nothing_was_written(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # A Ctrl+C as a finished job prints its summary comes after the bus closed: what was
    # written must not be denied. (The record is per process: this one's, made fresh, as
    # a new process starts it.)
    monkeypatch.setattr(stopping, "_wrote_before", [])
    monkeypatch.setattr(stopping, "_without_servos", [])
    assert stopping.unwritten_text() == "nothing was written to the servos"
    bus = ServoBus.open(SimSpec())
    with stopping.marking_the_stop(bus, bus):
        bus.set_torque(1, True)
    assert stopping.unwritten_text().startswith("after the command was done with the servos")
