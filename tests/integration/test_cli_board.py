"""The commands through the controller board, as a user runs them: ``busarm sim serve
--board`` and ``twin serve --board`` as processes of their own (the board on a real pty),
the commands at them in this process through click's runner (by the board's port, or
found without --port), ``busarm board info | beep``, and what the board cannot do said as
one error (those on ``board://sim``, the simulated board in this process).

Each test has its own config and runtime folders (XDG_CONFIG_HOME, XDG_RUNTIME_DIR,
BUSARM_RUNTIME_DIR under tmp_path), so nothing here sees a server another test or a
developer runs.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from busarm.cli.main import cli
from conftest import not_crashed, process_env, sigint_and_wait

SERVED = pytest.mark.wallclock("commands in this process at a board served on a pty by "
                               "another process")
SERVER = pytest.mark.slow  # a server started as its own process (a few seconds to start)

BOARD_PORT = re.compile(r"board:///dev/pts/\d+")
NOT_READABLE = "n/a (the controller board cannot read it)"

Env = dict[str, str | None]
"""Variables for a command in this process: None removes one for the call."""


@pytest.fixture
def env(tmp_path: Path) -> Env:
    """A user with no --port, BUSARM_PORT or arm options set (None: removed), and folders
    of this test's own; with a generous reply margin, as the README says to set on a busy
    computer (the served board answers in wall-clock time beside the rest of the suite).
    The commands run in this process with these set for the call only (click's runner);
    a server's process gets them on top of this one's environment (``process_env``)."""
    runtime = tmp_path / "xdg-run"
    runtime.mkdir(mode=0o700)
    return {"BUSARM_PORT": None, "BUSARM_ARM": None, "BUSARM_CALIBRATION": None,
            "XDG_CONFIG_HOME": str(tmp_path / "config"), "XDG_RUNTIME_DIR": str(runtime),
            "BUSARM_RUNTIME_DIR": str(tmp_path / "run"), "COLUMNS": "200",
            "BUSARM_TIMEOUT_MARGIN_MS": "200"}




def busarm(*args: str, env: Env) -> Result:
    """``busarm ARGS`` in this process (click's runner), in ``env``."""
    return CliRunner(mix_stderr=False).invoke(cli, list(args), env=env, prog_name="busarm")




def ok(result: Result) -> str:
    not_crashed(result)
    assert result.exit_code == 0, (result.exit_code, result.stdout, result.stderr)
    return result.stdout


def one_error(result: Result, code: int) -> str:
    not_crashed(result)
    assert result.exit_code == code, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]


def row(table: str, name: str) -> str:
    """The value column of the table row ``name`` (rich's box-drawn tables)."""
    found = re.search(rf"│ {re.escape(name)}\s*│ (.*?)\s*│", table)
    assert found, f"no row {name!r} in:\n{table}"
    return found.group(1)


class Server:
    """``busarm sim|twin serve --board`` in its own process; its first stdout line is the
    port. Stopped as a user stops it: Ctrl+C, exit code 0."""

    def __init__(self, args: list[str], env: Env) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "busarm", *args], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, env=process_env(env),
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        assert self.proc.stdout is not None
        self.port = self.proc.stdout.readline().strip()
        assert BOARD_PORT.fullmatch(self.port), self.proc.communicate(timeout=10)

    def using_note(self, kind: str = "sim") -> str:
        return (f"note: no --port given: using the arm of `busarm {kind} serve` (pid "
                f"{self.proc.pid}) on {self.port} (--port sim for a fresh simulated arm)")

    def stop(self) -> str:
        code, _, err = sigint_and_wait(self.proc)
        assert code == 0, err
        assert "Traceback" not in err
        return err


@pytest.fixture
def serve(env: Env) -> Iterator[Callable[..., Server]]:
    """Start a server (killed at the end if the test did not stop it)."""
    started: list[Server] = []

    def start(*args: str) -> Server:
        started.append(Server(list(args), env))
        return started[-1]

    yield start
    for server in started:
        if server.proc.poll() is None:
            server.proc.kill()
            server.proc.communicate(timeout=10)


# ---------------------------------------------------------------------- sim serve --board


@SERVER
@SERVED
@pytest.mark.parametrize("way", ["--port", "found"])
def test_servo_and_arm_commands_through_a_served_board(
        env: Env, serve: Callable[..., Server], way: str) -> None:
    """By its port, or found without --port: scan, info, move, monitor, an arm move the
    next command still sees."""
    server = serve("sim", "serve", "--board")

    def run(*args: str) -> str:
        result = busarm(*args, *(["--port", server.port] if way == "--port" else []), env=env)
        notes = [line for line in result.stderr.splitlines() if line.startswith("note:")]
        assert notes == ([] if way == "--port" else [server.using_note()]), result.stderr
        return ok(result)

    assert "found 6 servo(s): 1, 2, 3, 4, 5, 10" in run("scan", "--ids", "0-12")
    info = run("info", "1")
    assert row(info, "position") == "+0.0 deg (500 pulses)"
    for unreadable in ("last move (target, time)", "waiting move (target, time)", "mode",
                       "LED", "LED alarms"):
        assert row(info, unreadable) == NOT_READABLE, unreadable
    assert row(info, "voltage") == "11.10 V" and row(info, "temperature limit") == "85 C"

    run("move", "1", "30", "--time", "0.3", "--wait")
    watched = run("monitor", "--count", "1", "--ids", "1-5,10")
    # --wait ends within 1 deg of the target (its help says so): on a busy computer the
    # rest of the move may still be under way when the monitor reads, nearer than that.
    seen = re.search(r"│\s+1 │\s+([-+]\d+\.\d) │", watched)
    assert seen and float(seen[1]) == pytest.approx(30.0, abs=1.0), watched

    run("arm", "move-to", "200", "0", "40", "--pitch", "-90")
    pose = json.loads(run("arm", "pose", "--json"))["pose"]
    assert pose["x_mm"] == pytest.approx(200, abs=3) and pose["y_mm"] == pytest.approx(0, abs=3)
    assert pose["z_mm"] == pytest.approx(40, abs=3)
    assert pose["pitch_deg"] == pytest.approx(-90, abs=2)
    assert "simulator stopped" in server.stop()


@SERVER
@SERVED
def test_board_info_shows_the_battery_the_imu_and_gravity(
        env: Env, serve: Callable[..., Server]) -> None:
    server = serve("sim", "serve", "--board")
    result = busarm("board", "info", "--time", "0.5", env=env)
    table = ok(result)
    assert server.using_note() in result.stderr
    assert re.fullmatch(r"12\.\d\d V", row(table, "battery"))
    assert 12.2 <= float(row(table, "battery").split()[0]) <= 12.4  # the simulated 12.3 V
    rate_hz = float(row(table, "IMU rate").split()[0])
    assert 80 <= rate_hz <= 120  # the simulated board's 100 Hz
    accel = row(table, "acceleration (mean)")
    found = re.fullmatch(r"x (\S+)\s+y (\S+)\s+z (\S+) m/s\^2", accel)
    assert found, accel
    x, y, z = (float(v) for v in found.groups())
    assert abs(x) < 0.1 and abs(y) < 0.1 and z == pytest.approx(9.81, abs=0.05)
    assert row(table, "buttons") == "no press"
    assert f"on {server.port}" in table
    server.stop()


def test_the_boards_url_keys_reach_the_simulated_board_and_servos(env: Env) -> None:
    scan = ok(busarm("scan", "--ids", "0-12", "--port", "board://sim?ids=3,7", env=env))
    assert "found 2 servo(s): 3, 7" in scan
    table = ok(busarm("board", "info", "--time", "0.5", "--port",
                      "board://sim?battery_v=11.5&imu_hz=50", env=env))
    assert float(row(table, "battery").removesuffix(" V")) == pytest.approx(11.5, abs=0.05)
    assert 40 <= float(row(table, "IMU rate").split()[0]) <= 60


# ---------------------------------------------------------------------- errors


def test_board_info_on_a_port_that_is_not_a_boards(env: Env) -> None:
    said = one_error(busarm("board", "info", "--port", "sim", env=env), 2)
    assert said == ("error: sim is not a controller board's port (give "
                    "board:///dev/ttyACM0, or board://sim)")


def test_a_silent_board_is_one_error(env: Env) -> None:
    said = one_error(busarm("board", "beep", "--port", "board://sim?silent=1", env=env), 1)
    assert "no report from the controller board in 1 s" in said
    assert "is it powered, and is this its port?" in said


@pytest.mark.parametrize(("args", "what"), [
    (["motor", "1", "100"], "motor (continuous rotation) mode"),
    (["motor", "7", "stop"], "motor (continuous rotation) mode"),
    (["led", "1", "on"], "the servos' LEDs"),
])
def test_what_the_board_cannot_do_is_one_error(env: Env, args: list[str],
                                               what: str) -> None:
    said = one_error(busarm(*args, "--port", "board://sim", env=env), 2)
    assert said.startswith(f"error: the controller board cannot do {what}: "), said
    assert "use a plain LX bus adapter" in said


# ---------------------------------------------------------------------- twin serve --board


@SERVER
@SERVED
def test_twin_serve_board_gives_a_board_port_and_a_camera(
        env: Env, serve: Callable[..., Server]) -> None:
    server = serve("twin", "serve", "--board", "--seed", "2", "--blocks", "1")
    assert server.proc.stdout is not None
    camera = server.proc.stdout.readline().strip()
    assert re.fullmatch(r"twin://127\.0\.0\.1:\d+", camera), camera
    pose = json.loads(ok(busarm("arm", "pose", "--json", "--port", server.port, env=env)))
    assert set(pose["joints_deg"]) >= {"base_yaw", "shoulder_pitch"}
    table = ok(busarm("board", "info", "--time", "0.3", env=env))
    assert re.fullmatch(r"\d+\.\d\d V", row(table, "battery"))
    assert "twin stopped" in server.stop()
