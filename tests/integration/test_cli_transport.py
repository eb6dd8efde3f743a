"""``busarm transport`` through the real CLI (a subprocess, in a folder of its own): the
input it refuses before anything is opened or driven, in one line each, and Ctrl+C while
it explores a twin's arena.

The whole jobs (``transport --arena N`` and ``map build --arena N``, about a minute) run
once, as the README's lines: test_readme_examples checks what they print and write
(its CHECKED rule), as these tests once did on runs of their own.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

SEED = 1
TWIN_PORT = f"board://twin?family=arena&seed={SEED}"


def busarm(*args: str, cwd: Path, timeout_s: float = 240.0,
           env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "busarm", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout_s, env=env)


@pytest.mark.parametrize(("command", "message"), [
    (["transport", "--start", "1,2"],
     "error: --start '1,2': expected X,Y,YAW (m, m, deg), e.g. 0.5,-1.2,90"),
    (["--port", "board://sim", "transport"],
     "error: on a robot, give --map MAP.yaml (made by `busarm map build`) and --points FILE "
     "(where to pick and place)"),
], ids=["two-numbers-for-a-pose", "a-robot-without-map-or-points"])
def test_bad_input_is_one_error_before_anything_is_opened(tmp_path: Path, command: list[str],
                                                          message: str) -> None:
    done = busarm(*command, cwd=tmp_path, timeout_s=60.0)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [message]
    assert done.stdout == ""
    assert list(tmp_path.iterdir()) == []  # no report, no map: nothing was done


@pytest.mark.wallclock("Ctrl+C to a transport process while it explores")
def test_a_twin_on_a_board_port_needs_no_map_or_points(tmp_path: Path) -> None:
    """The twin is an arena: with no map it explores (stopped by Ctrl+C once under way)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "--port", TWIN_PORT, "transport"], cwd=tmp_path,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stderr is not None
        assert proc.stderr.readline() == "no map given: exploring the arena first\n"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("interrupted: "), err


@pytest.mark.slow  # it explores the arena first (about 10 s)
@pytest.mark.wallclock("SIGTERM to a transport process while it drives to the block")
def test_sigterm_while_it_drives_keeps_the_report_and_stops_the_robot(
        tmp_path: Path, twin_config_home: Path) -> None:
    """What `timeout`, systemd and container runtimes send (issue 30): exit 143 and one
    line (the servos' torque read back after the stop, the wheels stopped, where the
    report is); the report so far says which phase it stopped in, and why."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "transport", "--arena", str(SEED), "--report",
         "out"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1", BUSARM_RUNTIME_DIR=str(tmp_path / "run")))
    try:
        assert proc.stderr is not None
        said = []
        for line in proc.stderr:  # the map made, the arm stowed, localised: then it drives
            said.append(line)
            if line.startswith("drive to pick"):
                break
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 143, [*said, err]
    assert out == "" and err.splitlines() == [
        "stopped by SIGTERM: all servos stopped (MOVE_STOP); servos 1-5, 10 holding position "
        "(torque on); the wheels stopped; the report so far: out/report.json"]
    data = json.loads((tmp_path / "out" / "report.json").read_text())
    assert not data["delivered"] and data["why"] == "stopped by SIGTERM"
    assert [(p["name"], p["ok"], p["detail"]) for p in data["phases"]] == [
        ("stow the arm", True, ""), ("localise", True, ""),
        ("drive to pick", False, "stopped by SIGTERM")]
    assert (tmp_path / "out" / "map.yaml").exists()  # the map it explored, kept
