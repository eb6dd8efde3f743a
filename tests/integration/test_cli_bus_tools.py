"""The bus and protocol commands as a person meets them: a wrong echo setting, a scan
that finds nothing, a port that is no serial device, IDs out of range, servo moves past
the arm's joint limits, and the offline ``decode``/``encode`` tools.

The CLI runs in this process (click's CliRunner) against the in-process simulator, or
simulated servos of the test's own (``sim_bus``, opened by the commands from one run to
the next as a served arm), on their simulated clock: their counters show exactly what
reached the bus. ``decode -`` also reads the standard input of a real process.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from busarm.bus.driver import ServoBus
from busarm.cli.main import cli
from busarm.errors import ConfigError
from busarm.protocol import Command
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.spec import SimSpec
from conftest import in_process_port

SIM = "sim://?timing=0"
ECHOING_SIM = "sim://?timing=0&echo=1"


def run(*args: str, port: str = SIM, stdin: str | None = None) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", port, *args], input=stdin)


def one_error(result: Result, code: int) -> str:
    """The single ``error:`` line on stderr of a run that exited ``code``; no traceback."""
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


@pytest.fixture
def sim_bus(monkeypatch: pytest.MonkeyPatch) -> tuple[str, SimBus]:
    """Servos 1-5 and 10 whose adapter does not echo, on their simulated clock, and the
    port by which commands run in this process open them: (port, SimBus)."""
    bus = SimBus.with_ids([1, 2, 3, 4, 5, 10], timing=WireTiming(enabled=False))
    url = in_process_port(monkeypatch, bus)
    return url, bus


# ---------------------------------------------------------------------------- echo


NO_ECHO = "the replies look like the adapter does not echo: try --echo off (or auto)"


def test_echo_on_with_an_adapter_that_does_not_echo_scan_says_so() -> None:
    result = run("--echo", "on", "scan", "--ids", "0-12")
    message = one_error(result, 1)
    assert NO_ECHO in message and "servo 1 answers" in message
    assert "conflict" not in result.stdout  # not taken for duplicate IDs any more


def test_echo_on_with_an_adapter_that_does_not_echo_info_says_so(
    sim_bus: tuple[str, SimBus],
) -> None:
    path, _ = sim_bus
    result = run("--echo", "on", "info", "1", port=path)
    message = one_error(result, 1)
    assert "servo 1 answered POS_READ, but our own request did not come back" in message
    assert NO_ECHO in message
    assert "bad reply" not in result.stdout  # no table of nothing


def test_echo_off_on_an_echoing_adapter_warns_once_and_works() -> None:
    result = run("--echo", "off", "scan", "--ids", "0-12", port=ECHOING_SIM)
    assert result.exit_code == 0, result.stderr
    assert "found 6 servo(s)" in result.stdout
    warning = (f"warning: {ECHOING_SIM}: the adapter echoes what it sends, but echo is set "
               "off: use --echo on (or auto)")
    assert result.stderr.count(warning) == 1, result.stderr


def test_echo_auto_and_on_with_an_echoing_adapter_say_nothing() -> None:
    for echo in ("auto", "on"):
        result = run("--echo", echo, "info", "1", port=ECHOING_SIM)
        assert result.exit_code == 0, result.stderr
        assert "warning" not in result.stderr and "+0.0 deg (500 pulses)" in result.stdout


# ---------------------------------------------------------------------------- scan, ports, IDs


def test_a_scan_that_finds_nothing_exits_1_with_what_to_check() -> None:
    result = run("scan", "--ids", "20-30")
    message = one_error(result, 1)
    assert "found 0 servo(s)" in result.stdout
    assert message.startswith(f"error: no servo answered on {SIM} at 115200 baud")
    for hint in ("powered", "--baud", "--echo", "--port", "`busarm ports`"):
        assert hint in message, hint


def test_scan_ids_beyond_253_say_the_range_once() -> None:
    message = one_error(run("scan", "--ids", "1-300"), 2)
    assert "'1-300' is outside the servo IDs 0-253 (254 is the broadcast ID)" in message
    assert message.count("253") == 1 and "254 is out of range" not in message


@pytest.mark.parametrize(("args", "bad"), [
    (["info", "-1"], "-1"), (["stop", "1", "-3"], "-3"), (["torque", "on", "-2"], "-2"),
    (["set-id", "-1", "3"], "-1"),
])
def test_a_negative_id_is_a_range_error_not_an_unknown_option(args: list[str], bad: str) -> None:
    message = one_error(run(*args), 2)
    assert f"servo ID {bad} is out of range 0..253" in message
    assert "No such option" not in message


def test_a_port_that_is_no_serial_device_says_what_it_is(tmp_path: Path) -> None:
    regular = tmp_path / "capture.bin"
    regular.write_bytes(b"")
    cases = [(regular, "it is a regular file, not a serial device"),
             (tmp_path, "it is a directory, not a serial device"),
             (tmp_path / "ttyUSB9", "it does not exist (is the adapter plugged in?"),
             (Path("/dev/null"), "it is not a serial device")]
    for port, what in cases:
        message = one_error(run("scan", port=str(port)), 1)
        assert message.startswith(f"error: cannot open '{port}': {what}"), message
        assert "`busarm ports`" in message
        assert "Errno" not in message and "ioctl" not in message


def test_read_state_of_a_string_id_is_a_type_error_naming_it() -> None:
    with ServoBus.open(SimSpec(timing=False)) as bus, pytest.raises(ConfigError) as caught:
        bus.read_state("1")  # type: ignore[arg-type]
    assert str(caught.value) == "servo ID must be an integer 0..253, got '1' (a str)"


# ---------------------------------------------------------------------------- arm limits


def test_servo_move_past_its_joints_limits_is_refused_sending_nothing(
    sim_bus: tuple[str, SimBus],
) -> None:
    path, bus = sim_bus
    message = one_error(run("move", "2", "100", port=path), 2)
    assert message == (
        "error: servo 2 is joint shoulder_pitch of the JetAuto Pro arm: +100.0 deg is "
        "outside its limits -90.0..+90.0 deg (servo angle); --ignore-arm-limits moves it "
        "anyway"
    )
    message = one_error(run("move", "--pose", "1=10,10=60", port=path), 2)
    assert "servo 10 is the gripper of the JetAuto Pro arm" in message
    assert "-72.0..+48.0 deg" in message
    assert bus.frames_received == 0
    assert bus.servo(2).position_pulses == 500


def test_ignore_arm_limits_moves_anyway_and_is_documented(sim_bus: tuple[str, SimBus]) -> None:
    path, bus = sim_bus
    result = run("move", "2", "100", "--time", "0", "--wait", "--ignore-arm-limits", port=path)
    assert result.exit_code == 0, result.stderr
    # Past the joint's +90 deg (875 pulses), at +100 deg but for the load's few pulses.
    assert 500 + 90 / 0.24 < bus.servo(2).position_pulses <= 500 + 100 / 0.24 + 1
    assert abs(bus.servo(2).position_pulses - (500 + 100 / 0.24)) <= 4
    help_text = run("move", "--help").stdout
    assert "--ignore-arm-limits" in help_text and "joint's limits" in help_text


# ---------------------------------------------------------------------------- decode, encode


def test_decode_takes_each_token_as_its_own_byte() -> None:
    result = run("decode", "55", "55", "1", "3", "1c", "df")  # 1 3 is 01 03, not 0x13
    assert result.exit_code == 0, result.stderr
    assert result.stdout.splitlines()[0] == "55 55 01 03 1c df  request POS_READ to id 1"
    joined = run("decode", "1 3")
    assert one_error(joined, 1) == "error: no valid frame in 2 byte(s)"
    assert joined.stdout.startswith("0 frame(s) in 2 byte(s)")


def test_decode_still_takes_one_run_without_spaces() -> None:
    result = run("decode", "555501031cdf")
    assert result.exit_code == 0, result.stderr
    assert result.stdout.splitlines() == [
        "55 55 01 03 1c df  request POS_READ to id 1", "1 frame(s) in 6 byte(s)"]
    assert "odd number of hex digits (3)" in one_error(run("decode", "55", "555"), 2)


def test_decode_shows_the_checksum_a_bad_frame_should_have() -> None:
    result = run("decode", "55 55 fe 03 0e f0 55 55 01 07 01 f4 01 e8 03 17")
    assert result.exit_code == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "55 55 fe 03 0e f0  request ID_READ to broadcast"
    assert lines[1].startswith(
        "55 55 01 07 01 f4 01 e8 03 17  bad checksum 0x17, expected 0x16 (with the right "
        "one: request MOVE_TIME_WRITE to id 1: position_pulses=500 time_ms=1000)")
    bad_only = run("decode", "55 55 01 07 01 f4 01 e8 03 17")
    assert one_error(bad_only, 1) == "error: no valid frame in 10 byte(s)"
    assert "expected 0x16" in bad_only.stdout


@pytest.mark.wallclock("the standard input of a real process (a pipe from `encode`)")
def test_decode_reads_standard_input_given_as_dash() -> None:
    encoded = run("encode", "POS_READ", "1")
    assert encoded.exit_code == 0, encoded.stderr
    decoded = subprocess.run(
        [sys.executable, "-m", "busarm", "decode", "-"],
        input=encoded.stdout + "5555fe030ef0\n", capture_output=True, text=True,
        check=False, timeout=60,
    )
    assert decoded.returncode == 0, decoded.stderr
    assert decoded.stdout.splitlines() == [
        "55 55 01 03 1c df  request POS_READ to id 1",
        "55 55 fe 03 0e f0  request ID_READ to broadcast",
        "2 frame(s) in 12 byte(s)",
    ]
    assert one_error(run("decode", "-", stdin="00 11\n"), 1).endswith("in 2 byte(s)")
    assert "not both" in one_error(run("decode", "-", "55"), 2)


def test_encode_help_lists_every_command_and_its_args() -> None:
    result = run("encode", "--help")
    assert result.exit_code == 0, result.stderr
    for command in Command:
        assert f"{command.name} ({command.value})" in result.stdout, command.name
    assert "position_pulses 0..1000, time_ms 0..30000" in result.stdout
