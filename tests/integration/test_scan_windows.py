"""The ID scan's short per-ID windows (busarm.bus.id_scan): each ID waits only as long as
its reply needs on the wire, and a reply that comes later is still not missed, whether
it arrives whole in a later window (recognised by its ID) or runs into a later request
and garbles that window (the IDs asked shortly before it are probed again).

The servos are on a simulated clock: their timing is exact on any computer."""

from __future__ import annotations

import pytest

from busarm.bus.driver import ServoBus
from busarm.bus.id_scan import LATE_REACH_S, SCAN_MARGIN_S
from busarm.protocol import Command, IdReply, encode_reply
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.transport import SimTransport

TURNAROUND_S = 0.0005


class CollidingTransport(SimTransport):
    """A simulated line on which ``late_id``'s ID_READ reply reaches the host damaged,
    as when a late reply runs into the next request on a half-duplex line."""

    def __init__(self, sim: SimBus, late_id: int) -> None:
        super().__init__(sim)
        self.reply = encode_reply(late_id, IdReply(late_id))
        self.damaged = 0

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        data = super().read(max_bytes, timeout_s)
        if self.reply in data:
            self.damaged += 1
            broken = self.reply[:-1] + bytes([self.reply[-1] ^ 0x5A])  # a bad checksum
            data = data.replace(self.reply, broken)
        return data


def bus_on(sim: SimBus, transport: SimTransport | None = None) -> ServoBus:
    return ServoBus(transport or SimTransport(sim), echo="off", turnaround_s=TURNAROUND_S)


def test_the_window_is_the_wire_time_of_a_request_and_its_reply() -> None:
    bus = bus_on(SimBus.with_ids((1,)))
    wire = (6 + 7) * 10.0 / 115200 + TURNAROUND_S
    assert bus.scan_window_s() == pytest.approx(wire + SCAN_MARGIN_S)
    assert bus.scan_window_s(0.004) == pytest.approx(wire + 0.004)  # a slower scan


def test_absent_ids_cost_a_window_each() -> None:
    sim = SimBus.with_ids((1,))
    bus = bus_on(sim)
    window = bus.scan_window_s()
    result = bus.scan(range(50, 150))
    assert result.found == []
    # 100 windows and the wait for stragglers (4 windows), nothing more.
    assert result.duration_s == pytest.approx(104 * window, rel=0.02)


def test_a_reply_later_than_its_window_is_found_by_its_id() -> None:
    sim = SimBus.with_ids((3, 9))
    bus = bus_on(sim)
    sim.delay_next_reply(2.5 * bus.scan_window_s())  # lands two windows later
    result = bus.scan(range(12))
    assert result.found == [3, 9]
    assert result.conflicts == []


def test_a_late_reply_that_garbles_a_later_window_is_asked_again() -> None:
    sim = SimBus.with_ids((3,))
    transport = CollidingTransport(sim, late_id=3)
    bus = bus_on(sim, transport)
    sim.delay_next_reply(1.5 * bus.scan_window_s())  # in the window of ID 4 or 5
    heard: list[tuple[Command, int]] = []
    sim.taps.append(lambda request: heard.append((request.command, request.servo_id)))
    result = bus.scan(range(8))
    assert transport.damaged == 1
    assert result.found == [3]  # its damaged reply came in another ID's window
    assert result.conflicts == []
    assert (Command.POS_READ, 3) in heard  # probed with the bus's own timeouts


def test_a_slow_servo_is_found_by_a_slower_scan() -> None:
    sim = SimBus.with_ids((2,), timing=WireTiming(turnaround_s=0.003))
    bus = bus_on(sim)
    assert bus.scan([2], margin_s=0.004).found == [2]


def test_a_garbled_window_probes_only_the_ids_asked_shortly_before() -> None:
    # A bus with a long margin (a pty's, a slow adapter's) still probes a few IDs, not
    # every ID asked within its long read deadline.
    sim = SimBus.with_ids((30,))
    bus = ServoBus(SimTransport(sim), echo="off", timeout_margin_s=0.3)
    heard: list[tuple[Command, int]] = []
    sim.taps.append(lambda request: heard.append((request.command, request.servo_id)))
    sim.inject_stray_bytes(b"\x00\x13\x37")  # noise just before servo 30's reply
    result = bus.scan(range(40))
    assert result.found == [30]
    probed = {sid for command, sid in heard if command is Command.POS_READ}
    # The noise delays the reply into the next ID's window: that window is the garbled
    # one, and the IDs asked up to LATE_REACH_S before it are probed.
    window = bus.scan_window_s()
    assert 30 in probed
    assert probed <= set(range(31 - int(LATE_REACH_S / window) - 1, 32)), probed
