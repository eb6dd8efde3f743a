"""Soak: thousands of reads through a faulty simulated line on a real pseudo-terminal.

The simulator (``busarm sim serve``, in its own process as a real device would be)
drops and corrupts 1 % of the bytes each way, seeded, at the real wire speed. The
servos stand still at distinct positions (from a power-off state file), so every
right answer is known. What must hold for every single read: the value is right, or
the call raises a typed busarm error after its bounded retries, and it never
outlives its time budget.
"""

from __future__ import annotations

import random
import time
from collections import Counter
from pathlib import Path

import pytest

from busarm.bench.bus import SimServerProcess
from busarm.bus.driver import ServoBus
from busarm.errors import BusTimeoutError, ProtocolError
from busarm.protocol import Command
from busarm.sim.servo import SimServo
from busarm.sim.storage import record_from_servo, save_state

pytestmark = [pytest.mark.realtime, pytest.mark.usefixtures("no_gc_pauses")]

SLACK_S = 0.005
"""What a call may take beyond its own timeouts: scheduling on a busy 2-core machine."""
POSITIONS = {1: 137, 2: 268, 3: 409, 4: 555, 5: 702, 10: 861}


def soak(tmp_path: Path, reads: int, *, echo: bool, seed: int) -> None:
    state = tmp_path / "servos.json"
    save_state(state, [record_from_servo(SimServo(sid, position_pulses=p))
                       for sid, p in POSITIONS.items()])
    faults = ["--drop", "0.01", "--corrupt", "0.01", "--seed", str(seed)]
    with SimServerProcess("--state", str(state), *faults, *(["--echo"] if echo else [])) as path:
        bus = ServoBus.open(path, echo="on" if echo else "off")
        try:
            _soak(bus, reads, random.Random(seed))
        finally:
            bus.close()


def _soak(bus: ServoBus, reads: int, rng: random.Random) -> None:
    budget_s = bus.read_budget_s(Command.POS_READ) + SLACK_S
    outcomes: Counter[str] = Counter()
    wrong: list[str] = []
    late: list[float] = []
    unbounded: list[str] = []
    ids = list(POSITIONS)
    for _ in range(reads):
        sid = rng.choice(ids)
        t0 = time.monotonic()
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
        took = time.monotonic() - t0
        if took > budget_s:
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


@pytest.mark.slow
def test_soak_echo_off(tmp_path: Path) -> None:
    # As many reads as with echo: each way, about 600 retries and 30 reads that fail
    # typed (every kind: timeout, checksum, protocol), all checked one by one.
    soak(tmp_path, 2_000, echo=False, seed=20240611)


@pytest.mark.slow
def test_soak_echo_on(tmp_path: Path) -> None:
    soak(tmp_path, 2_000, echo=True, seed=7)
