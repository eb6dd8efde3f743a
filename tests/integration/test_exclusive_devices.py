"""Exclusive devices (issue 29): a robot's serial device has one driver at a time.

A second program opening a device another holds is refused at once, told the holder's PID
and command line, and writes nothing: the first goes on undisturbed. The robot is served
on a real pty (the simulated servos, and the simulated controller board in front of them
for the base); the first program is this one, the second a real ``busarm`` process (the
process holding the device is the subject: its PID is in the message). The lock dies with
its holder, even one killed by SIGKILL.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from busarm.bus.device_lock import DeviceInUseError, command_line, lock_device, locks_dir
from busarm.bus.driver import ServoBus
from busarm.clock import WALL_CLOCK
from busarm.errors import TransportError
from busarm.protocol import Command
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.pty import PtyServer
from conftest import PTY_MARGIN_S, ListeningSim, open_board_bus, process_env

PTY_WAY = pytest.mark.wallclock(
    "a robot served on a real pty in wall-clock time, opened by this process and by real "
    "`busarm` processes: the process holding the device is the subject")
MARGIN = ("--timeout-margin-ms", "300")
"""For a command at a pty on a computer that may be busy (PTY_MARGIN_S's reason)."""
RUN_TIMEOUT_S = 60.0
"""Only a failing test waits it out: a busy computer may take seconds to start Python."""


def busarm(*args: str) -> subprocess.CompletedProcess[str]:
    """``busarm ARGS`` run to its end as a process of its own (this one's runtime folder,
    whose locks it shares)."""
    return subprocess.run([sys.executable, "-m", "busarm", *args], capture_output=True,
                          text=True, timeout=RUN_TIMEOUT_S, env=process_env({}))


def refused_line(result: subprocess.CompletedProcess[str], device: str) -> str:
    """The one error line of a command refused ``device`` while this process holds it."""
    assert result.returncode == 1, (result.returncode, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith("error: "), lines
    assert f"{device} is in use by PID {os.getpid()} ({command_line()})" in lines[0], lines
    return lines[0]


@PTY_WAY
def test_a_second_program_is_refused_the_arm_and_the_first_goes_on() -> None:
    sim = ListeningSim.with_ids(timing=WireTiming(enabled=False), clock=WALL_CLOCK)
    assert isinstance(sim, ListeningSim)
    with PtyServer(sim) as server, ServoBus.open(
            server.path, timeout_margin_s=PTY_MARGIN_S) as first:
        first.move_deg(1, 90.0, 20.0)  # slow: still under way while the second one tries
        first.read_temp_c(1)  # answered: the move, sent before it, reached the servo
        heard = len(sim.heard)
        line = refused_line(busarm("--port", server.path, *MARGIN, "move", "1", "-90",
                                   "--time", "0"), server.path)
        assert "one program drives a robot at a time" in line
        # The first one's next request is all the servos heard since: any byte the second
        # had written would have come before it (one pty, in order).
        assert 0.0 < first.read_position_deg(1) < 90.0  # still on its way to +90
        assert sim.heard[heard:] == [Command.POS_READ]
        first.stop()


@PTY_WAY
def test_a_second_program_is_refused_the_base_and_the_wheels_go_on(
        monkeypatch: pytest.MonkeyPatch) -> None:
    first, board, server = open_board_bus(SimBus.with_ids(timing=WireTiming(),
                                                          clock=WALL_CLOCK))
    heard = bytearray()  # every byte the host sends the board from now on
    receive = board.receive

    def hearing(data: bytes) -> None:
        heard.extend(data)
        receive(data)

    monkeypatch.setattr(board, "receive", hearing)
    try:
        first.link.set_motor_speeds(dict.fromkeys(range(1, 5), 1.0))
        first.read_temp_c(1)  # answered: the speeds, sent before it, reached the board
        before = len(heard)
        first.read_temp_c(1)
        one_read = bytes(heard[before:])
        before = len(heard)
        refused_line(busarm("--port", "board://" + server.path, *MARGIN, "base", "stop"),
                     server.path)
        # The same device without the board's framing is the same device.
        with pytest.raises(DeviceInUseError, match=re.escape(
                f"{server.path} is in use by PID {os.getpid()} ({command_line()}), this "
                "program itself")):
            ServoBus.open(server.path)
        assert [wheel.target_rev_s for wheel in board.wheels] == [1.0] * 4  # not stopped
        first.read_temp_c(1)
        assert bytes(heard[before:]) == one_read  # nothing but the first one's read
        first.link.stop_motors()
    finally:
        first.close()
        server.stop()


@PTY_WAY
def test_the_lock_dies_with_its_holder_killed() -> None:
    sim = SimBus.with_ids(timing=WireTiming(enabled=False), clock=WALL_CLOCK)
    with PtyServer(sim) as server:
        args = ("--port", server.path, *MARGIN, "monitor", "--ids", "1", "--interval", "0.05")
        holder = subprocess.Popen([sys.executable, "-m", "busarm", *args], text=True,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  env=process_env({}))
        try:
            assert holder.stdout is not None
            while "refresh 1" not in holder.stdout.readline():  # it has the arm
                assert holder.poll() is None, holder.communicate()
            with pytest.raises(DeviceInUseError) as refused:
                ServoBus.open(server.path)
            assert refused.value.pid == holder.pid
            assert (f"{server.path} is in use by PID {holder.pid} (busarm {shlex.join(args)})"
                    in str(refused.value))
            holder.send_signal(signal.SIGKILL)  # no chance to let go of anything itself
            holder.communicate(timeout=RUN_TIMEOUT_S)
        finally:
            if holder.poll() is None:
                holder.kill()
                holder.communicate()
        assert holder.returncode == -signal.SIGKILL
        with ServoBus.open(server.path, timeout_margin_s=PTY_MARGIN_S) as bus:  # at once
            assert bus.read_position_deg(1) == 0.0


@PTY_WAY
def test_the_same_program_opening_twice_is_refused_and_close_lets_go(tmp_path: Path) -> None:
    sim = ListeningSim.with_ids(timing=WireTiming(enabled=False), clock=WALL_CLOCK)
    assert isinstance(sim, ListeningSim)
    with PtyServer(sim) as server:
        first = ServoBus.open(server.path, timeout_margin_s=PTY_MARGIN_S)
        heard = len(sim.heard)
        mine = re.escape(f"{server.path} is in use by PID {os.getpid()} ({command_line()}), "
                         "this program itself")
        with pytest.raises(DeviceInUseError, match=mine):
            ServoBus.open(server.path)
        link = tmp_path / "arm"
        link.symlink_to(server.path)  # another name of it: the lock is the device's
        with pytest.raises(DeviceInUseError, match=f"{link} \\({server.path}\\) is in use"):
            ServoBus.open(str(link))
        first.read_temp_c(1)
        assert sim.heard[heard:] == [Command.TEMP_READ]  # the refused wrote nothing
        first.close()
        first.close()  # a second close lets go of nothing more
        with ServoBus.open(server.path, timeout_margin_s=PTY_MARGIN_S) as again:
            again.read_temp_c(1)
        with ServoBus.open(str(link), timeout_margin_s=PTY_MARGIN_S) as again:
            again.read_temp_c(1)


def test_a_lock_file_names_its_holder_and_is_emptied_when_let_go(tmp_path: Path) -> None:
    device = tmp_path / "ttyFAKE0"
    device.touch()
    with lock_device(str(device)) as lock:
        assert lock.held and lock.path.parent == locks_dir()
        assert f'"pid": {os.getpid()}' in lock.path.read_text()
        with pytest.raises(DeviceInUseError) as refused:
            lock_device(str(device))
        assert refused.value.pid == os.getpid() and refused.value.command == command_line()
    assert not lock.held and lock.path.read_text() == ""
    with lock_device(str(device)):
        pass


def test_pyserial_urls_name_no_device_of_this_computer_and_take_no_lock() -> None:
    with ServoBus.open("loop://") as first, ServoBus.open("loop://") as second:
        assert first.transport.name == second.transport.name == "loop://"


def test_a_lock_folder_that_cannot_be_made_is_one_clear_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    not_a_folder = tmp_path / "run"
    not_a_folder.write_text("")
    monkeypatch.setenv("BUSARM_RUNTIME_DIR", str(not_a_folder))
    with pytest.raises(TransportError, match=r"cannot lock /dev/null: no lock folder .*set "
                                             r"\$BUSARM_RUNTIME_DIR to a folder of yours"):
        ServoBus.open("/dev/null")
