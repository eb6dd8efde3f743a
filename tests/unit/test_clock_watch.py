"""A watched simulated clock says once when a program read it after waiting with
``time.sleep`` (the wall clock ran ahead while it stood still and the reading thread was
blocked), and never when the program waited on it, computed, or waited for a CPU on a
loaded machine. The wall clock and the scheduler's times here are a stand-in's, moved by
the test: nothing sleeps."""

from __future__ import annotations

import threading
import warnings
from collections.abc import Iterator

import pytest

import busarm.clock
from busarm.clock import FROZEN_AFTER_S, FrozenClockWarning, SimClock


class FakeTime:
    """The wall clock, and this thread's time on a CPU and waiting for one, as the clock
    reads them (``time.monotonic``, ``time.process_time``, Linux's schedstat)."""

    def __init__(self) -> None:
        self.wall_s = 1000.0
        self.cpu_s = 5.0
        self.waiting_s = 1.0
        self.schedstat = True

    def monotonic(self) -> float:
        return self.wall_s

    def process_time(self) -> float:
        return self.cpu_s

    def sleep(self, seconds: float) -> None:
        self.wall_s += seconds

    def thread_times(self) -> tuple[float, float] | None:
        return (self.cpu_s, self.waiting_s) if self.schedstat else None

    def compute(self, seconds: float) -> None:
        self.wall_s += seconds
        self.cpu_s += seconds

    def starve(self, seconds: float) -> None:  # runnable, but the CPUs are others'
        self.wall_s += seconds
        self.cpu_s += seconds * 0.02
        self.waiting_s += seconds * 0.98


@pytest.fixture
def fake(monkeypatch: pytest.MonkeyPatch) -> FakeTime:
    stand_in = FakeTime()
    monkeypatch.setattr(busarm.clock, "time", stand_in)
    monkeypatch.setattr(busarm.clock, "_thread_times", stand_in.thread_times)
    return stand_in


@pytest.fixture
def clock(fake: FakeTime) -> Iterator[SimClock]:
    watched = SimClock(step_s=0.004)
    watched.warn_when_frozen("the twin")
    yield watched


def _silent(clock: SimClock) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", FrozenClockWarning)
        clock.now()


def test_a_read_after_a_second_of_time_sleep_is_told_once_at_the_readers_line(
        fake: FakeTime, clock: SimClock) -> None:
    clock.sleep(0.5)
    fake.sleep(1.0)  # time.sleep(1.0): the wall runs, the thread is blocked
    with pytest.warns(FrozenClockWarning) as caught:
        clock.now()
    (warning,) = caught
    assert str(warning.message) == (
        "the twin keeps simulated time, and it stood still for 1.0 s of wall time before "
        "this read (0.500 s on its clock): time.sleep does not move it. Wait with "
        "robot.clock.sleep(seconds), not time.sleep")
    assert warning.filename == __file__  # the program's line, not the clock's inside
    fake.sleep(10.0)
    _silent(clock)  # once: a program that means it need not hear it again


def test_short_waits_add_up_until_the_clock_moves(fake: FakeTime, clock: SimClock) -> None:
    step_s = FROZEN_AFTER_S / 3
    for _ in range(2):
        fake.sleep(step_s)
        _silent(clock)
    fake.sleep(step_s * 1.01)
    with pytest.warns(FrozenClockWarning):
        clock.now()


def test_waiting_on_the_clock_is_never_told(fake: FakeTime, clock: SimClock) -> None:
    for _ in range(20):
        fake.sleep(0.4)
        clock.sleep(0.01)  # the program waits on the robot's clock, which moves
        fake.sleep(0.4)
        _silent(clock)


def test_computing_is_not_waiting_and_the_watch_starts_again_after_it(
        fake: FakeTime, clock: SimClock) -> None:
    fake.compute(3.0)  # a long plan or a render: busy
    _silent(clock)
    fake.compute(0.01)
    fake.sleep(0.19)
    _silent(clock)  # 0.2 s: not long enough yet
    fake.sleep(0.4)
    with pytest.warns(FrozenClockWarning, match="stood still for 0.6 s"):
        clock.now()


def test_waiting_for_a_cpu_on_a_loaded_machine_is_not_waiting(fake: FakeTime,
                                                              clock: SimClock) -> None:
    fake.starve(3.0)  # computing, but given 2 % of a CPU: no time.sleep in it
    _silent(clock)
    fake.sleep(1.0)
    with pytest.warns(FrozenClockWarning):
        clock.now()


def test_without_the_schedulers_times_the_process_cpu_time_decides(
        fake: FakeTime, clock: SimClock) -> None:
    fake.schedstat = False
    clock.sleep(0.1)
    fake.compute(2.0)
    _silent(clock)
    fake.sleep(1.0)
    with pytest.warns(FrozenClockWarning):
        clock.now()


def test_an_unwatched_clock_is_never_told(fake: FakeTime) -> None:
    plain = SimClock()
    fake.sleep(100.0)
    _silent(plain)


def test_a_read_while_another_thread_waits_on_the_clock_is_not_told(
        fake: FakeTime, clock: SimClock) -> None:
    inside, leave = threading.Event(), threading.Event()

    def held_step() -> None:  # a step of simulated time that takes its wall time
        inside.set()
        leave.wait(10.0)

    clock.attach(held_step)
    waiter = threading.Thread(target=clock.sleep, args=(clock.step_s,))
    waiter.start()
    try:
        assert inside.wait(10.0)
        fake.sleep(2.0)  # paced, or computing physics: the clock is moving
        _silent(clock)
    finally:
        leave.set()
        waiter.join(10.0)
    clock.detach(held_step)
    assert not waiter.is_alive()
