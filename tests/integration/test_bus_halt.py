"""The bus's e-stop latch (``ServoBus.halt``), five ways (in-process and through a pty,
adapter echoing or not, and behind the simulated controller board on a pty): MOVE_STOP
goes out at once, every later write but a stop is refused from any thread until
``rearm``, a wait for a move ends, reads go on."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import pytest

from busarm.errors import HaltedError
from busarm.protocol import Command
from conftest import SimArm

pytestmark = pytest.mark.realtime


def test_halt_refuses_writes_until_rearmed(arm: SimArm) -> None:
    bus = arm.bus
    start = bus.read_position_deg(1)
    bus.halt("e-stop test")
    assert bus.halted == "e-stop test"
    bus.read_temp_c(1)  # answered: the halt's MOVE_STOPs have reached the servos (on a pty)
    received = arm.sim.frames_received
    writes: list[Callable[[], object]] = [
        lambda: bus.move_deg(1, start + 20, 0.5),
        lambda: bus.sync_move_deg({1: start + 20, 2: 0.0}, 0.5),
        lambda: bus.set_torque(2, False)]
    # The board has no motor mode (test_driver's test_the_board_refuses_...).
    motors = arm.board is None
    if motors:
        writes.append(lambda: bus.set_motor_speed(3, 500))
    for write in writes:
        with pytest.raises(HaltedError, match=r"refused: the robot is halted \(e-stop test\); "
                                              "re-arm it first"):
            write()
    bus.read_temp_c(1)  # answered: whatever was sent before it has reached the servos
    assert arm.sim.frames_received == received + 1  # the read: not a byte of the writes
    bus.stop()  # a stop is never refused
    if motors:
        bus.set_motor_speed(3, 0)
    assert bus.read_position_deg(1) == pytest.approx(start, abs=0.5)  # reads go on
    bus.rearm()
    bus.move_deg(1, start + 20, 0.2)
    bus.wait_until_reached({1: start + 20}, tolerance_deg=1.0)


def test_halt_from_another_thread_ends_a_move_and_its_wait(arm: SimArm) -> None:
    bus = arm.bus
    start = bus.read_position_deg(2)
    stops: list[float] = []
    arm.sim.taps.append(lambda r: stops.append(time.monotonic())
                        if r.command is Command.MOVE_STOP else None)
    bus.sync_move_deg({2: start + 60}, 2.0)
    stopper = threading.Timer(0.3, bus.halt)
    stopper.start()
    began = time.monotonic()
    with pytest.raises(HaltedError, match="the move was stopped"):
        bus.wait_until_reached({2: start + 60})
    stopper.join()
    assert time.monotonic() - began < 1.0
    assert stops and stops[0] - began < 0.5  # MOVE_STOP reached the servos at the halt
    time.sleep(0.3)
    held = bus.read_position_deg(2)
    time.sleep(0.3)
    assert bus.read_position_deg(2) == pytest.approx(held, abs=0.5)  # stopped, holding
    assert abs(held - start) < 55  # cut short, nowhere near the target
