"""The ``busarm`` command line, end to end.

The CLI runs in this process (click's CliRunner) against the in-process simulator
(``sim://?timing=0``) or against simulated servos of the test's own (``sim_servos``),
which the commands open from one run to the next as a served arm, on their simulated
clock: their counters show exactly what reached the bus, and a wait costs only the CPU
it takes. ``sim serve`` and ``monitor`` are also run as real subprocesses on a real
pseudo-terminal and stopped with SIGINT; ``demo`` serves its own arm on one.
"""

from __future__ import annotations

import io
import os
import re
import signal
import subprocess
import sys
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import click
import pytest
from click.testing import CliRunner, Result
from rich.console import Console
from serial.tools import list_ports
from serial.tools.list_ports_common import ListPortInfo

from busarm.arm.arm import Arm
from busarm.arm.config import load_arm_config
from busarm.bus.driver import ServoBus
from busarm.cli import bus_cmds, demo
from busarm.cli.main import cli
from busarm.clock import SimClock
from busarm.sim.bus import ARM_SERVO_IDS, SimBus, WireTiming
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import ServoParams
from busarm.sim.transport import SimTransport
from conftest import in_process_port, sigint_and_wait

SIM = "sim://?timing=0"
MARGIN = ("--timeout-margin-ms", "200")
"""For a command at a pty served by another process (wall-clock time) on a computer that
may be busy: a reply heard late is not what these tests are about."""


def run(*args: str, port: str = SIM) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", port, *args])


def assert_one_error(result: Result, code: int) -> str:
    """Exactly one ``error:`` line on stderr, nothing else, no traceback."""
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    assert isinstance(result.exception, SystemExit)
    return lines[0]


SimFactory = Callable[[Sequence[SimServo]], tuple[str, SimBus]]
CLOCK_START_S = 0.0
"""A fresh SimClock's time: the servos given to ``sim_servos`` are made at it."""


@pytest.fixture
def sim_servos(monkeypatch: pytest.MonkeyPatch) -> SimFactory:
    """Simulated servos (no wire timing, on a fresh simulated clock) that commands run in
    this process open by the port returned, kept from one command to the next as a
    served arm is: -> (port, SimBus)."""
    def start(servos: Sequence[SimServo]) -> tuple[str, SimBus]:
        sim = SimBus(servos, timing=WireTiming(enabled=False), clock=SimClock(CLOCK_START_S))
        return in_process_port(monkeypatch, sim), sim

    return start


def servos(*ids: int, **params: object) -> list[SimServo]:
    return [SimServo(sid, params=ServoParams(**params), now=CLOCK_START_S)  # type: ignore[arg-type]
            for sid in ids]


def sleep_and_advance(bus: SimBus, seconds: float) -> None:
    """Let ``seconds`` of the servos' simulated time pass, and bring them up to it (the
    simulation advances when asked)."""
    bus.clock.sleep(seconds)
    bus.advance()


# ---------------------------------------------------------------------------- help


def _all_commands(group: click.Group, prefix: str = "") -> Iterator[tuple[str, click.Command]]:
    for name, command in group.commands.items():
        yield prefix + name, command
        if isinstance(command, click.Group):
            yield from _all_commands(command, prefix + name + " ")


def test_every_command_and_option_has_help() -> None:
    names = dict(_all_commands(cli))
    for expected in ("ports", "scan", "info", "move", "stop", "torque", "set-id", "offset",
                     "limits", "led", "monitor", "decode", "encode", "sim", "sim serve", "demo",
                     "arm", "arm fk", "arm ik", "arm ik-batch", "arm pose", "arm move-to",
                     "arm home", "arm gripper", "arm calibrate", "arm urdf", "arm workspace",
                     "actions", "actions show", "actions play", "actions record", "bench ik",
                     "twin", "twin serve", "twin snapshot", "twin scene", "camera",
                     "camera calibrate", "camera handeye", "vision", "vision detect",
                     "vision locate", "bench vision", "bench locate"):
        assert expected in names
    for name, command in [("busarm", cli), *names.items()]:
        assert command.help, name
        for param in command.params:
            if isinstance(param, click.Option) and not param.hidden:
                assert param.help, f"{name} {param.opts}"
    result = run("--help")
    assert result.exit_code == 0 and "set-id" in result.stdout


# ---------------------------------------------------------------------------- protocol tools


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["MOVE_TIME_WRITE", "1", "500", "1000"], "55 55 01 07 01 f4 01 e8 03 16"),
        (["28", "254"], "55 55 fe 03 1c e2"),  # POS_READ by number, to broadcast
        (["angle-offset-adjust", "1", "-10"], "55 55 01 04 11 f6 f3"),  # signed byte
        (["SERVO_ID_READ", "254"], "55 55 fe 03 0e f0"),
    ],
)
def test_encode_prints_the_exact_bytes(args: list[str], expected: str) -> None:
    result = run("encode", *args)
    assert result.exit_code == 0, result.stderr
    assert result.stdout.strip() == expected


def test_decode_finds_every_frame_and_reports_garbage() -> None:
    text = (
        "ff 00 "  # garbage
        "0x55,0x55,0x01,0x03,0x1c,0xdf "  # POS_READ request, 0x and commas
        "5555 01 05 1c f4 01 e8 "  # its reply: position 500
        "55 55 01 07 01 f4 01 e8 03 17 "  # bad checksum
        "55 55 fe 03 0e f0"  # ID_READ broadcast
    )
    result = run("decode", text)
    assert result.exit_code == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert lines[0] == "55 55 01 03 1c df  request POS_READ to id 1"
    assert lines[1].startswith("55 55 01 05 1c f4 01 e8  reply POS_READ from id 1:")
    assert "position_pulses=500" in lines[1]
    # The bad candidate in its place, with the checksum it should have.
    assert lines[2].startswith("55 55 01 07 01 f4 01 e8 03 17  bad checksum 0x17, expected 0x16")
    assert lines[3] == "55 55 fe 03 0e f0  request ID_READ to broadcast"
    assert lines[4] == (
        "3 frame(s) in 32 byte(s); 12 byte(s) skipped (not part of a valid frame); "
        "1 candidate frame(s) with a bad checksum"
    )


def test_decode_of_bytes_without_frames() -> None:
    result = run("decode", "00", "11")
    assert result.exit_code == 1  # nothing decoded is a failure, for scripts
    assert result.stdout.startswith("0 frame(s) in 2 byte(s)")
    assert result.stderr.strip() == "error: no valid frame in 2 byte(s)"


# ---------------------------------------------------------------------------- bad input


BAD_INPUT = [
    ["move", "254", "10"],  # ID out of range (254 is broadcast)
    ["move", "1", "130"],  # angle out of range
    ["move", "1", "-121"],
    ["move", "1", "10", "--time", "31"],  # time out of range
    ["move", "1", "10", "--time", "1", "--speed", "50"],
    ["move", "1"],
    ["move", "--pose", "1=0,1=5"],
    ["move", "--pose", "1=0,2=200"],
    ["info", "300"],
    ["stop", "1", "x"],
    ["torque", "sideways", "1"],
    ["set-id", "3", "3"],
    ["set-id", "1", "2", "3"],
    ["set-id", "254"],
    ["offset", "1", "31"],
    ["limits", "1", "--angle", "10", "-10"],
    ["limits", "1", "--vin", "4", "12"],
    ["limits", "1", "--temp", "120"],
    ["led", "1", "--alarms", "fire"],
    ["scan", "--ids", "0-300"],
    ["scan", "--margin-ms", "500"],
    ["monitor", "--ids", "1", "--count", "0"],
    ["frobnicate"],
    ["--retries", "99", "scan"],
    ["decode", "55 5g"],
    ["decode", "555"],
    ["encode", "MOVE_TIME_WRITE", "1", "1500", "0"],
    ["encode", "NOT_A_COMMAND", "1"],
    ["encode", "POS_READ", "255"],
    ["encode", "POS_READ", "1", "7"],
]


@pytest.mark.parametrize("args", BAD_INPUT, ids=" ".join)
def test_bad_input_is_one_error_exit_2_and_sends_nothing(
    args: list[str], sim_servos: SimFactory
) -> None:
    port, bus = sim_servos(servos(1, 2, 3))
    result = run(*args, port=port)
    assert_one_error(result, 2)
    assert (bus.frames_received, bus.frames_rejected) == (0, 0)
    # Control: one valid write now (broadcast: no presence check) is counted.
    assert run("--echo", "off", "stop", port=port).exit_code == 0
    assert (bus.frames_received, bus.frames_rejected) == (1, 0)


def test_bus_errors_exit_1() -> None:
    assert "does not answer" in assert_one_error(run("info", "7"), 1)
    assert "cannot open" in assert_one_error(run("scan", port="/nonexistent/ttyUSB9"), 1)
    echo_missing = run("--echo", "on", "--retries", "0", "stop", "1")
    assert "echo" in assert_one_error(echo_missing, 1)


# ---------------------------------------------------------------------------- bus commands


def test_ports_runs_on_this_machine() -> None:
    result = run("ports")
    assert result.exit_code == 0, result.stderr
    assert result.stdout.strip()


def _port(device: str, vid: int, pid: int, description: str) -> ListPortInfo:
    info = ListPortInfo(device)
    info.vid, info.pid, info.description = vid, pid, description
    return info


def test_ports_marks_servo_adapters(monkeypatch: pytest.MonkeyPatch) -> None:
    found = [_port("/dev/ttyUSB0", 0x1A86, 0x7523, "USB Serial"),
             _port("/dev/ttyACM0", 0x2341, 0x0043, "Arduino Uno")]
    monkeypatch.setattr(list_ports, "comports", lambda: found)
    result = run("ports")
    assert result.exit_code == 0, result.stderr
    usb = next(line for line in result.stdout.splitlines() if "ttyUSB0" in line)
    acm = next(line for line in result.stdout.splitlines() if "ttyACM0" in line)
    assert "1a86:7523" in usb and "yes: CH340" in usb
    assert "2341:0043" in acm and "yes" not in acm


def test_ports_with_no_ports(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(list_ports, "comports", lambda: [])
    result = run("ports")
    assert result.exit_code == 0, result.stderr
    assert "no serial ports found" in result.stdout


def test_scan_finds_the_arm() -> None:
    result = run("scan", "--ids", "0-20")
    assert result.exit_code == 0, result.stderr
    assert "found 6 servo(s): 1, 2, 3, 4, 5, 10" in result.stdout
    assert "11.10" in result.stdout  # supply voltage column


def test_scan_with_a_wider_margin_still_finds_the_arm() -> None:
    result = run("scan", "--ids", "0-20", "--margin-ms", "5")
    assert result.exit_code == 0, result.stderr
    assert "found 6 servo(s): 1, 2, 3, 4, 5, 10" in result.stdout


def test_scan_reports_duplicate_ids(sim_servos: SimFactory) -> None:
    now = CLOCK_START_S
    # Two servos on ID 3 at different positions: their position replies collide.
    twins = [SimServo(3, now=now), SimServo(3, position_pulses=400.0, now=now)]
    port, _ = sim_servos([*twins, SimServo(4, now=now)])
    result = run("scan", "--ids", "0-9", port=port)
    assert result.exit_code == 0, result.stderr
    assert "conflict: more than one servo answers at ID 3" in result.stdout


def test_monitor_count() -> None:
    result = run("monitor", "--ids", "1,2", "--count", "3", "--interval", "0")
    assert result.exit_code == 0, result.stderr
    assert [f"refresh {n}" in result.stdout for n in (1, 2, 3)] == [True] * 3
    assert "refresh 4" not in result.stdout
    assert re.search(r"│\s+2\s+│\s+\+0\.0\s+│\s+25\s+│\s+11\.10\s+│\s+off\s+│", result.stdout)


# ---------------------------------------------------------------------------- servo commands


def test_info_shows_every_field_and_no_reply(sim_servos: SimFactory) -> None:
    port, _ = sim_servos(servos(1, answers_wait_read=False))
    result = run("info", "1", port=port)
    assert result.exit_code == 0, result.stderr
    out = result.stdout
    for field in ("position", "last move", "angle offset", "angle limits", "voltage limits",
                  "temperature limit", "temperature", "voltage", "mode", "torque", "LED",
                  "LED alarms"):
        assert field in out
    assert re.search(r"waiting move.*no reply", out)
    assert "+0.0 deg (500 pulses)" in out
    assert "6.50..12.00 V" in out


def test_move_single_and_pose_with_wait(sim_servos: SimFactory) -> None:
    path, bus = sim_servos(servos(1, 2, 3))
    result = run("move", "2", "-30", "--time", "0.1", "--wait", port=path)
    assert result.exit_code == 0, result.stderr
    assert abs(bus.servo(2).position_pulses - 375) <= 1
    result = run("move", "--pose", "1=12,3=-24", "--speed", "400", "--wait", port=path)
    assert result.exit_code == 0, result.stderr
    assert "reached" in result.stdout
    assert abs(bus.servo(1).position_pulses - 550) <= 1
    assert abs(bus.servo(3).position_pulses - 400) <= 1


def test_stop_and_torque(sim_servos: SimFactory) -> None:
    path, bus = sim_servos(servos(1, 2))
    assert run("torque", "on", port=path).exit_code == 0
    assert bus.servo(1).is_loaded and bus.servo(2).is_loaded
    assert run("torque", "off", "2", port=path).exit_code == 0
    assert not bus.servo(2).is_loaded
    assert bus.servo(1).is_loaded
    assert run("move", "1", "100", "--time", "5", port=path).exit_code == 0
    sleep_and_advance(bus, 1.0)  # a fifth of the way
    result = run("stop", port=path)
    assert result.exit_code == 0 and "stopped all servos" in result.stdout
    sleep_and_advance(bus, 0.1)
    held = bus.servo(1).position_pulses
    sleep_and_advance(bus, 0.1)
    assert 500 < bus.servo(1).position_pulses == held < 600


def test_set_id_refuses_two_servos(sim_servos: SimFactory) -> None:
    path, bus = sim_servos(servos(1, 2))
    message = assert_one_error(run("set-id", "7", port=path), 1)
    assert "2 servos on the bus" in message
    assert [s.servo_id for s in bus.servos] == [1, 2]


def test_set_id_refuses_duplicate_ids(sim_servos: SimFactory) -> None:
    now = CLOCK_START_S
    path, bus = sim_servos([SimServo(3, now=now), SimServo(3, position_pulses=420.0, now=now)])
    assert "more than one servo" in assert_one_error(run("set-id", "3", "7", port=path), 1)
    assert "more than one servo" in assert_one_error(run("set-id", "7", port=path), 1)
    assert [s.servo_id for s in bus.servos] == [3, 3]


def test_set_id_with_one_servo(sim_servos: SimFactory) -> None:
    path, bus = sim_servos(servos(3))
    result = run("set-id", "7", port=path)
    assert result.exit_code == 0, result.stderr
    assert "servo 3 is now ID 7" in result.stdout
    assert bus.servos[0].servo_id == 7
    assert run("set-id", "7", "9", port=path).exit_code == 0
    assert bus.servos[0].servo_id == 9


def test_offset_limits_led_write_and_read_back() -> None:
    result = run("offset", "1", "-4.8", "--save")
    assert result.exit_code == 0, result.stderr
    assert "-4.80 deg (saved)" in result.stdout
    result = run("limits", "1", "--angle", "-90", "90", "--vin", "6", "11.5", "--temp", "70")
    assert result.exit_code == 0, result.stderr
    for text in ("-90.0 deg", "+90.0 deg", "6.00 V", "11.50 V", "70 C"):
        assert text in result.stdout
    result = run("led", "1", "off", "--alarms", "over-temperature,stalled")
    assert result.exit_code == 0, result.stderr
    assert "LED off, flashes on: over-temperature, stalled" in result.stdout
    assert "flashes on: none" in run("led", "1", "--alarms", "none").stdout


# ---------------------------------------------------------------------------- demo


def _table(text: str) -> list[tuple[str, list[str]]]:
    """The tool path table's rows in order: the step, and the cells after it (t, x, y, z,
    pitch, off line)."""
    return [(line.split("│")[1].strip(), line.split("│")[2:-1])
            for line in text.splitlines() if line.count("│") == 8]


def _table_rows(text: str) -> dict[str, list[str]]:
    """The tool path table's rows, by step."""
    return dict(_table(text))


def test_demo_picks_and_places_along_straight_lines() -> None:
    """The demo's pick-and-place and its tool path table, on the demo's arm (servos 1-5
    and 10, a block between the fingers) in this process on its simulated clock, with
    wire timing (its reads take time, so the path is measured along each move)."""
    sim = SimBus.with_ids(ARM_SERVO_IDS, timing=WireTiming())
    sim.put_block_in_gripper()
    with ServoBus(SimTransport(sim)) as bus:
        arm = Arm(bus, load_arm_config())
        path = demo._ToolPath(arm, 300.0)
        demo._pick_and_place(arm, path)
    console = Console(width=120, record=True, file=io.StringIO())
    console.print(path.table)
    text = console.export_text()
    assert "grip: holding the block" in text
    rows = _table_rows(text)
    for step in ("down to grasp", "lift", "carry", "lower", "retreat"):
        off_line_mm = float(rows[step][-1])
        assert off_line_mm < 2.0, (step, off_line_mm)
    x, y, z = (float(v) for v in rows["down to grasp"][1:4])
    assert abs(x - 200) < 2 and abs(y + 110) < 2 and abs(z - 15) < 2
    # Measured along the way, not only at the end: the rows between "lift" and "carry"
    # go from the pick's side (y -110) towards the place's (y +120).
    table = _table(text)
    lift = next(k for k, (step, _) in enumerate(table) if step == "lift")
    ys = [float(cells[2]) for _, cells in table[lift + 1:lift + 4]]
    assert min(ys) > -100 and max(ys) < 110 and ys == sorted(ys), ys


@pytest.mark.wallclock("`demo` serves its own simulated arm on a real pseudo-terminal, "
                       "in wall-clock time")
def test_demo_serves_its_own_arm_on_a_pty(monkeypatch: pytest.MonkeyPatch) -> None:
    """The command: no --port needed, its arm scanned through the pty, driven there, and
    the tool path printed. (The whole pick-and-place takes 10 s on the wall clock; the
    test above runs it on the simulated clock, so here only the grip, the block the demo
    put between the fingers felt through the pty.)"""
    gripped: list[bool] = []

    def grip_only(arm: Arm, path: demo._ToolPath) -> None:
        path.row("start")
        gripped.append(arm.grip().is_holding)

    monkeypatch.setattr(demo, "_pick_and_place", grip_only)
    result = CliRunner(mix_stderr=False).invoke(
        cli, ["--timeout-margin-ms", "200", "demo", "--no-timing"], env={"BUSARM_PORT": None})
    assert result.exit_code == 0, result.stderr
    assert "no --port given" not in result.stderr  # the demo runs its own simulator
    assert re.search(r"simulated arm on pseudo-terminal /dev/\S+", result.stdout)
    assert "found 6 servo(s): 1, 2, 3, 4, 5, 10" in result.stdout
    assert gripped == [True]
    assert "tool path (measured" in result.stdout and "start" in _table_rows(result.stdout)
    assert re.search(r"done in [\d.]+ s \(retries: \d+, timeouts: \d+", result.stdout)


# ---------------------------------------------------------------------------- subprocesses


def _busarm() -> list[str]:
    script = Path(sys.executable).with_name("busarm")
    return [str(script)] if script.exists() else [sys.executable, "-m", "busarm"]



def _sigint_and_wait(proc: subprocess.Popen[str]) -> tuple[int, str, str]:
    return sigint_and_wait(proc, 30)


@pytest.mark.wallclock("`sim serve` and `monitor` as processes, on a real pty, stopped "
                       "with SIGINT")
def test_sim_serve_and_monitor_as_subprocesses() -> None:
    env = {**os.environ, "COLUMNS": "120"}
    server = subprocess.Popen(
        [sys.executable, "-m", "busarm", "sim", "serve"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    try:
        assert server.stdout is not None
        path = server.stdout.readline().strip()
        assert path.startswith("/dev/"), path
        scan = subprocess.run(
            [*_busarm(), "--port", path, *MARGIN, "scan", "--ids", "0-20"],
            capture_output=True, text=True, timeout=30, env=env,
        )
        assert scan.returncode == 0, scan.stderr
        assert "found 6 servo(s): 1, 2, 3, 4, 5, 10" in scan.stdout

        monitor = subprocess.Popen(
            [*_busarm(), "--port", path, *MARGIN, "monitor", "--ids", "1,10", "--interval",
             "0.05"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
            # Ctrl+C must reach it even when the tests run as a background job (which
            # starts every child with SIGINT ignored).
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        assert monitor.stdout is not None
        while "refresh 2" not in monitor.stdout.readline():
            assert monitor.poll() is None, monitor.communicate()
        code, _, err = _sigint_and_wait(monitor)
        assert code == 130, err
        # It only read: no stop sent, and nothing said of stopping.
        assert "interrupted: nothing was written to the servos" in err
        assert "Traceback" not in err
    finally:
        code, _, err = _sigint_and_wait(server)
    assert code == 0, err
    assert "Traceback" not in err
    assert f"on {path}" in err


# ---------------------------------------------------------------------------- safety checks


def test_writes_to_a_missing_servo_fail_and_write_nothing(sim_servos: SimFactory) -> None:
    path, bus = sim_servos(servos(1))
    assert run("move", "1", "100", "--time", "5", port=path).exit_code == 0
    cases = [(["move", "7", "10"], 1), (["stop", "7"], 1), (["torque", "off", "7"], 1),
             (["limits", "7", "--temp", "70"], 1), (["led", "7", "off"], 1),
             (["offset", "7", "3"], 1), (["stop", "1", "7"], 2)]
    for args, reads in cases:
        before = bus.frames_received
        result = run("--echo", "off", "--retries", "0", *args, port=path)
        assert assert_one_error(result, 1) == "error: no servo answers at ID 7", args
        # Only the presence checks (one read per ID) reached the bus: no write, no stop.
        assert bus.frames_received - before == reads, args
    assert bus.servo(1).is_loaded
    bus.advance()  # the simulation advances when asked
    position = bus.servo(1).position_pulses
    sleep_and_advance(bus, 0.05)
    assert bus.servo(1).position_pulses > position  # still moving: nothing stopped it


def test_move_outside_the_servos_angle_limits_is_refused(sim_servos: SimFactory) -> None:
    path, bus = sim_servos(servos(1, 2))
    assert run("limits", "2", "--angle", "-30", "30", port=path).exit_code == 0
    before = bus.frames_received
    message = assert_one_error(run("--echo", "off", "move", "2", "60", port=path), 2)
    assert "+60.0 deg for servo 2" in message and "-30.0..+30.0 deg" in message
    message = assert_one_error(run("--echo", "off", "move", "--pose", "1=60,2=-45",
                                   port=path), 2)
    assert "servo 2" in message
    assert bus.frames_received - before == 3  # the limit reads only
    assert bus.servo(1).position_pulses == bus.servo(2).position_pulses == 500
    result = run("move", "2", "30", "--time", "0", "--wait", port=path)
    assert result.exit_code == 0, result.stderr


def test_vin_limits_that_would_unload_the_servo_need_force() -> None:
    message = assert_one_error(run("limits", "1", "--vin", "6", "11"), 2)
    assert "11.10 V" in message and "6..11 V" in message and "--force" in message
    assert "12.00 V" in run("limits", "1").stdout
    result = run("limits", "1", "--vin", "6", "11", "--force")
    assert result.exit_code == 0, result.stderr
    assert "11.00 V" in result.stdout


def test_monitor_ctrl_c_leaves_the_arm_as_it_was(
    sim_servos: SimFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, bus = sim_servos(servos(1))

    def interrupted(*args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(bus_cmds, "_monitor_loop", interrupted)
    assert run("move", "1", "100", "--time", "5", port=path).exit_code == 0
    result = run("monitor", "--ids", "1", port=path)
    assert result.exit_code == 130, result.stderr
    # It only reads: another program's move goes on, and nothing is said of stopping (the
    # `move` before it in this process was another command: it wrote, the monitor did not).
    line = result.stderr.strip()
    assert line == "interrupted: nothing was written to the servos", line
    assert not any(word in line for word in ("MOVE_STOP", "stopped", "holding")), line
    bus.advance()
    position = bus.servo(1).position_pulses
    sleep_and_advance(bus, 0.1)
    assert bus.servo(1).position_pulses > position


def test_ctrl_c_during_a_command_says_the_servos_stopped(
    sim_servos: SimFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    path, bus = sim_servos(servos(1))

    def interrupted(*args: object, **kwargs: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(ServoBus, "wait_until_reached", interrupted)
    result = run("move", "1", "100", "--time", "5", "--wait", port=path)
    assert result.exit_code == 130, result.stderr
    assert result.stderr.strip() == ("interrupted: all servos stopped (MOVE_STOP); servo 1 "
                                     "holding position (torque on)")
    sleep_and_advance(bus, 0.05)
    held = bus.servo(1).position_pulses
    sleep_and_advance(bus, 0.1)
    assert bus.servo(1).position_pulses == held < 600


def test_default_simulator_note() -> None:
    def invoke(*args: str, **env: str | None) -> Result:
        return CliRunner(mix_stderr=False).invoke(cli, list(args), env=env)

    note = ("note: no --port given: using a simulated arm that lives for this one command (it "
            "starts straight up every time); to keep one between commands, run `busarm sim "
            "serve` in another terminal")
    result = invoke("stop", BUSARM_PORT=None)
    assert result.exit_code == 0 and result.stderr.strip() == note, result.stderr
    assert note not in invoke("--port", "sim", "stop", BUSARM_PORT=None).stderr
    assert note not in invoke("stop", BUSARM_PORT=SIM).stderr
    for args in (["encode", "POS_READ", "1"], ["decode", "55 55 01 03 1c df"], ["ports"]):
        result = invoke(*args, BUSARM_PORT=None)
        assert note not in result.stderr, args
