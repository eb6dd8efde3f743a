"""Renumbering on a line whose servos answer later than an ID scan waits for (a busy
computer, a slow adapter): ``set_id`` asks a silent ID again with the bus's own margin
before it takes the silence as absence, so it neither refuses a servo that is there nor
hands out an ID another servo holds.

The servos are on a simulated clock: their late answers are late by exactly the
turnaround below, on any computer."""

from __future__ import annotations

import pytest

from busarm.bus.driver import ServoBus
from busarm.errors import BusConflictError
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.transport import SimTransport

SLOW_TURNAROUND_S = 0.03
"""Past a scan's deadline and its wait for stragglers, within the bus's margin below."""
MARGIN_S = 0.05


def slow_bus(*ids: int) -> tuple[ServoBus, SimBus]:
    sim = SimBus.with_ids(ids, timing=WireTiming(turnaround_s=SLOW_TURNAROUND_S))
    return ServoBus(SimTransport(sim), timeout_margin_s=MARGIN_S), sim


def test_a_slow_servo_at_the_old_id_is_renumbered() -> None:
    bus, sim = slow_bus(1, 3)
    assert 3 not in bus.scan([3, 7]).found  # the scan alone does not hear it in time
    bus.set_id(3, 7)
    assert sorted(s.servo_id for s in sim.servos) == [1, 7]
    assert bus.read_id(7) == 7


def test_a_slow_servo_at_the_new_id_keeps_it() -> None:
    bus, sim = slow_bus(3, 7)
    with pytest.raises(BusConflictError, match="ID 7 is already taken"):
        bus.set_id(3, 7)
    assert sorted(s.servo_id for s in sim.servos) == [3, 7]
