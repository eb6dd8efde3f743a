"""Exit codes, stops and messages that say what is true (issue 13, third trial's items 8-10,
12, 13, 15 (error style) and 17).

- A command that did not do its job exits 1 after its whole output: ``pick-sort`` with a
  block that failed (a block skipped for a reason it gives does not count), a benchmark
  that prints FAIL (its JSON too). Ctrl+C is 130 wherever a command is interrupted
  (``motor``, ``actions record``: the frames taken are still written), the input ending at
  a question is bad input (2), and a reader of stdout that goes away ends the command
  quietly with 141, saying only what the servos were left doing if it stopped them.
- A read with no valid reply says what came back: damaged or cut-short replies, or
  nothing on a line that lately delivered replies late or damaged, not "no servo answers".
- ``monitor`` only reads: its Ctrl+C sends nothing; ``motor ID stop`` leaves a limp servo
  limp and says a stop outside the servo's angle limits.
- ``pick-sort`` says "out of reach" of a block beyond the gripper's reach, and skips it.

The CLI runs as subprocesses where signals, pipes, stdin or a process's exit code are the
point (those that need the simulated servos' truth serve them on a real pseudo-terminal, in
wall-clock time, with a generous reply margin), else in this process through click's
runner, on simulated servos of the test's own on a simulated clock (``in_process``).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner, Result

from busarm.bus.driver import ServoBus
from busarm.cli.main import cli
from busarm.clock import WALL_CLOCK
from busarm.protocol import Command, ServoMode
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.spec import SimSpec
from busarm.sim.transport import SimTransport
from conftest import (
    PTY_MARGIN_S,
    ListeningSim,
    in_process_port,
    keep_twin_calibration,
    sigint_and_wait,
)

MARGIN = ("--timeout-margin-ms", "200")
"""For a command at a pty served in wall-clock time, on a computer that may be busy: a
reply heard late is not what these tests are about."""

FAR1 = {"format": "busarm.scene", "version": 1, "seed": 3,
        "table": {"x_min_mm": -200.0, "x_max_mm": 420.0, "y_min_mm": -400.0,
                  "y_max_mm": 400.0},
        "blocks": [{"color": "red", "x_mm": 380, "y_mm": 0, "yaw_deg": 0, "size_mm": 30,
                    "mass_g": 20}],
        "bins": [{"color": "red", "x_mm": 66.69, "y_mm": 183.24, "size_mm": 90.0,
                  "wall_mm": 12.0},
                 {"color": "green", "x_mm": 66.69, "y_mm": -183.24, "size_mm": 90.0,
                  "wall_mm": 12.0},
                 {"color": "blue", "x_mm": -66.69, "y_mm": 183.24, "size_mm": 90.0,
                  "wall_mm": 12.0}]}
"""A red block at x = 380 mm, beyond the gripper's reach (the third trial's far1.json)."""


PTY_REASON = ("a command as its own process at simulated servos served on a pty, in "
              "wall-clock time")


def in_process(monkeypatch: pytest.MonkeyPatch, sim: SimBus) -> str:
    """The port by which commands run in this process (click's runner) open ``sim``, the
    test's own simulated servos (on their simulated clock), kept from one command to the
    next as a served arm is."""
    url = in_process_port(monkeypatch, sim)
    return url


def _serve(ids: tuple[int, ...]) -> Iterator[tuple[str, ListeningSim]]:
    sim = ListeningSim.with_ids(ids, timing=WireTiming(enabled=False), clock=WALL_CLOCK)
    assert isinstance(sim, ListeningSim)
    server = PtyServer(sim)
    yield server.start(), sim
    server.stop()


@pytest.fixture
def pty_arm() -> Iterator[tuple[str, ListeningSim]]:
    """The arm's six simulated servos on a real pseudo-terminal (wall-clock time), for a
    command run as its own process."""
    yield from _serve((1, 2, 3, 4, 5, 10))


@pytest.fixture
def wheel(monkeypatch: pytest.MonkeyPatch) -> tuple[str, ListeningSim]:
    """One simulated servo, ID 7 (a wheel, not the arm's), for commands in this process:
    its port, and its simulated servo."""
    sim = ListeningSim.with_ids((7,), timing=WireTiming(enabled=False))
    assert isinstance(sim, ListeningSim)
    return in_process(monkeypatch, sim), sim


@pytest.fixture(scope="module")
def home(tmp_path_factory: pytest.TempPathFactory, twin_calibration: tuple[Path, Path]
         ) -> Iterator[dict[str, str]]:
    """The environment of the commands: their own config and runtime folders (the twin's
    camera calibration kept there, as a first pick-sort keeps it, for the next commands)."""
    root = tmp_path_factory.mktemp("home")
    keep_twin_calibration(root / "config", twin_calibration)
    env = {"XDG_CONFIG_HOME": str(root / "config"), "XDG_RUNTIME_DIR": str(root / "run"),
           "BUSARM_RUNTIME_DIR": str(root / "run"), "COLUMNS": "200",
           "PYTHONUNBUFFERED": "1"}
    saved = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    os.environ.pop("BUSARM_PORT", None)
    yield {**os.environ}
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


def run(*args: str, port: str | None = None, input: str | None = None,
        env: dict[str, str | None] | None = None) -> Result:
    """``busarm ARGS`` in this process (``env``: variables set, or unset by None)."""
    return CliRunner(mix_stderr=False).invoke(
        cli, [*(("--port", port) if port else ()), *args], input=input, env=env)


def busarm(*args: str, env: dict[str, str] | None = None,
           **options: Any) -> subprocess.Popen[str]:
    """``python -m busarm ARGS`` with the default SIGINT (background test runs start
    children with SIGINT ignored)."""
    options.setdefault("stdout", subprocess.PIPE)
    options.setdefault("stderr", subprocess.PIPE)
    return subprocess.Popen(
        [sys.executable, "-m", "busarm", *args], text=True, env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL), **options)


def finished(*args: str, env: dict[str, str] | None = None,
             timeout_s: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "busarm", *args], capture_output=True,
                          text=True, env=env, timeout=timeout_s, stdin=subprocess.DEVNULL)


def wait_for(stream: Any, text: str, proc: subprocess.Popen[str]) -> list[str]:
    """Lines of ``stream`` up to the first with ``text`` (the process must still run)."""
    lines: list[str] = []
    while not lines or text not in lines[-1]:
        line = stream.readline()
        assert line or proc.poll() is None, (lines, proc.communicate())
        lines.append(line)
    return lines



def ctrl_c(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    return sigint_and_wait(proc, 30)


def one_error(result: Result | subprocess.CompletedProcess[str], code: int) -> str:
    """Exactly one line on stderr, no traceback, and exit code ``code``."""
    got = result.exit_code if isinstance(result, Result) else result.returncode
    assert got == code, (got, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stdout + result.stderr, result.stderr
    return lines[0]


# ---------------------------------------------------------------------- a job not done


def test_a_block_beyond_reach_is_skipped_as_out_of_reach_and_the_run_exits_0(
        home: dict[str, str], tmp_path: Path) -> None:
    scene = tmp_path / "far1.json"
    scene.write_text(json.dumps(FAR1))
    result = run("pick-sort", "--scene", str(scene), "--report", str(tmp_path / "r"),
                 env={"XDG_CONFIG_HOME": home["XDG_CONFIG_HOME"]})  # the twin's calibration
    assert result.exit_code == 0, result.stderr
    row = next(line for line in result.stdout.splitlines() if line.startswith("red"))
    # Seen only in part (cut by the picture's edge, even facing it): where it may be is
    # beyond the farthest grasp on its bearing, and it says so, with both distances.
    found = re.search(r"skipped: out of reach \((\d+) mm from the base.*; reach (\d+) mm\)",
                      row)
    assert found is not None, row
    assert 340 < int(found[1]) < 400 and 300 < int(found[2]) < 380, row
    assert "not seen whole" not in result.stdout + result.stderr
    assert "sorted 0, failed 0, skipped 1" in result.stdout
    data = json.loads((tmp_path / "r" / "report.json").read_text())
    assert data["blocks"][0]["outcome"] == "skipped"


def test_a_block_that_failed_makes_pick_sort_exit_1_after_its_report(
        home: dict[str, str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        twin_calibration: tuple[Path, Path]) -> None:
    from busarm.apps.pick_sort.sorter import PickSorter

    keep_twin_calibration(Path(os.environ["XDG_CONFIG_HOME"]), twin_calibration)  # this test's
    def missed(self: PickSorter, target: Any, place: str | None = None
               ) -> tuple[bool, str, None, Any]:
        return False, "the test's grasp missed", None, self._plan(target)

    monkeypatch.setattr(PickSorter, "pick_and_place", missed)
    report = tmp_path / "r"
    result = run("pick-sort", "--seed", "1", "--blocks", "1", "--report", str(report))
    assert result.exit_code == 1, (result.stdout, result.stderr)
    errors = [x for x in result.stderr.splitlines() if x.startswith("error")]
    assert len(errors) == 1 and result.stderr.rstrip().endswith(errors[0]), result.stderr
    line = errors[0]
    assert line == (f"error: 1 block(s) failed to be sorted (the reasons above, and in "
                    f"{report}/report.json)"), line
    assert "failed: the test's grasp missed" in result.stdout  # the whole report first
    assert "sorted 0, failed 1, skipped 0" in result.stdout
    assert json.loads((report / "report.json").read_text())["totals"]["failed"] == 1


@pytest.mark.parametrize("as_json", [False, True])
def test_a_benchmark_exits_1_when_it_prints_fail(monkeypatch: pytest.MonkeyPatch,
                                                 as_json: bool) -> None:
    args = ["bench", "ik", "--n", "20", "--batch-n", "20", *(["--json"] if as_json else [])]
    monkeypatch.setenv("COLUMNS", "200")  # the table's cells whole, whatever ran before
    monkeypatch.setattr("busarm.bench.ik.TARGET_SINGLE_US", float("inf"))
    monkeypatch.setattr("busarm.bench.ik.TARGET_BATCH_PER_S", 0.0)
    met = run(*args)
    assert met.exit_code == 0, met.stderr
    monkeypatch.setattr("busarm.bench.ik.TARGET_BATCH_PER_S", 1e15)  # out of reach
    missed = run(*args)
    assert one_error(missed, 1) == "error: 1 target(s) missed: FAIL in the report"
    if as_json:  # the report is printed whole, and is the same JSON
        assert json.loads(missed.stdout).keys() == json.loads(met.stdout).keys()
    else:
        assert ">= 1,000,000,000,000,000/s FAIL" in missed.stdout, missed.stdout


def test_the_vision_benchmark_counts_its_own_fail(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("busarm.bench.vision.TARGET_SPEEDUP", 0.0)  # met, however busy
    monkeypatch.setattr("busarm.bench.vision.TARGET_CLUTTER_FPS", 0.0)  # met, however busy
    monkeypatch.setattr("busarm.bench.vision.TARGET_LOCATE_FPS", 1e12)  # out of reach
    result = run("bench", "vision", "--pictures", "1", "--seconds", "0.5")
    assert one_error(result, 1) == "error: 1 target(s) missed: FAIL in the report"
    assert "FAIL >= 1e+12" in result.stdout, result.stdout


# ---------------------------------------------------------------------- interrupted, EOF


@pytest.mark.wallclock("Ctrl+C to a command as its own process, while it turns")
def test_an_interrupted_motor_stops_and_exits_130(home: dict[str, str]) -> None:
    # pace=1: the 30 s of simulated turning take (at least) 30 s, for Ctrl+C to come first.
    proc = busarm("--port", "sim://?ids=7&pace=1", "motor", "7", "300", "--time", "30",
                  env=home)
    wait_for(proc.stderr, "turning at speed 300", proc)
    code, out, err = ctrl_c(proc)
    assert code == 130, err
    assert out.startswith("servo 7 stopped: back in position mode, holding at "), out
    assert err.strip().splitlines()[-1].startswith("interrupted: all servos stopped"), err
    assert "Traceback" not in err


@pytest.mark.wallclock("Ctrl+C to a command as its own process, while it records")
def test_an_interrupted_recording_writes_its_frames_and_exits_130(
        home: dict[str, str], tmp_path: Path) -> None:
    taught = tmp_path / "taught.d6a"
    # pace=1: a frame every 0.1 s of wall-clock time, as at a real arm.
    proc = busarm("--port", "sim://?pace=1", "actions", "record", str(taught), "--interval",
                  "0.1", env=home)
    wait_for(proc.stderr, "frame 3:", proc)
    code, out, err = ctrl_c(proc)
    assert code == 130, err
    frames = int(re.search(r"wrote (\d+) frames to ", out)[1])  # type: ignore[index]
    assert frames >= 3 and taught.exists()
    assert err.strip().splitlines()[-1].startswith(f"interrupted after frame {frames}: "), err
    shown = run("actions", "show", str(taught))
    assert shown.exit_code == 0 and f"{frames} frames" in shown.stdout, shown.stderr


@pytest.mark.wallclock("Ctrl+C to a command as its own process, waiting on its stdin")
def test_a_recording_interrupted_before_any_frame_writes_nothing_and_exits_130(
        home: dict[str, str], tmp_path: Path) -> None:
    taught = tmp_path / "taught.d6a"
    proc = busarm("--port", "sim", "actions", "record", str(taught), env=home,
                  stdin=subprocess.PIPE)  # Enter captures: none is pressed
    wait_for(proc.stderr, "Enter captures", proc)
    code, out, err = ctrl_c(proc)
    assert code == 130, err
    assert err.strip().splitlines()[-1].startswith(
        "interrupted before any frame: nothing written: "), err
    assert not taught.exists() and out == ""


@pytest.mark.wallclock(PTY_REASON + ": its stdin ends")
def test_the_input_ending_at_a_question_is_bad_input_not_an_interruption(
        pty_arm: tuple[str, ListeningSim], tmp_path: Path) -> None:
    path, sim = pty_arm
    out = tmp_path / "cal.json"
    result = finished("--port", path, *MARGIN, "arm", "calibrate", "--out", str(out))
    assert result.returncode == 2, result.stderr
    assert "Is the arm in that pose?" in result.stderr  # asked, on stderr; then one line:
    line = result.stderr.strip().splitlines()[-1]
    assert [x for x in result.stderr.splitlines() if x.startswith("error")] == [line]
    assert line.startswith("error: the input ended (end of file) before the question was "
                           "answered: run it at a terminal, or with --yes: "), line
    assert "interrupted" not in line
    assert line.endswith("servos 1-5, 10 limp (torque off)"), line  # as it was made
    assert not out.exists()
    moves = {Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE, Command.MOVE_START,
             Command.ANGLE_OFFSET_ADJUST, Command.ANGLE_OFFSET_WRITE}
    assert not moves & set(sim.writes()), sim.writes()  # nothing moved, nothing stored


@pytest.mark.wallclock("Ctrl+C to a command as its own process")
def test_vision_detect_interrupted_says_nothing_of_servos(home: dict[str, str]) -> None:
    proc = busarm("vision", "detect", "--camera", "twin", "--frames", "0", env=home)
    wait_for(proc.stdout, "block(s)", proc)
    code, _, err = ctrl_c(proc)
    assert code == 130, err
    assert err.strip().splitlines() == ["interrupted"], err


# ---------------------------------------------------------------------- a closed pipe


@pytest.mark.wallclock("a command as its own process whose stdout's reader goes away")
def test_a_reader_that_goes_away_ends_the_command_quietly(home: dict[str, str]) -> None:
    proc = busarm("vision", "detect", "--camera", "twin", "--frames", "0", env=home)
    assert proc.stdout is not None
    for _ in range(3):  # what `| head -3` reads
        assert proc.stdout.readline()
    proc.stdout.close()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 141, err  # 128 + SIGPIPE, as a shell reports Unix tools
    assert err == "", err  # no message, no traceback


@pytest.mark.wallclock(PTY_REASON + ": its stdout has no reader")
def test_a_closed_pipe_that_stopped_the_arm_says_so(pty_arm: tuple[str, ListeningSim],
                                                    home: dict[str, str]) -> None:
    path, sim = pty_arm
    read_end, write_end = os.pipe()
    os.close(read_end)  # no reader, before it prints "moving ..."
    proc = busarm("--port", path, *MARGIN, "move", "1", "100", "--time", "5", "--wait",
                  env=home, stdout=write_end)
    os.close(write_end)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 141, err
    assert err.strip().splitlines() == [
        "error: the output was closed (broken pipe): all servos stopped (MOVE_STOP); "
        "servo 1 holding position (torque on)"], err
    assert Command.MOVE_STOP in sim.writes() and sim.servo(1).is_loaded


# ---------------------------------------------------------------------- bus faults


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_lost_bytes_are_not_called_a_missing_servo(seed: int) -> None:
    line = one_error(run("arm", "move-to", "200", "0", "40",
                         port=f"sim://?drop=0.05&seed={seed}"), 1)
    assert not line.startswith("error: no servo answers"), line
    assert ("came back damaged" in line or "came back cut short" in line
            or "this line is unreliable" in line or "answered on this bus before" in line), line
    assert "cabl" in line, line  # what to check (cabling, a cable and its connectors)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_late_replies_are_said_late(seed: int) -> None:
    line = one_error(run("arm", "move-to", "200", "0", "40",
                         port=f"sim://?late=0.3&seed={seed}"), 1)
    assert "this line is unreliable" in line and "arrived after its deadline" in line, line
    assert "--timeout-margin-ms" in line, line


def test_a_servo_that_is_not_there_is_still_said_so() -> None:
    assert one_error(run("arm", "pose", port="sim://?ids=2,3,4,5,10"), 1) == \
        "error: no servo answers at ID 1"


def test_garbled_replies_are_said_damaged_by_the_driver() -> None:
    said: list[str] = []
    answered = False
    with ServoBus.open(SimSpec(corrupt=0.2, seed=5), retries=2) as bus:
        for _ in range(40):
            try:
                bus.read_position_deg(1)
                answered = True
            except Exception as exc:  # every kind is looked at
                if answered:  # once heard, never "did not answer" alone
                    said.append(str(exc))
    assert said, "no read failed: the fault rate is too low to test anything"
    assert all("did not answer" not in s or "this line is unreliable" in s
               or "answered on this bus before" in s for s in said), said
    assert any("came back damaged" in s for s in said), said


# ---------------------------------------------------------------------- what stops say


@pytest.mark.wallclock(PTY_REASON + ", Ctrl+C to it")
def test_monitor_only_reads_and_its_ctrl_c_sends_nothing(
        pty_arm: tuple[str, ListeningSim], home: dict[str, str]) -> None:
    path, sim = pty_arm
    # A slow move (30 s: still under way however long the monitor takes to start).
    assert run("move", "1", "-40", "--time", "30", *MARGIN, port=path).exit_code == 0
    with ServoBus.open(path, echo="off", timeout_margin_s=PTY_MARGIN_S) as bus:
        bus.read_id(1)  # answered after the move was taken
    sim.heard.clear()
    proc = busarm("--port", path, *MARGIN, "monitor", "--ids", "1", "--interval", "0.05",
                  env=home)
    wait_for(proc.stdout, "refresh 2", proc)
    code, _, err = ctrl_c(proc)
    assert code == 130, err
    assert err.strip().splitlines() == ["interrupted: nothing was written to the servos"]
    assert sim.writes() == []  # no MOVE_STOP: the move of "another program" goes on
    servo = sim.servo(1)  # the servo's model, 0.1 s on: still on its way
    now = time.monotonic()
    servo.advance(now)
    before = servo.position_pulses
    servo.advance(now + 0.1)
    assert servo.position_pulses < before


def test_motor_stop_leaves_a_limp_servo_limp_and_says_where_it_is(
        wheel: tuple[str, ListeningSim]) -> None:
    path, sim = wheel
    with ServoBus(SimTransport(sim), echo="off") as bus:
        bus.set_motor_speed(7, 300)
        bus.set_torque(7, False)  # made limp while turning
        assert not bus.read_torque(7)  # (the simulator has taken the writes)
    servo = sim.servo(7)
    servo.move_by_hand(-150, sim.clock.now())  # turned past the angle limits
    result = run("motor", "7", "stop", port=path)
    assert result.exit_code == 0, result.stderr
    said = " ".join(result.stdout.split())
    assert said.startswith("servo 7 stopped: back in position mode at -156.0 deg, limp "
                           "(torque off, left off; `busarm torque on 7` makes it hold)"), said
    assert ("outside its angle limits -120.0..+120.0 deg: a move within them brings it back "
            "(`busarm move 7 0`)") in said, said
    assert not servo.is_loaded  # not energised
    with ServoBus(SimTransport(sim), echo="off") as bus:
        assert bus.read_mode(7).mode == ServoMode.POSITION and bus.read_mode(7).motor_speed == 0
    assert run("move", "7", "0", "--time", "0.5", "--wait", port=path).exit_code == 0


def test_a_stop_within_the_limits_says_nothing_of_them(
        wheel: tuple[str, ListeningSim]) -> None:
    path, sim = wheel
    with ServoBus(SimTransport(sim), echo="off") as bus:
        bus.move_deg(7, 10.0, 0.0)  # torque on, holding at +10
        bus.set_motor_speed(7, 0)
    out = " ".join(run("motor", "7", "stop", port=path).stdout.split())
    assert out.startswith("servo 7 stopped: back in position mode, holding at +"), out
    assert "limits" not in out


# ---------------------------------------------------------------------- smaller ones


def test_a_bare_gripper_gap_is_millimetres() -> None:
    path = "sim"
    bare, with_unit = run("arm", "gripper", "25", port=path), run("arm", "gripper", "25mm",
                                                                  port=path)
    assert bare.exit_code == with_unit.exit_code == 0, bare.stderr
    assert bare.stdout == with_unit.stdout and "25.1 mm apart" in bare.stdout
    line = one_error(run("arm", "gripper", "25cm", port=path), 2)
    assert "'25cm' is not open, close or a gap between the fingers in mm such as 25 or " \
        "25mm" in line


def test_an_offset_rounded_to_the_servos_steps_says_so() -> None:
    path = "sim"
    out = run("offset", "2", "0.1", port=path).stdout
    assert out.startswith("servo 2 angle offset: +0.00 deg (rounded from +0.1 deg to the "
                          "servo's steps of 0.24 deg; not saved"), out
    exact = run("offset", "2", "0.48", port=path).stdout
    assert "+0.48 deg (not saved" in exact and "rounded" not in exact


def test_a_missing_adapter_is_said_before_what_the_job_needs(home: dict[str, str]) -> None:
    line = one_error(run("--port", "/dev/ttyUSB9", "pick-sort"), 1)
    assert line.startswith("error: cannot open '/dev/ttyUSB9': it does not exist"), line
    env: dict[str, str | None] = {"BUSARM_PORT": "/dev/ttyUSB9"}
    line = one_error(run("scan", env=env), 1)
    assert line.endswith("; the port came from $BUSARM_PORT"), line
    line = one_error(run("scan", "--port", "/dev/ttyUSB8", env=env), 1)
    assert "/dev/ttyUSB8" in line and "BUSARM_PORT" not in line, line


def test_a_bin_for_a_colour_not_sorted_is_said(home: dict[str, str]) -> None:
    line = one_error(run("pick-sort", "--bins", "purple=1,2"), 2)
    assert line == ("error: --bins has no bin for the colours to sort (red, green, blue; "
                    "--colors chooses them): purple is not one of them; give COLOUR=X,Y "
                    "for at least one of them"), line
    result = run("--port", "/dev/ttyUSB9", "pick-sort", "--bins", "purple=1,2;red=3,4")
    assert result.stderr.splitlines()[0] == (
        "warning: --bins purple: not one of the colours to sort (red, green, blue; --colors "
        "chooses them); no block goes there"), result.stderr


def test_sorting_rules_refuse_bad_options_before_anything_opens(home: dict[str, str]) -> None:
    line = one_error(run("pick-sort", "--by", "size", "--bins", "red=60,180"), 2)
    assert line == ("error: sorting by size needs a bin named as a size class (small, "
                    "medium, large); bins given: red (--bins NAME=X,Y;...)"), line
    line = one_error(run("pick-sort", "--tag-places", "0=red"), 2)
    assert line == "error: --tag-places is for --by tag (not --by color)", line
    line = one_error(run("pick-sort", "--by", "tag", "--tag-places", "0,x=red"), 2)
    assert line == ("error: tag places '0,x=red': 'x' is not a tag id or a range of them "
                    "(0..586)"), line
    line = one_error(run("pick-sort", "--by", "size", "--blocks", "3"), 2)
    assert line.startswith("error: --blocks 3: the seeded table for --by size has 4-6"), line


@pytest.mark.wallclock("a network camera refused at once, in wall-clock time")
def test_a_refused_camera_stream_is_said_refused_at_once() -> None:
    # (That a command as its own process says it in one line, no OpenCV noise on its
    # stderr: test_cli_additions' test_camera_stream_that_fails_gives_one_error_in_time.)
    start = time.monotonic()
    line = one_error(run("vision", "detect", "--camera", "http://127.0.0.1:1/video"), 1)
    assert line == ("error: cannot open camera stream http://127.0.0.1:1/video: the "
                    "connection was refused (nothing listens on 127.0.0.1:1)"), line
    assert time.monotonic() - start < 15


def test_poses_need_no_bus_and_say_nothing_of_one(home: dict[str, str]) -> None:
    result = run("arm", "poses", "--json")
    assert result.exit_code == 0 and result.stderr == "", result.stderr
    assert {p["name"] for p in json.loads(result.stdout)["poses"]} >= {"home", "look"}


def test_alarm_names_are_listed_with_spaces() -> None:
    assert run("led", "1", port="sim").stdout.strip() == \
        "servo 1: LED on, flashes on: over-temperature, over-voltage, stalled"


def test_errors_are_written_one_way() -> None:
    ours = one_error(run("limits", "1", "--angle", "100", "50", port="sim"), 2)
    clicks = one_error(run("limits", "1", "--temp", "200", port="sim"), 2)
    assert ours == "error: Invalid value for '--angle': min 100 must be below max 50 deg"
    assert clicks == "error: Invalid value for '--temp': 200 is not in the range 50<=x<=100"


def test_decode_names_commands_as_encode_takes_them() -> None:
    encoded = run("encode", "MOVE_TIME_WRITE", "1", "500", "1000")
    assert encoded.exit_code == 0, encoded.stderr
    decoded = run("decode", *encoded.stdout.split())
    assert "request MOVE_TIME_WRITE to id 1" in decoded.stdout, decoded.stdout
    assert "SERVO_" not in decoded.stdout
