"""Power off and on: what the servos store survives a simulator restart, the rest does not.

Settings are written through the driver; the simulator is then rebuilt from its state
file, as a servo powers on from its EEPROM. The last test kills ``busarm sim serve``
with SIGKILL while the driver keeps writing stored settings: the file must still load,
holding for each servo either the settings before or after the write in flight.

The simulator in this process (``SimSpec``) is on a simulated clock; a pty, and ``busarm
sim serve`` in its own process, serve in wall-clock time, and there every stored write
makes the simulator save its file (two fsyncs, tens of ms, more on a busy disk) before
it answers the next request: the buses there wait for replies with a generous margin.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest

from busarm.bus.driver import ServoBus
from busarm.clock import WALL_CLOCK
from busarm.errors import BusTimeoutError, ProtocolError, TransportError
from busarm.protocol import AlarmFlag, ServoMode
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.spec import SimSpec
from busarm.sim.storage import load_state
from conftest import PTY_MARGIN_S

STORED_WRITE_MARGIN_S = 0.3
"""The reply margin on a pty: a reply may wait for the simulator's save of its file after
a stored write (the deadline is not what these tests are about; a late reply is also
asked for again, twice). Not more: ``set_id`` asks a silent ID again with it."""
KILL_MARGIN_S = 1.0
"""The reply margin while hammering ``sim serve`` until SIGKILL: the loop must end by the
kill alone, and costs nothing while the server answers (once killed, the pty is gone)."""
PTY = pytest.param("pty", marks=pytest.mark.wallclock(
    "a pty served by a thread in wall-clock time: power-off through a real device file"))


@contextlib.contextmanager
def arm_from_state(kind: str, state: Path) -> Iterator[ServoBus]:
    """The arm powered on from ``state``: the simulator in this process, or a pty."""
    if kind == "inproc":
        bus = ServoBus.open(SimSpec(state=state))
        try:
            yield bus
        finally:
            bus.close()
        return
    sim = SimBus.with_ids(state_file=state, timing=WireTiming(), clock=WALL_CLOCK)
    with PtyServer(sim) as server:
        bus = ServoBus.open(server.path, timeout_margin_s=STORED_WRITE_MARGIN_S)
        try:
            yield bus
        finally:
            bus.close()


@pytest.mark.parametrize("kind", ["inproc", PTY])
def test_stored_settings_survive_a_restart_and_volatile_ones_do_not(
    kind: str, tmp_path: Path
) -> None:
    state = tmp_path / "servos.json"
    with arm_from_state(kind, state) as bus:
        assert not state.exists(), "nothing stored yet"
        # Stored: ID, saved offset, angle / voltage / temperature limits, LED.
        bus.set_id(5, 6)
        bus.adjust_offset_deg(1, 7.2)
        bus.save_offset(1)
        bus.write_angle_limits_deg(3, -60.0, 48.0)
        bus.write_vin_limits_v(3, 6.8, 11.6)
        bus.write_temp_limit_c(3, 75)
        bus.set_led(4, False)
        # Volatile: an offset not saved, motor mode, torque, the alarm mask.
        bus.adjust_offset_deg(2, -4.8)
        bus.set_motor_speed(10, 300)
        bus.set_torque(4, True)
        bus.write_alarm_mask(1, AlarmFlag.OVER_VOLTAGE)
        # Read back before the restart, so the checks below cannot pass by default.
        assert bus.read_offset_deg(2) == pytest.approx(-4.8)
        assert bus.read_mode(10).mode is ServoMode.MOTOR
        assert bus.read_torque(4) is True
        assert bus.read_alarm_mask(1) == AlarmFlag.OVER_VOLTAGE
        # The horn of unloaded servo 1 did not turn, so its reading shifted by the offset.
        assert bus.read_position_pulses(1) == 500 - 30
        bus.set_motor_speed(10, 0)  # stop turning, so the horn is where the file says
    assert state.exists()

    with arm_from_state(kind, state) as bus:
        # (A scan's own deadline is short: on a pty, with the margin of one whose deadline
        # is not the subject.)
        assert bus.scan(range(12), margin_s=PTY_MARGIN_S).found == [1, 2, 3, 4, 6, 10]
        assert bus.read_offset_deg(1) == pytest.approx(7.2)
        assert bus.read_position_pulses(1) == 500 - 30
        assert bus.read_angle_limits_deg(3) == pytest.approx((-60.0, 48.0))
        assert bus.read_vin_limits_v(3) == pytest.approx((6.8, 11.6))
        assert bus.read_temp_limit_c(3) == 75
        assert bus.read_led(4) is False
        assert bus.read_led(1) is True
        # Volatile settings are back to their power-on values.
        assert bus.read_offset_deg(2) == 0.0
        mode = bus.read_mode(10)
        assert (mode.mode, mode.motor_speed) == (ServoMode.POSITION, 0)
        assert bus.read_torque(4) is False
        assert bus.read_torque(10) is False
        assert bus.read_alarm_mask(1) == AlarmFlag(7)
        # Untouched servos kept the defaults.
        assert bus.read_angle_limits_deg(2) == pytest.approx((-120.0, 120.0))
        assert bus.read_temp_limit_c(6) == 85


def test_unsaved_offset_is_lost_even_after_other_stored_writes(tmp_path: Path) -> None:
    state = tmp_path / "servos.json"
    with arm_from_state("inproc", state) as bus:
        bus.adjust_offset_deg(2, 12.0)
        bus.set_led(2, False)  # a stored write: the file is rewritten, the offset not saved
    with arm_from_state("inproc", state) as bus:
        assert bus.read_offset_deg(2) == 0.0
        assert bus.read_led(2) is False


# ---------------------------------------------------------------------- SIGKILL


OLD = (-60.0, 60.0)  # 250..750 pulses
NEW = (-12.0, 24.0)  # 450..600 pulses
PULSES = {(250, 750): OLD, (450, 600): NEW}


GOING = 5
"""Write rounds answered before the kill is timed: the writes have got going."""


def _hammer_then_kill(state: Path, kill_after_s: float) -> int:
    """Serve ``state``, write OLD, then alternate NEW/OLD, with SIGKILL ``kill_after_s``
    after GOING rounds were answered; return how many rounds were sent."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "sim", "serve", "--ids", "1,2", "--state", str(state)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    killed = threading.Event()

    def kill() -> None:
        killed.set()  # first: the loop may see the server gone before kill() returns
        proc.kill()  # SIGKILL

    timer = threading.Timer(kill_after_s, kill)
    writes = 0
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), proc.communicate(timeout=30)[1]
        bus = ServoBus.open(path, echo="off", timeout_margin_s=KILL_MARGIN_S)
        try:
            for sid in (1, 2):
                bus.write_angle_limits_deg(sid, *OLD)
            assert bus.read_angle_limits_deg(2) == pytest.approx(OLD)
            with contextlib.suppress(TransportError, BusTimeoutError, ProtocolError):
                while True:
                    limits = NEW if writes % 2 == 0 else OLD
                    for sid in (1, 2):
                        bus.write_angle_limits_deg(sid, *limits)
                    writes += 1
                    bus.read_angle_limits_deg(1)  # paces the loop; fails once it is gone
                    if writes == GOING:
                        timer.start()
            # Only the kill ends the loop: a live server answers within the margin.
            assert killed.is_set(), f"the writes failed before the kill ({writes})"
        finally:
            bus.close()
    finally:
        timer.cancel()
        if timer.ident is not None:  # started
            timer.join()
        if proc.poll() is None:
            proc.kill()
        proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL
    return writes


@pytest.mark.wallclock("SIGKILL to `busarm sim serve`, a process serving a pty, while "
                       "it saves its state file: a process and wall-clock time")
@pytest.mark.parametrize("kill_after_s", [0.12, 0.27, 0.41])
def test_sigkill_during_stored_writes_leaves_old_or_new(
    tmp_path: Path, kill_after_s: float
) -> None:
    state = tmp_path / "servos.json"
    writes = _hammer_then_kill(state, kill_after_s)
    assert writes >= GOING, "the server died before the writes got going"
    records = load_state(state)
    assert records is not None
    by_id = {int(r["id"]): r for r in records}
    assert sorted(by_id) == [1, 2]
    for sid, record in by_id.items():
        pair = (int(record["min_pulses"]), int(record["max_pulses"]))
        assert pair in PULSES, f"servo {sid}: limits {pair} are neither old nor new"
    # And the simulator powers on from it.
    with arm_from_state("inproc", state) as bus:
        for sid in (1, 2):
            pair = (int(by_id[sid]["min_pulses"]), int(by_id[sid]["max_pulses"]))
            assert bus.read_angle_limits_deg(sid) == pytest.approx(PULSES[pair])
