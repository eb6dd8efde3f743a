"""What people asked of the command line (issue 13): named poses, the gripper in mm, motor
mode, network camera streams, sample action groups, and the ``actions`` details (a record
into a missing folder fails first; an interrupted play says at which frame).

Through the real CLI: click's CliRunner in-process, against simulated servos that live
for the whole test (so a saved pose is there to go back to) on their simulated clock
(``sim_arm``); or ``busarm`` as a subprocess where Ctrl+C or the process's own stderr
matters, against such servos served on a real pseudo-terminal in wall-clock time
(``pty_arm``). Network streams are served on 127.0.0.1 only.
"""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.arm.action_samples import SAMPLES, build_sample, read_sample, sample_names
from busarm.arm.config import load_arm_config
from busarm.bus.driver import ServoBus
from busarm.cli.main import cli
from busarm.clock import WALL_CLOCK
from busarm.protocol import Command, ModeReply, Request, ServoMode
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport
from conftest import PTY_MARGIN_S, in_process_port, wait_for

SIM = "sim://?timing=0"
MARGIN = ("--timeout-margin-ms", "200")
"""For a command at a pty served in wall-clock time, on a computer that may be busy: a
reply heard late is not what these tests are about."""
PTY_REASON = ("Ctrl+C to a command as its own process, at simulated servos served on a pty "
              "in wall-clock time")


def run(*args: str, port: str = SIM, input: str | None = None) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", port, *args], input=input)


def ok(result: Result) -> str:
    assert result.exit_code == 0, (result.exit_code, result.stdout, result.stderr)
    assert "Traceback" not in result.stdout + result.stderr
    return result.stdout


def one_error(result: Result, code: int) -> str:
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = [ln for ln in result.stderr.strip().splitlines() if not ln.startswith("note:")]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


def busarm(*args: str) -> subprocess.Popen[str]:
    """``busarm ARGS`` as a child that Ctrl+C reaches (even from a background job)."""
    return subprocess.Popen(
        [sys.executable, "-m", "busarm", *args], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def wait_for_line(proc: subprocess.Popen[str], text: str, timeout_s: float = 20.0) -> None:
    """Read the child's stderr until a line holds ``text``."""
    assert proc.stderr is not None
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        line = proc.stderr.readline()
        if text in line:
            return
        assert line or proc.poll() is None, proc.communicate()
    raise AssertionError(f"no line with {text!r} within {timeout_s} s")


@pytest.fixture
def sim_arm(monkeypatch: pytest.MonkeyPatch) -> tuple[str, SimBus]:
    """The simulated arm for commands run in this process (click's runner), kept from one
    command to the next as a served arm is: the port they open it by, and the simulator
    (on its simulated clock)."""
    sim = SimBus.with_ids(timing=WireTiming(enabled=False))
    url = in_process_port(monkeypatch, sim)
    return url, sim


@pytest.fixture
def pty_arm() -> Iterator[tuple[str, SimBus]]:
    """The simulated arm on a real pseudo-terminal, in wall-clock time, for a command run
    as its own process: its path, and the simulator."""
    sim = SimBus.with_ids(timing=WireTiming(enabled=False), clock=WALL_CLOCK)
    server = PtyServer(sim)
    yield server.start(), sim
    server.stop()


@pytest.fixture
def config_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    home = tmp_path / "config"
    monkeypatch.setenv("XDG_CONFIG_HOME", str(home))
    return home


def joints_of(port: str) -> list[float]:
    return list(json.loads(ok(run("arm", "pose", "--json", port=port)))["joints_deg"].values())


# ---------------------------------------------------------------------- named poses


def test_a_saved_pose_is_listed_and_moved_back_to(sim_arm: tuple[str, SimBus],
                                                  config_home: Path) -> None:
    path, _ = sim_arm
    over_bin = ["30", "-120", "90", "-60", "10"]
    ok(run("arm", "move-joints", *over_bin, "--speed", "180", port=path))
    result = run("arm", "pose", "--save", "over_bin", port=path)
    assert "saved pose 'over_bin'" in ok(result) + result.stderr
    ok(run("arm", "home", "--speed", "180", port=path))

    listed = json.loads(ok(run("arm", "poses", "--json", port=path)))
    by_name = {p["name"]: p for p in listed["poses"]}
    assert {"home", "look", "over_bin"} <= set(by_name)
    assert by_name["home"]["builtin"] and not by_name["over_bin"]["builtin"]
    assert list(by_name["over_bin"]["joints_deg"].values()) == pytest.approx(
        [float(a) for a in over_bin], abs=1.0)
    table = ok(run("arm", "poses", port=path))
    assert "over_bin" in table and "saved" in table and "arm config" in table
    # Kept per robot, in the XDG config folder.
    files = list(config_home.glob("busarm/*/poses.json"))
    assert len(files) == 1 and "over_bin" in json.loads(files[0].read_text())["poses"]
    assert "over_bin" not in ok(run("arm", "poses", "--json", port="twin"))  # another robot

    assert "to pose 'over_bin'" in ok(run("arm", "move-joints", "--pose", "over_bin",
                                          "--speed", "180", port=path))
    assert joints_of(path) == pytest.approx([float(a) for a in over_bin], abs=1.5)


def test_pose_names_are_checked_and_built_in_ones_kept(sim_arm: tuple[str, SimBus],
                                                       config_home: Path) -> None:
    path, _ = sim_arm
    line = one_error(run("arm", "pose", "--save", "Over Bin", port=path), 2)
    assert "'Over Bin'" in line and "lowercase letters" in line
    line = one_error(run("arm", "pose", "--save", "home", port=path), 2)
    assert "'home' is built into the arm config" in line
    line = one_error(run("arm", "poses", "--delete", "look", port=path), 2)
    assert "'look' is built into the arm config" in line
    line = one_error(run("arm", "move-joints", "--pose", "nowhere", port=path), 2)
    assert "no pose named 'nowhere'" in line and "home" in line
    assert not list(config_home.rglob("poses.json"))  # nothing was written


def test_pose_json_goes_back_into_move_joints(sim_arm: tuple[str, SimBus],
                                              tmp_path: Path) -> None:
    path, _ = sim_arm
    ok(run("arm", "move-joints", "-20", "-100", "60", "-70", "0", "--speed", "180", port=path))
    saved = tmp_path / "pose.json"
    saved.write_text(ok(run("arm", "pose", "--json", port=path)))
    ok(run("arm", "home", "--speed", "180", port=path))
    ok(run("arm", "move-joints", "--json", str(saved), "--speed", "180", port=path))
    assert joints_of(path) == pytest.approx([-20, -100, 60, -70, 0], abs=1.5)
    ok(run("arm", "home", "--speed", "180", port=path))
    ok(run("arm", "move-joints", "--json", "-", "--speed", "180", port=path,
           input=saved.read_text()))
    assert joints_of(path) == pytest.approx([-20, -100, 60, -70, 0], abs=1.5)
    line = one_error(run("arm", "move-joints", "--json", "-", port=path,
                         input='{"joints_deg": {"base_yaw": 0}}'), 2)
    assert "joint names base_yaw are not this arm's" in line


# ---------------------------------------------------------------------- gripper in mm


def test_gripper_opens_to_a_gap_in_mm(sim_arm: tuple[str, SimBus]) -> None:
    path, sim = sim_arm
    assert "gripper at 25.1 mm apart (566 pulses)" in ok(run("arm", "gripper", "25mm",
                                                             port=path))
    sim.clock.sleep(2.0)  # arrived, in simulated time
    sim.advance()
    assert sim.servo(10).position_pulses == pytest.approx(566, abs=2)
    for bad, shown in (("120mm", "gripper gap = 120.0 mm is out of range 0..93.8 mm"),
                       ("-3mm", "gripper gap = -3.0 mm is out of range 0..93.8 mm"),
                       ("25cm", "'25cm' is not open, close or a gap")):
        assert shown in one_error(run("arm", "gripper", bad, port=path), 2)
    sim.advance()
    assert sim.servo(10).position_pulses == pytest.approx(566, abs=2)  # nothing was sent
    out = ok(run("arm", "gripper", "10mm", port=SIM + "&block=1"))
    # Closing, stopped on the block: holding it (busarm.arm.gripper's one rule).
    assert "gripper holding something: stopped at 30.0 mm apart (540 pulses), short of the " \
        "10.0 mm asked" in out


# ---------------------------------------------------------------------- motor mode


def mode(at: str | SimBus, servo_id: int) -> tuple[ServoMode, int]:
    """The servo's mode and motor speed, read back (``at``: a pty's path, or a simulator
    in this process)."""
    bus = (ServoBus.open(at, echo="off", timeout_margin_s=PTY_MARGIN_S)
           if isinstance(at, str) else ServoBus(SimTransport(at), echo="off"))
    with bus:
        reply = bus.read_mode(servo_id)
    return reply.mode, reply.motor_speed


def servo_mode(sim: SimBus, servo_id: int) -> tuple[ServoMode, int]:
    """The mode and motor speed a servo served on a pty would answer, asked of its model
    in this process (the wire stays the program's at the other end)."""
    with sim.lock:
        reply = sim.servo(servo_id).handle(Request(servo_id, Command.OR_MOTOR_MODE_READ),
                                           sim.clock.now())
    assert isinstance(reply, ModeReply)
    return reply.mode, reply.motor_speed


def test_motor_turns_for_a_time_then_holds(sim_arm: tuple[str, SimBus]) -> None:
    path, sim = sim_arm
    sim.advance()
    before = sim.servo(1).position_pulses
    started = sim.clock.now()
    out = ok(run("motor", "1", "500", "--time", "0.3", "--arm-servo", port=path))
    assert sim.clock.now() - started >= 0.3  # (simulated seconds)
    assert "servo 1 stopped: back in position mode, holding at" in out
    assert mode(sim, 1) == (ServoMode.POSITION, 0)
    sim.advance()
    assert abs(sim.servo(1).position_pulses - before) > 50  # it did turn


def test_motor_keep_turning_then_stop_and_bad_speeds(sim_arm: tuple[str, SimBus]) -> None:
    path, sim = sim_arm
    line = one_error(run("motor", "1", "2000", port=path), 2)
    assert "motor speed = 2000 is out of range -1000..1000" in line
    assert "'fast' is not an integer" in one_error(run("motor", "1", "fast", port=path), 2)
    assert mode(sim, 1) == (ServoMode.POSITION, 0)  # nothing was sent
    assert "stop it with `busarm motor 1 stop`" in ok(
        run("motor", "1", "-300", "--keep-turning", "--arm-servo", port=path))
    assert mode(sim, 1) == (ServoMode.MOTOR, -300)
    assert "back in position mode" in ok(run("motor", "1", "stop", port=path))
    assert mode(sim, 1) == (ServoMode.POSITION, 0)


def test_motor_refuses_a_servo_of_the_arm_unless_asked(sim_arm: tuple[str, SimBus]) -> None:
    path, sim = sim_arm
    line = one_error(run("motor", "2", "300", "--time", "0.2", port=path), 2)
    assert "servo 2 is shoulder_pitch of the arm" in line and "--arm-servo" in line
    assert mode(sim, 2) == (ServoMode.POSITION, 0)  # nothing was sent


def test_stop_stops_a_motor_left_turning_and_says_so(sim_arm: tuple[str, SimBus]) -> None:
    path, sim = sim_arm
    ok(run("motor", "1", "400", "--keep-turning", "--arm-servo", port=path))
    assert mode(sim, 1) == (ServoMode.MOTOR, 400)
    out = " ".join(ok(run("stop", "1", port=path)).split())
    assert "servo 1 turning in motor mode: stopped (speed 0, position mode)" in out, out
    assert "servo 1 holding position (torque on)" in out, out
    assert mode(sim, 1) == (ServoMode.POSITION, 0)
    # Without IDs MOVE_STOP goes to all, and it says what that does not stop.
    assert "motor mode does not stop so" in " ".join(ok(run("stop", port=path)).split())


@pytest.mark.wallclock(PTY_REASON)
def test_motor_ctrl_c_stops_it(pty_arm: tuple[str, SimBus]) -> None:
    path, sim = pty_arm
    proc = busarm("--port", path, *MARGIN, "motor", "2", "800", "--arm-servo")
    try:
        wait_for_line(proc, "turning at speed 800")
        # Asked of the servo itself, not through the pty: the command holds the device
        # (one driver at a time), and a read of ours would be a second one on its line.
        assert wait_for(lambda: servo_mode(sim, 2) == (ServoMode.MOTOR, 800))
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err  # the way to end it, but an interruption all the same
    assert "servo 2 stopped: back in position mode, holding at" in out
    assert "Traceback" not in err
    assert mode(path, 2) == (ServoMode.POSITION, 0)
    servo, now = sim.servo(2), time.monotonic()  # the servo's model, 0.1 s on: still
    servo.advance(now)
    held = servo.position_pulses
    servo.advance(now + 0.1)
    assert servo.position_pulses == held


# ---------------------------------------------------------------------- camera streams


def _mjpeg_frame() -> bytes:
    image = np.full((120, 160, 3), 128, np.uint8)
    image[40:80, 60:100] = (0, 0, 255)  # a red block, BGR
    return bytes(cv2.imencode(".jpg", image)[1].tobytes())


class _Mjpeg(BaseHTTPRequestHandler):
    """An MJPEG stream (multipart/x-mixed-replace), as IP cameras and phones serve."""

    def do_GET(self) -> None:
        frame = _mjpeg_frame()
        self.send_response(200)
        self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
        self.end_headers()
        try:
            for _ in range(100):
                self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n"
                                 b"Content-Length: %d\r\n\r\n" % len(frame) + frame + b"\r\n")
                time.sleep(0.02)
        except OSError:
            pass  # the client has what it wanted

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def mjpeg_url() -> Iterator[str]:
    server = ThreadingHTTPServer(("127.0.0.1", 0), _Mjpeg)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}/stream.mjpg"
    server.shutdown()
    server.server_close()


@pytest.mark.wallclock("a network camera stream, served by a thread in wall-clock time")
def test_camera_from_an_http_mjpeg_stream(mjpeg_url: str) -> None:
    result = CliRunner(mix_stderr=False).invoke(
        cli, ["vision", "detect", "--camera", mjpeg_url, "--frames", "3", "--json"])
    frames = [json.loads(line) for line in ok(result).splitlines()]
    assert len(frames) == 3
    assert all(f["source"] == mjpeg_url and f["width_px"] == 160 for f in frames)
    assert [d["color"] for d in frames[0]["detections"]] == ["red"]


@pytest.mark.wallclock("a network camera's open timeout (5 s), in a process of its own "
                       "(its stderr: no OpenCV noise)")
def test_camera_stream_that_fails_gives_one_error_in_time() -> None:
    refused = socket.socket()
    refused.bind(("127.0.0.1", 0))
    closed_port = refused.getsockname()[1]
    refused.close()
    silent = socket.socket()  # accepts the connection, never answers
    silent.bind(("127.0.0.1", 0))
    silent.listen(1)
    try:
        for url, why in ((f"http://cam:secret@127.0.0.1:{closed_port}/video", "refused"),
                         (f"rtsp://127.0.0.1:{silent.getsockname()[1]}/live", "silent")):
            start = time.monotonic()
            proc = busarm("vision", "detect", "--camera", url)
            out, err = proc.communicate(timeout=30)
            assert time.monotonic() - start < 15, why  # the 5 s open timeout, no hang
            assert proc.returncode == 1, (why, out, err)
            assert err.strip().count("\n") == 0, (why, err)  # one line: no OpenCV noise
            assert err.startswith("error: cannot open camera stream"), (why, err)
            # Said as it is: refused at once, or nothing within the 5 s.
            said = "the connection was refused" if why == "refused" else "within 5 s"
            assert said in err and "secret" not in err, (why, err)
    finally:
        silent.close()


# ---------------------------------------------------------------------- action groups


def test_samples_are_listed_shipped_and_played_by_name(sim_arm: tuple[str, SimBus]) -> None:
    listed = json.loads(ok(run("actions", "list", "--json")))["samples"]
    assert [s["name"] for s in listed] == sample_names() == ["nod", "open-close", "wave"]
    assert all(s["frames"] >= 4 and s["description"] for s in listed)
    config = load_arm_config()
    for name in sample_names():  # the shipped files are the ones our writer makes
        assert read_sample(name) == build_sample(name)
        first_ms, first, _ = SAMPLES[name].frames[0]
        for j, a in zip(config.joints, first, strict=True):  # reachable from anywhere
            assert max(a - j.min_deg, j.max_deg - a) / (first_ms / 1000) <= j.max_speed_deg_s
    path, sim = sim_arm
    result = run("actions", "play", "open-close", port=path)
    assert "played 4 of 4 frames" in ok(result)
    assert "frame 4 of 4" in result.stderr
    sim.clock.sleep(2.0)  # arrived, in simulated time
    sim.advance()
    assert sim.servo(10).position_pulses == pytest.approx(450, abs=3)
    line = one_error(run("actions", "play", "dance"), 2)
    assert "no action group file dance" in line and "nod, open-close, wave" in line


@pytest.mark.wallclock(PTY_REASON)
def test_interrupted_play_says_at_which_frame(pty_arm: tuple[str, SimBus]) -> None:
    path, sim = pty_arm
    # At half speed frame 2 takes 1.2 s: Ctrl+C comes within it on a busy computer too.
    proc = busarm("--port", path, *MARGIN, "actions", "play", "wave", "--speed-scale", "0.5")
    try:
        wait_for_line(proc, "frame 2 of 7", timeout_s=60)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    last = err.strip().splitlines()[-1]  # one line says where, and what the servos do
    assert last.startswith("interrupted at frame 2 of 7: all servos stopped"), err
    assert "holding" in last, err
    assert "Traceback" not in err
    servo, now = sim.servo(1), time.monotonic()  # the servo's model, 0.3 s on: still
    servo.advance(now)
    held = servo.position_pulses
    servo.advance(now + 0.3)
    assert servo.position_pulses == held  # stopped mid-wave, holding


def test_record_into_a_missing_folder_fails_before_teaching(
        sim_arm: tuple[str, SimBus], tmp_path: Path) -> None:
    path, sim = sim_arm
    ok(run("arm", "home", "--speed", "180", port=path))  # torque on
    out = tmp_path / "no" / "such" / "taught.d6a"
    line = one_error(run("actions", "record", str(out), "--interval", "0.05", "--frames", "2",
                         port=path), 2)
    assert f"cannot write {out}" in line and "does not exist" in line
    assert all(sim.servo(sid).is_loaded for sid in (1, 2, 3, 4, 5))  # torque never went off


def test_config_home_is_taken_only_when_absolute(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    from busarm.fileio import config_home

    monkeypatch.setenv("XDG_CONFIG_HOME", "relative/dir")  # the XDG rule: ignore it
    assert config_home() == Path.home() / ".config"
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert config_home() == tmp_path
