"""Soak: thousands of reads through a faulty simulated line.

The simulator drops and corrupts 1 % of the bytes each way, seeded, at the real wire
speed. The servos stand still at distinct positions (from a power-off state file), so
every right answer is known. What must hold for every single read: the value is right,
or the call raises a typed busarm error after its bounded retries, and it never
outlives its time budget.

Each way (adapter echoing or not) soaks in-process on the simulated clock, where a read's
time is the simulation's: it is checked against the budget the driver computes, exactly,
and the same faults fall on the same reads on any computer. One soak goes through a real
pseudo-terminal to ``busarm sim serve`` in its own process, as a real device would be:
the bytes cross two processes in wall-clock time, so a busy computer may hear a reply
late (``LOADED_MARGIN_S``) or hold any read up (``LOADED_MACHINE_S``); there the budget
only catches an endless wait (and the error's message, retries beyond the bus's).
"""

from __future__ import annotations

import random
from collections import Counter
from pathlib import Path

import pytest

from busarm.bench.bus import SimServerProcess
from busarm.bus.driver import ServoBus
from busarm.errors import BusTimeoutError, ProtocolError
from busarm.protocol import Command
from busarm.sim.servo import SimServo
from busarm.sim.spec import SimSpec
from busarm.sim.storage import record_from_servo, save_state

POSITIONS = {1: 137, 2: 268, 3: 409, 4: 555, 5: 702, 10: 861}
LOADED_MACHINE_S = 2.0
"""On the wall clock, what a busy computer (other tests, CPU-bound programs beside them:
a load of 12 on 2 cores held one read up by half a second) may add to one read. Not the
driver's time: through the pty the budget only catches a read that never ends; that no
read outlives the driver's own budget is the in-process soaks' check, exact."""
LOADED_MARGIN_S = 0.05
"""The reply margin through the pty: the driver's default (4 ms) is for a computer that
does nothing else; on a busy one a reply heard late is retried, and its late bytes meet
the retry's, failing reads the faults alone would not (at a load of 16 on 2 cores and a
margin of 30 ms, one read in twenty instead of one in seventy)."""


def servos_at_rest(tmp_path: Path) -> Path:
    """The state file of the servos at ``POSITIONS``."""
    state = tmp_path / "servos.json"
    save_state(state, [record_from_servo(SimServo(sid, position_pulses=p))
                       for sid, p in POSITIONS.items()])
    return state


def soak_in_process(tmp_path: Path, reads: int, *, echo: bool, seed: int) -> None:
    sim = SimSpec(state=servos_at_rest(tmp_path), drop=0.01, corrupt=0.01, seed=seed,
                  echo=echo)
    with ServoBus.open(sim, echo="on" if echo else "off") as bus:
        assert bus.clock.is_simulated
        _soak(bus, reads, random.Random(seed), slack_s=0.0)


def _soak(bus: ServoBus, reads: int, rng: random.Random, *, slack_s: float) -> None:
    clock = bus.clock
    budget_s = bus.read_budget_s(Command.POS_READ) + slack_s
    outcomes: Counter[str] = Counter()
    wrong: list[str] = []
    late: list[float] = []
    unbounded: list[str] = []
    ids = list(POSITIONS)
    for _ in range(reads):
        sid = rng.choice(ids)
        t0 = clock.now()
        try:
            value = bus.read_position_pulses(sid)
        except (BusTimeoutError, ProtocolError) as exc:
            outcomes[type(exc).__name__] += 1
            if f" {bus.retries + 1} attempts" not in str(exc):  # "after 3", "in 3 attempts"
                unbounded.append(str(exc))
        else:
            outcomes["right"] += 1
            if value != POSITIONS[sid]:
                wrong.append(f"servo {sid}: {value}, expected {POSITIONS[sid]}")
        took = clock.now() - t0
        if took > budget_s + 1e-9:  # (a rounding of the simulated clock's sums)
            late.append(took)
    report = (
        f"{reads} reads: {outcomes['right']} right, "
        f"{reads - outcomes['right']} typed failures {dict(outcomes - Counter(right=reads))}, "
        f"{len(wrong)} wrong; driver stats {bus.stats}; "
        f"{len(late)} over the {budget_s * 1e3:.1f} ms budget"
        + (f" (worst {max(late) * 1e3:.1f} ms)" if late else "")
    )
    print(report)  # shown with -s / -rP: the counts of a passing run
    assert not wrong, f"{report}; wrong values: {wrong[:10]}"
    assert not late, report
    assert not unbounded, f"{report}; failures not after all retries: {unbounded[:3]}"
    # The faults really happened, and retries really mended most of them.
    assert bus.stats["retries"] > reads // 20, report
    assert bus.stats["retries"] <= reads * bus.retries, report
    assert outcomes["right"] >= 0.95 * reads, report
    assert sum(outcomes.values()) == reads, report


def test_soak_echo_off(tmp_path: Path) -> None:
    # As many reads as with echo: each way, about 600 retries and 30 reads that fail
    # typed (every kind: timeout, checksum, protocol), all checked one by one.
    soak_in_process(tmp_path, 2_000, echo=False, seed=20240611)


def test_soak_echo_on(tmp_path: Path) -> None:
    soak_in_process(tmp_path, 2_000, echo=True, seed=7)


@pytest.mark.slow
@pytest.mark.wallclock("`busarm sim serve` in its own process on a real pty: bytes "
                       "between two processes in wall-clock time")
@pytest.mark.usefixtures("no_gc_pauses")
def test_soak_through_a_pty_to_another_process(tmp_path: Path) -> None:
    # A fifth of the reads of the soaks above (2000 each, in-process, exactly timed): on
    # the wall clock every lost or garbled reply costs about an attempt's deadline, and
    # 400 reads through the pty already see some 130 retries and every kind of typed
    # failure.
    faults = ["--drop", "0.01", "--corrupt", "0.01", "--seed", "20240611", "--echo"]
    with SimServerProcess("--state", str(servos_at_rest(tmp_path)), *faults) as path, \
            ServoBus.open(path, echo="on", timeout_margin_s=LOADED_MARGIN_S) as bus:
        assert not bus.clock.is_simulated
        _soak(bus, 400, random.Random(20240611), slack_s=LOADED_MACHINE_S)
