"""The bus's e-stop latch (``ServoBus.halt``), five ways (in-process and through a pty,
adapter echoing or not, and behind the simulated controller board on a pty): MOVE_STOP
goes out at once, every later write but a stop is refused from any thread until
``rearm``, a wait for a move ends, reads go on.

In-process the servos are on a simulated clock, so a halt from another thread is made to
land at a simulated moment (``halting_at``) and the times checked are exact; through a
pty they are wall-clock times, checked with room for a busy computer."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest

from busarm.clock import SimClock
from busarm.errors import HaltedError
from busarm.protocol import Command
from conftest import SimArm, wait_for

POLL_S = 0.02
"""wait_until_reached's default poll: the wait looks at the latch once per poll."""
LOADED_MACHINE_S = 0.5
"""On the wall clock, what a busy computer may add to a thread's turn (the stopper's
timer, the pty server's relay): not the driver's time."""


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


@contextmanager
def halting_at(arm: SimArm, at_s: float) -> Iterator[list[float]]:
    """Another thread halts ``arm.bus`` once the servos' clock reads ``at_s``; the list
    given gets the time it halted at (that clock's). The thread is joined on leaving.

    On the wall clock (a pty) a timer does it. On a simulated clock time passes only as
    the test's own thread waits on it: as the clock reaches ``at_s``, that thread wakes
    the stopper and holds simulated time still until the halt is latched, so the other
    thread's halt lands at that simulated moment, whatever else the computer does."""
    bus, clock = arm.bus, arm.sim.clock
    halted_at: list[float] = []

    def halt() -> None:
        halted_at.append(clock.now())
        bus.halt()

    if not isinstance(clock, SimClock):
        timer = threading.Timer(at_s - clock.now(), halt)
        timer.start()
        try:
            yield halted_at
        finally:
            timer.cancel()
            timer.join()
        return
    due = threading.Event()

    def stopper() -> None:
        if due.wait(timeout=30.0):  # wall time: only a failing test waits that long
            halt()

    def gate() -> None:
        if not due.is_set() and clock.now() >= at_s:
            due.set()
            assert wait_for(lambda: bus.halted is not None), "the other thread never halted"

    thread = threading.Thread(target=stopper, name="test-halt-stopper")
    thread.start()
    clock.attach(gate)
    try:
        yield halted_at
    finally:
        clock.detach(gate)
        due.set()  # if the wait ended some other way, the stopper halts now and ends
        thread.join()


def test_halt_from_another_thread_ends_a_move_and_its_wait(arm: SimArm) -> None:
    bus, clock = arm.bus, arm.sim.clock
    start = bus.read_position_deg(2)
    stops: list[float] = []
    arm.sim.taps.append(lambda r: stops.append(clock.now())
                        if r.command is Command.MOVE_STOP else None)
    bus.sync_move_deg({2: start + 60}, 2.0)
    began = clock.now()
    with halting_at(arm, began + 0.3) as halted_at, \
            pytest.raises(HaltedError, match="the move was stopped"):
        bus.wait_until_reached({2: start + 60})
    ended = clock.now()
    assert halted_at, "the wait ended before the halt"
    # The wait ends at its next look at the latch: after the read under way and a poll.
    # The halt's MOVE_STOP waits for that read too (one transaction at a time).
    within_s = bus.read_budget_s(Command.POS_READ) + POLL_S
    if isinstance(clock, SimClock):  # at the moment asked, to the clock's step
        assert halted_at[0] == pytest.approx(began + 0.3, abs=clock.step_s)
    else:  # a busy computer may be late to run the timer, or the pty's relay
        within_s += LOADED_MACHINE_S
    assert halted_at[0] <= ended <= halted_at[0] + within_s
    # Through a pty the server's thread relays it in its own time: waited for.
    assert wait_for(lambda: bool(stops)), "no MOVE_STOP reached the servos"
    assert halted_at[0] <= stops[0] <= halted_at[0] + within_s
    clock.sleep(0.3)
    held = bus.read_position_deg(2)
    clock.sleep(0.3)
    assert bus.read_position_deg(2) == pytest.approx(held, abs=0.5)  # stopped, holding
    assert abs(held - start) < 55  # cut short, nowhere near the target
