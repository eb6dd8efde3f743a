"""Commands without --port use a running ``busarm sim serve`` / ``twin serve`` (found by
its runtime file), and options are accepted where users put them (``busarm arm pose
--port X``, ``busarm --config X arm pose``).

The servers (and the dashboard) run as real subprocesses (in wall-clock time), each test
with its own runtime folder (BUSARM_RUNTIME_DIR), so nothing here sees a server another
test or a developer runs; the commands at them run in this process through click's runner
(found without --port through that folder, talking to the served arm over its pty), given
a generous reply margin (``MARGIN``). Where options are the point, not a server, the
commands run in this process on the simulated arm on its simulated clock. Only ``-v``'s
logging to a command's stderr is checked on a command run as its own process.
"""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner, Result
from rich.console import Console

from busarm.cli import sessions
from busarm.cli.common import SIM_NOTE, Settings
from busarm.cli.main import cli
from busarm.cli.option_places import walk
from busarm.sim.bus import SimBus, WireTiming
from conftest import in_process_port, not_crashed, process_env, wait_for

STRAIGHT_UP_Z_MM = 629.4
"""The tool height of the simulator's power-on pose (every servo at 500 pulses)."""
MARGIN = ("--timeout-margin-ms", "200")
"""For a command at a served arm (wall-clock time) on a computer that may be busy: a reply
heard late is not what these tests are about."""
SERVED = ("`busarm sim|twin serve` as its own process (wall-clock time), found by commands "
          "run in this process")

Env = dict[str, str | None]
"""Variables for a command in this process: None removes one for the call."""


@pytest.fixture
def env(tmp_path: Path) -> Env:
    """A user with no --port, BUSARM_PORT or arm options set (None: removed), and a
    runtime folder of this test's own. The commands run in this process with these set
    for the call only (click's runner); a server's process gets them on top of this
    one's environment (``process_env``)."""
    return {"BUSARM_PORT": None, "BUSARM_ARM": None, "BUSARM_CALIBRATION": None,
            "BUSARM_RUNTIME_DIR": str(tmp_path / "run"), "COLUMNS": "200"}




def in_process(*args: str, env: Env) -> subprocess.CompletedProcess[str]:
    """``busarm ARGS`` in this process (click's runner), in ``env``, as a finished process.
    A crash (an exception other than the SystemExit of an exit code) fails the test: the
    runner would swallow the traceback a process prints."""
    result = CliRunner(mix_stderr=False).invoke(cli, list(args), env=env, prog_name="busarm")
    not_crashed(result)
    return subprocess.CompletedProcess(args, result.exit_code, result.stdout, result.stderr)


def busarm(*args: str, env: Env) -> subprocess.CompletedProcess[str]:
    """``busarm ARGS`` in this process, at a served arm (or finding none): with a generous
    reply margin, unless given."""
    margin = () if MARGIN[0] in args else MARGIN
    return in_process(*args, *margin, env=env)


def as_process(*args: str, env: Env, timeout_s: float = 120.0
               ) -> subprocess.CompletedProcess[str]:
    """``busarm ARGS`` as its own process (with a generous reply margin, unless given)."""
    margin = () if MARGIN[0] in args else MARGIN
    return subprocess.run([sys.executable, "-m", "busarm", *args, *margin],
                          capture_output=True, text=True, env=process_env(env),
                          timeout=timeout_s)




class Server:
    """``busarm sim|twin serve`` in its own process; stop() sends SIGTERM."""

    def __init__(self, args: list[str], env: Env) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "busarm", *args], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, env=process_env(env),
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        assert self.proc.stdout is not None
        self.path = self.proc.stdout.readline().strip()
        assert self.path.startswith("/dev/"), self.proc.communicate(timeout=30)
        self.runtime = Path(str(env["BUSARM_RUNTIME_DIR"]))

    def runtime_files(self) -> list[Path]:
        return sorted(self.runtime.glob("*.json")) if self.runtime.is_dir() else []

    def wait_announced(self, files: int = 1) -> Path:
        """The runtime file it announced itself by (the newest, once ``files`` are there)."""
        assert wait_for(lambda: len(self.runtime_files()) >= files or
                        self.proc.poll() is not None, timeout_s=30)
        assert self.proc.poll() is None, ("not announced", self.proc.communicate(timeout=30))
        if files == 1:
            (path,) = self.runtime_files()
            return path
        return max(self.runtime_files(), key=lambda f: f.stat().st_mtime_ns)

    def stop(self) -> str:
        if self.proc.poll() is None:
            self.proc.terminate()
        _, err = self.proc.communicate(timeout=30)
        assert self.proc.returncode == 0, err
        assert "Traceback" not in err
        return err


@pytest.fixture
def servers() -> Iterator[list[Server]]:
    started: list[Server] = []
    yield started
    for server in started:
        if server.proc.poll() is None:
            server.proc.kill()
            server.proc.communicate(timeout=30)


def pose_of(result: subprocess.CompletedProcess[str]) -> dict[str, float]:
    assert result.returncode == 0, result.stderr
    pose: dict[str, float] = json.loads(result.stdout)["pose"]
    return pose


def notes(result: subprocess.CompletedProcess[str]) -> list[str]:
    return [line for line in result.stderr.splitlines() if line.startswith("note:")]


# ---------------------------------------------------------------------- sim serve


@pytest.mark.wallclock(SERVED)
def test_a_served_arm_keeps_one_set_of_files_by_default_or_by_its_pty(
        env: Env, servers: list[Server]) -> None:
    server = Server(["sim", "serve", "--no-timing"], env)
    servers.append(server)
    server.wait_announced()
    saved = busarm("arm", "pose", "--save", "over_bin", env=env)
    assert saved.returncode == 0, saved.stderr
    assert "/busarm/sim/poses.json" in saved.stderr
    listed = in_process("--port", server.path, *MARGIN, "arm", "poses", env=env)
    assert listed.returncode == 0 and "over_bin" in listed.stdout, listed.stderr
    moved = in_process("--port", server.path, *MARGIN, "arm", "move-joints", "--pose",
                       "over_bin", env=env)
    assert moved.returncode == 0, moved.stderr


@pytest.mark.wallclock(SERVED)
def test_commands_without_port_build_on_a_running_sim_serve(
        env: Env, servers: list[Server]) -> None:
    server = Server(["sim", "serve", "--no-timing"], env)
    servers.append(server)
    runtime = server.wait_announced()
    data = json.loads(runtime.read_text())
    assert (data["kind"], data["port"], data["pid"]) == ("sim", server.path, server.proc.pid)
    using = (f"note: no --port given: using the arm of `busarm sim serve` (pid "
             f"{server.proc.pid}) on {server.path} (--port sim for a fresh simulated arm)")

    moved = busarm("arm", "move-to", "200", "0", "40", "--pitch", "-90", env=env)
    assert moved.returncode == 0, moved.stderr
    assert notes(moved) == [using]  # said once, naming the server
    after = busarm("arm", "pose", "--json", env=env)
    assert notes(after) == [using]
    pose = pose_of(after)
    assert abs(pose["x_mm"] - 200) < 3 and abs(pose["z_mm"] - 40) < 3, pose
    assert abs(pose["pitch_deg"] + 90) < 2, pose

    # An explicit --port sim is a fresh in-process arm, server or not.
    fresh = in_process("--port", "sim", "arm", "pose", "--json", env=env)
    assert notes(fresh) == [] and pose_of(fresh)["z_mm"] == pytest.approx(STRAIGHT_UP_Z_MM, abs=1)

    assert "simulator stopped" in server.stop()
    assert not runtime.exists(), "the runtime file outlived its server"
    alone = busarm("arm", "pose", "--json", env=env)
    assert notes(alone) == [SIM_NOTE]
    assert pose_of(alone)["z_mm"] == pytest.approx(STRAIGHT_UP_Z_MM, abs=1)


@pytest.mark.wallclock(SERVED)
def test_the_newest_of_two_servers_is_used(env: Env, servers: list[Server]) -> None:
    first = Server(["sim", "serve", "--no-timing", "--ids", "1,2,3,4,5,10"], env)
    servers.append(first)
    first.wait_announced()
    second = Server(["sim", "serve", "--no-timing"], env)
    servers.append(second)
    second.wait_announced(files=2)
    result = busarm("stop", env=env)
    assert result.returncode == 0, result.stderr
    assert notes(result) == [f"note: no --port given: using the arm of `busarm sim serve` (pid "
                             f"{second.proc.pid}) on {second.path} (--port sim for a fresh "
                             "simulated arm)"]
    second.stop()
    first.stop()


@pytest.mark.wallclock(SERVED)
def test_a_killed_servers_file_is_ignored_and_removed(env: Env,
                                                      servers: list[Server]) -> None:
    server = Server(["sim", "serve", "--no-timing"], env)
    servers.append(server)
    runtime = server.wait_announced()
    server.proc.kill()  # SIGKILL: no chance to remove its file
    server.proc.communicate(timeout=30)
    assert runtime.exists()
    result = busarm("arm", "pose", "--json", env=env)
    assert notes(result) == [SIM_NOTE]
    assert pose_of(result)["z_mm"] == pytest.approx(STRAIGHT_UP_Z_MM, abs=1)
    assert not runtime.exists(), "the stale runtime file was not cleaned"


def test_runtime_files_that_do_not_name_a_live_server_are_stale(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(sessions.RUNTIME_DIR_ENV, str(tmp_path))
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    record = {"format": sessions.FORMAT_NAME, "version": sessions.FORMAT_VERSION,
              "kind": "sim", "camera": None, "started": 1.0}
    gone = tmp_path / "sim-dead.json"
    gone.write_text(json.dumps({**record, "pid": dead.pid, "port": "/dev/null"}))
    no_port = tmp_path / "sim-noport.json"
    no_port.write_text(json.dumps({**record, "pid": os.getpid(), "port": "/dev/pts/nosuch"}))
    other = tmp_path / "notes.json"  # not a runtime file: left alone
    other.write_text("{}")
    live = tmp_path / "twin-live.json"
    live.write_text(json.dumps({**record, "kind": "twin", "pid": os.getpid(),
                                "port": "/dev/null", "camera": "twin://127.0.0.1:1"}))
    (found,) = sessions.running_sessions()
    assert (found.kind, found.port, found.camera) == ("twin", "/dev/null", "twin://127.0.0.1:1")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.json", "twin-live.json"]


def test_the_runtime_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(sessions.RUNTIME_DIR_ENV, raising=False)
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    assert sessions.runtime_dir() == tmp_path / "busarm"
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path / "missing"))
    assert sessions.runtime_dir().name == f"busarm-{os.getuid()}"
    # The file exists while the body runs, private folder, and is gone after it.
    monkeypatch.setenv(sessions.RUNTIME_DIR_ENV, str(tmp_path / "run"))
    with sessions.announced("sim", "/dev/null") as path:
        assert path is not None and path.parent == tmp_path / "run"
        assert (path.parent.stat().st_mode & 0o777) == 0o700
        assert sessions.find_session() is not None
    assert not path.exists() and sessions.find_session() is None


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                    reason="needs root to give the folder to another user")
def test_a_runtime_folder_of_another_user_is_not_trusted(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "run"
    monkeypatch.setenv(sessions.RUNTIME_DIR_ENV, str(folder))
    with sessions.announced("sim", "/dev/null"):
        assert sessions.find_session() is not None
        os.chown(folder, 12345, -1)  # as if another user had made it first in /tmp
        assert sessions.find_session() is None
        with sessions.announced("sim", "/dev/null") as planted:
            assert planted is None


@pytest.mark.wallclock(SERVED)
def test_twin_serve_is_the_default_arm_with_its_camera(
        env: Env, servers: list[Server], monkeypatch: pytest.MonkeyPatch) -> None:
    server = Server(["twin", "serve", "--seed", "2", "--blocks", "1"], env)
    servers.append(server)
    assert server.proc.stdout is not None
    camera = server.proc.stdout.readline().strip()
    data = json.loads(server.wait_announced().read_text())
    assert (data["kind"], data["port"], data["camera"]) == ("twin", server.path, camera)
    # The most margin the driver takes: a twin serve simulates its physics in the same
    # process as it answers, and may fall silent for long on a busy computer.
    result = busarm("arm", "gripper", "open", "--timeout-margin-ms", "1000", env=env)
    assert result.returncode == 0, result.stderr
    assert notes(result) == [f"note: no --port given: using the arm of `busarm twin serve` (pid "
                             f"{server.proc.pid}) on {server.path} (--port sim for a fresh "
                             "simulated arm)"]
    # The robot commands (camera, vision locate) get its camera too.
    monkeypatch.setenv(sessions.RUNTIME_DIR_ENV, str(env["BUSARM_RUNTIME_DIR"]))
    settings = Settings(port_given=False, err=Console(file=io.StringIO()),
                        timeout_margin_ms=1000.0)
    with settings.open_robot(needs=("camera",)) as robot:
        assert robot.port == server.path and robot.camera is not None
        assert robot.camera.read().image.shape[:2] == (480, 640)
    assert "twin stopped" in server.stop()
    assert not server.runtime_files()


# ---------------------------------------------------------------------- option places


def invoke(*args: str, **env: str | None) -> Result:
    return CliRunner(mix_stderr=False).invoke(
        cli, list(args), env={"BUSARM_PORT": None, "BUSARM_ARM": None,
                              "BUSARM_CALIBRATION": None, **env}, prog_name="busarm")


def one_error(result: Result, code: int = 2) -> str:
    assert result.exit_code == code, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    not_crashed(result)
    return lines[0]


@pytest.fixture
def sim_bus(monkeypatch: pytest.MonkeyPatch) -> tuple[str, SimBus]:
    """The simulated arm, no wire timing, kept from one command to the next (as a served
    arm is) for commands run in this process: the port they open it by, and its SimBus."""
    bus = SimBus.with_ids([1, 2, 3, 4, 5, 10], timing=WireTiming(enabled=False))
    url = in_process_port(monkeypatch, bus)
    return url, bus


def test_global_options_after_the_command(sim_bus: tuple[str, SimBus]) -> None:
    path, bus = sim_bus
    result = invoke("arm", "move-joints", "30", "-90", "0", "-90", "0", "--time", "0.2",
                    "--port", path, "--echo", "off", "--baud", "115200", "--retries", "1",
                    "--timeout-margin-ms", "20")
    assert result.exit_code == 0, result.stderr
    assert "note:" not in result.stderr  # --port was given, after the command
    assert bus.frames_received > 0
    # At the group too: the same arm, where the move left it.
    pose = invoke("arm", "--port", path, "pose", "--json")
    assert pose.exit_code == 0, pose.stderr
    assert json.loads(pose.stdout)["joints_deg"]["base_yaw"] == pytest.approx(30, abs=1)
    assert "cannot open" in one_error(invoke("arm", "pose", "--port", "/nonexistent/tty9"), 1)
    assert "1200<=x<=4000000" in one_error(invoke("move", "1", "10", "--baud", "5"))
    assert "'bogus' is not one of" in one_error(invoke("stop", "--echo", "bogus"))


def test_every_command_takes_the_global_options_after_it() -> None:
    # A command added after accept_everywhere() ran would not: this catches it.
    commands = list(walk(cli))
    assert len(commands) > 40
    for path, command in commands:
        options = {o for p in command.params for o in p.opts}
        # (`sim serve` and `twin serve` keep their own --echo flag.)
        assert {"--port", "--baud", "--echo", "--retries", "--timeout-margin-ms",
                "-v"} <= options, path


@pytest.mark.wallclock("-v logs to the stderr of a command run as its own process")
def test_verbose_after_the_command(env: Env) -> None:
    quiet = as_process("--port", "sim", "stop", env=env)
    loud = as_process("stop", "--port", "sim", "-v", env=env)
    assert quiet.returncode == loud.returncode == 0, loud.stderr
    assert "busarm" not in quiet.stderr and "busarm.bus" in loud.stderr, loud.stderr


def test_sim_serve_keeps_its_own_echo_flag() -> None:
    text = invoke("sim", "serve", "--help").stdout
    assert "--echo  " in text and "[on|off|auto]" not in text


@pytest.mark.parametrize("where", ["root", "group", "leaf"])
def test_arm_options_in_every_place(where: str, tmp_path: Path) -> None:
    def args(option: str, value: str) -> list[str]:
        return {"root": [option, value, "arm", "pose"],
                "group": ["arm", option, value, "pose"],
                "leaf": ["arm", "pose", option, value]}[where]

    missing = str(tmp_path / "missing.json")
    assert "arm config nosuch" in one_error(invoke("--port", "sim", *args("--config", "nosuch")))
    assert f"calibration {missing}" in one_error(
        invoke("--port", "sim", *args("--calibration", missing)))
    ok = invoke("--port", "sim", *args("--config", "jetauto_pro"))
    assert ok.exit_code == 0, ok.stderr


def test_arm_option_precedence() -> None:
    # The command line beats the environment, wherever on it; the nearest place wins.
    assert invoke("--port", "sim", "--config", "jetauto_pro", "arm", "pose",
                  BUSARM_ARM="nosuch").exit_code == 0
    assert invoke("--port", "sim", "arm", "pose", "--config", "jetauto_pro",
                  BUSARM_ARM="nosuch").exit_code == 0
    assert invoke("--port", "sim", "--config", "jetauto_pro", "move", "1", "10",
                  BUSARM_ARM="nosuch").exit_code == 0
    assert "arm config nosuch" in one_error(invoke("--port", "sim", "move", "1", "10",
                                                   BUSARM_ARM="nosuch"))
    assert invoke("--port", "sim", "--config", "nosuch", "arm", "--config", "jetauto_pro",
                  "pose").exit_code == 0
    assert invoke("--port", "sim", "--config", "nosuch", "arm", "pose", "--config",
                  "jetauto_pro").exit_code == 0
    assert "arm config nosuch" in one_error(
        invoke("--port", "sim", "arm", "--config", "jetauto_pro", "pose", "--config", "nosuch"))


def test_config_before_a_command_that_takes_it_after() -> None:
    # pick-sort, move and twin snapshot have their own --config: the one before the
    # command is their default.
    assert "arm config nosuch" in one_error(invoke("--config", "nosuch", "pick-sort"))
    assert "arm config nosuch" in one_error(
        invoke("--config", "nosuch", "--port", "sim", "move", "1", "10"))
    assert "arm config nosuch" in one_error(
        invoke("--config", "nosuch", "twin", "snapshot", "--png", "x.png"))


def test_arm_options_for_a_command_that_takes_none_are_refused(tmp_path: Path) -> None:
    calibration = str(tmp_path / "cal.json")
    assert one_error(invoke("--calibration", calibration, "pick-sort")) == (
        f"error: `busarm pick-sort` takes no --calibration (given {calibration!r})")
    assert one_error(invoke("--config", "jetauto_pro", "decode", "55")) == (
        "error: `busarm decode` takes no --config (given 'jetauto_pro')")
    assert "takes no --config" in one_error(invoke("scan", "--config", "jetauto_pro"))


def test_an_option_of_the_command_given_before_it_says_where_it_goes() -> None:
    message = one_error(invoke("--seed", "3", "pick-sort"))
    assert message == ("error: --seed is an option of `busarm pick-sort`, not of `busarm`: "
                       "put it after the command (busarm pick-sort --seed ...)")
    message = one_error(invoke("--json", "arm", "pose"))
    assert "--json is an option of `busarm arm pose`" in message
    assert "No such option: --nosuch" in one_error(invoke("--nosuch", "arm", "pose"))


@pytest.mark.wallclock(SERVED + ", Ctrl+C to the dashboard")
def test_the_dashboard_watches_a_running_sim_serve_with_its_saved_poses(
        env: Env, servers: list[Server], tmp_path: Path) -> None:
    """Without --port the dashboard drives the served arm, and finds the poses the
    commands saved for it; Ctrl+C stops it as a server stops: exit 0, no traceback."""
    import urllib.request

    server = Server(["sim", "serve", "--no-timing"], env)
    servers.append(server)
    server.wait_announced()
    saved = busarm("arm", "pose", "--save", "over_bin", env=env)
    assert saved.returncode == 0, saved.stderr
    dashboard = subprocess.Popen(
        [sys.executable, "-m", "busarm", "dashboard", "--http-port", "0", "--reports",
         str(tmp_path / "reports"), *MARGIN], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, env=process_env(env),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert dashboard.stdout is not None
        url = dashboard.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), dashboard.communicate(timeout=30)
        with urllib.request.urlopen(url + "api/robot", timeout=30) as reply:
            robot = json.loads(reply.read())
        assert robot["port"] == server.path and not robot["twin"]
        assert "over_bin" in robot["poses"]
    finally:
        dashboard.send_signal(signal.SIGINT)
        _, err = dashboard.communicate(timeout=60)
    assert dashboard.returncode == 0, err
    assert "Traceback" not in err
    assert f"using the arm of `busarm sim serve` (pid {server.proc.pid}) on {server.path}" in err
    assert err.rstrip().endswith("dashboard stopped: every servo was told to stop where it is "
                                 "(MOVE_STOP)")
