"""The clocks: simulated time moves only by waiting on it, steps never overshoot, bad
waits are refused, and the bus driver's timeouts are kept in the clock's own time."""

from __future__ import annotations

import math
import time

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from busarm.bus.driver import ServoBus
from busarm.clock import WALL_CLOCK, Clock, SimClock
from busarm.errors import BusTimeoutError, ConfigError
from busarm.protocol import Command
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.transport import SimTransport


def test_both_clocks_are_clocks() -> None:
    assert isinstance(WALL_CLOCK, Clock) and not WALL_CLOCK.is_simulated
    assert isinstance(SimClock(), Clock) and SimClock().is_simulated


@settings(max_examples=100, deadline=None)
@given(sleeps=st.lists(st.floats(0.0, 0.05, allow_nan=False), max_size=20),
       step=st.floats(0.0005, 0.01))
@example(sleeps=[1e-12, 1e-12, 0.03125], step=0.0078125)  # two waits joining one step
def test_sim_time_is_the_sum_of_the_waits_in_steps_no_longer_than_step(
        sleeps: list[float], step: float) -> None:
    clock = SimClock(5.0, step_s=step)
    seen: list[float] = []
    clock.attach(lambda: seen.append(clock.now()))
    for s in sleeps:
        clock.sleep(s)
    assert clock.now() == pytest.approx(5.0 + sum(sleeps), abs=1e-9)
    gaps = [b - a for a, b in zip([5.0, *seen], seen, strict=False)]
    # A wait within the clock's 1e-12 s rounding makes no step of its own: it joins the
    # next one (hence up to 1e-12 over the step for each such wait, plus the sum's last
    # bits).
    tiny = sum(s <= 1e-12 for s in sleeps)
    assert all(0 < g <= step + 1e-12 * (tiny + 1) + 1e-14 for g in gaps), gaps
    # Each wait ends exactly where it should: the callbacks saw its end time.
    ends = [5.0 + sum(sleeps[: k + 1]) for k, s in enumerate(sleeps) if s > 1e-12]
    for end in ends:
        assert any(math.isclose(t, end, abs_tol=1e-9) for t in seen)


def test_a_detached_callback_no_longer_runs() -> None:
    clock = SimClock(step_s=0.01)
    calls: list[float] = []

    def callback() -> None:
        calls.append(clock.now())

    clock.attach(callback)
    clock.sleep(0.05)
    clock.detach(callback)
    clock.detach(callback)  # twice: no error
    clock.sleep(0.05)
    assert len(calls) == 5 and clock.now() == pytest.approx(0.1)


@pytest.mark.parametrize("bad", [math.nan, math.inf, "1", True, 3601.0])
def test_bad_waits_are_refused_with_the_value_and_range(bad: object) -> None:
    for clock in (WALL_CLOCK, SimClock()):
        with pytest.raises(ConfigError, match="sleep seconds"):
            clock.sleep(bad)  # type: ignore[arg-type]


def test_bad_sim_clock_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"step_s = 0 s is out of range"):
        SimClock(step_s=0)
    with pytest.raises(ConfigError, match=r"pace = -1 is out of range 0.01..1000"):
        SimClock(pace=-1)


def test_a_negative_wait_is_no_wait() -> None:
    clock = SimClock(1.0)
    clock.sleep(-0.5)
    assert clock.now() == 1.0


def test_a_paced_clock_never_runs_ahead_of_the_wall_clock() -> None:
    clock = SimClock(step_s=0.01, pace=1.0)
    wall = time.monotonic()
    clock.sleep(0.2)
    assert time.monotonic() - wall >= 0.2 - 1e-3


def test_a_silent_servo_times_out_in_simulated_time_without_waiting_for_it() -> None:
    """On a simulated clock the driver's deadlines are simulated seconds: a servo that
    never answers gives the typed timeout once its budget has passed in simulated time."""
    clock = SimClock(step_s=0.001)
    sim = SimBus.with_ids([1], timing=WireTiming(115200), clock=clock)
    with ServoBus(SimTransport(sim), echo="off") as bus:
        assert bus.clock is clock
        assert bus.read_position_deg(1) == pytest.approx(0.0, abs=0.3)
        sim.servos[0].supply_mv = 4000  # browned out: silent
        start = clock.now()
        with pytest.raises(BusTimeoutError, match="servo 1 did not answer"):
            bus.read_position_deg(1)
        waited = clock.now() - start
        budget = bus.read_budget_s(Command.POS_READ)
    assert bus.retries == 2
    assert 3 * bus.timeout_s(6, 8) <= waited <= budget + 1e-6, (waited, budget)


def test_waiting_for_an_event_ends_when_it_is_set_or_the_time_has_passed() -> None:
    import threading

    for clock in (WALL_CLOCK, SimClock(step_s=0.01)):
        event = threading.Event()
        start = clock.now()
        assert clock.wait(event, 0.05) is False
        assert clock.now() - start >= 0.05 - 1e-9
        event.set()
        start = clock.now()
        assert clock.wait(event, 10.0) is True
        assert clock.now() - start < 0.01
    # Set by another thread while simulated time runs: seen within a step.
    clock, event = SimClock(step_s=0.01), threading.Event()
    clock.attach(lambda: event.set() if clock.now() >= 0.3 else None)
    assert clock.wait(event, 5.0) is True
    assert clock.now() == pytest.approx(0.3, abs=0.011)
