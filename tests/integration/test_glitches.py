"""Line glitches: stray bytes, stray frames, late and garbled replies, no servo at all.

The rule every test checks: a read returns the right value or raises a typed busarm
error (BusTimeoutError, ProtocolError), within its time budget, and a glitch never
leaks into a later read, of another servo or of the same one.

Tests taking ``arm`` run four ways (in-process and pty, echo on and off; see conftest).
"""

from __future__ import annotations

import contextlib
import os
import random
import time
import tty
from collections.abc import Iterator

import pytest

from busarm.bus.driver import ServoBus
from busarm.errors import BusTimeoutError, ChecksumError, ProtocolError
from busarm.protocol import Command, PositionReply, TempReply, VinReply, encode_reply
from busarm.sim.bus import FaultInjection, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport
from conftest import SimArm, lx_wire_only

pytestmark = [pytest.mark.realtime, pytest.mark.usefixtures("no_gc_pauses")]

SLACK_S = 0.005
"""What a call may take beyond its own timeouts: scheduling on a busy 2-core machine."""
VIN_REPLY_BYTES = 8
TYPED = (BusTimeoutError, ProtocolError)
TYPED_NAMES = ("BusTimeoutError", "UnreliableLineError", "ProtocolError", "ChecksumError")
"""The typed errors a read may end with (UnreliableLineError: a timeout from a servo that
answered before, or on a line seen delivering replies late or damaged)."""

SUPPLY_MV = {1: 11100, 2: 10200, 3: 9300, 4: 8400, 5: 7500, 10: 11900}
"""Distinct supplies, so that one servo's VIN reply is never right for another."""


def read_budget_s(bus: ServoBus, command: Command) -> float:
    """The driver's stated worst case for a read, plus slack for the OS."""
    return bus.read_budget_s(command) + SLACK_S


def set_supplies(arm: SimArm, supplies: dict[int, int]) -> None:
    for sid, mv in supplies.items():
        arm.sim.servo(sid).supply_mv = mv


def vin_or_error(bus: ServoBus, servo_id: int) -> int | str:
    """The VIN reading in mV, or the name of the typed error; anything else propagates."""
    try:
        return round(bus.read_vin_v(servo_id) * 1000)
    except TYPED as exc:
        return type(exc).__name__


def drain(arm: SimArm) -> None:
    """Wait (polling the simulator) until nothing it owes is still on its way, then read
    another servo so that the last bytes out of the simulator are flushed or ignored."""
    deadline = time.monotonic() + 2.0
    while arm.sim.next_output_at() is not None:
        assert time.monotonic() < deadline, "the simulator kept sending"
        arm.bus.transport.reset_input()
        time.sleep(0.001)
    arm.bus.read_temp_c(5)


# ---------------------------------------------------------------------- stray bytes


STRAYS = {
    "zero byte": b"\x00",
    "one 0x55": b"\x55",
    "a lone header": b"\x55\x55",
    "header, ID, length, command only": b"\x55\x55\x01\x05\x1b",
    "frame with a bad checksum": b"\x55\x55\x01\x05\x1b\x10\x27\x00",
    "another servo's VIN reply": encode_reply(2, VinReply(4321)),
    "this servo's reply to another command": encode_reply(1, PositionReply(321)),
    "this servo's TEMP reply": encode_reply(1, TempReply(27)),
    "noise burst": bytes(random.Random(5).randrange(256) for _ in range(40)),
}


# Stray bytes and late replies on the LX wire: behind a controller board the host never
# sees that line's bytes, so these run the LX ways only.
@lx_wire_only
@pytest.mark.parametrize("stray", list(STRAYS.values()), ids=list(STRAYS))
def test_stray_bytes_before_the_reply(arm: SimArm, stray: bytes) -> None:
    set_supplies(arm, SUPPLY_MV)
    arm.sim.inject_stray_bytes(stray)
    t0 = time.monotonic()
    assert vin_or_error(arm.bus, 1) == SUPPLY_MV[1]
    assert time.monotonic() - t0 <= read_budget_s(arm.bus, Command.VIN_READ)
    assert arm.bus.read_vin_v(2) == SUPPLY_MV[2] / 1000
    arm.sim.servo(1).supply_mv = 6800
    assert arm.bus.read_vin_v(1) == 6.8


@lx_wire_only
def test_stray_bytes_before_every_reply_of_a_scan(arm: SimArm) -> None:
    # Scans read many replies back to back; a stray frame naming an absent ID between
    # them must not be reported, and the real servos still must be.
    arm.sim.inject_stray_bytes(b"\x00\x55" + encode_reply(7, PositionReply(500)))
    result = arm.bus.scan(range(12))
    assert result.found == [1, 2, 3, 4, 5, 10]


# ---------------------------------------------------------------------- late replies


def _late_reply_outcomes(arm: SimArm, delays_s: list[float]) -> list[str]:
    """For each delay: read servo 1 with its reply that late, then servo 2, then servo 1
    again after its supply changed. Returns what went wrong (empty if nothing)."""
    problems: list[str] = []
    set_supplies(arm, SUPPLY_MV)
    bus = arm.bus
    budget = read_budget_s(bus, Command.VIN_READ)
    for i, delay in enumerate(delays_s):
        first, second = 7000 + 10 * i, 9000 + 10 * i
        arm.sim.servo(1).supply_mv = first
        arm.sim.delay_next_reply(delay)
        t0 = time.monotonic()
        a = vin_or_error(bus, 1)
        took = time.monotonic() - t0
        arm.sim.servo(1).supply_mv = second
        b = vin_or_error(bus, 2)
        a2 = vin_or_error(bus, 1)
        where = f"delay {delay * 1e3:.1f} ms"
        if a not in (first, *TYPED_NAMES):
            problems.append(f"{where}: servo 1 read {a}, expected {first}")
        if took > budget:
            problems.append(f"{where}: servo 1 read took {took * 1e3:.1f} ms > {budget * 1e3:.1f}")
        if b not in (SUPPLY_MV[2], *TYPED_NAMES):
            problems.append(f"{where}: next read of servo 2 gave {b}, expected {SUPPLY_MV[2]}")
        # The late reply holds the line (nothing overtakes it on one wire); if it came
        # while servo 1 was still being asked, servo 2's read finds the line free.
        if delay < (bus.retries + 1) * bus.timeout_s(6, VIN_REPLY_BYTES) and b != SUPPLY_MV[2]:
            problems.append(f"{where}: next read of servo 2 failed ({b}) on a free line")
        if a2 not in (second, *TYPED_NAMES):
            stale = " (the stale late reply)" if a2 == first else ""
            problems.append(f"{where}: next read of servo 1 gave {a2}{stale}, expected {second}")
        drain(arm)
        if vin_or_error(bus, 1) != second or vin_or_error(bus, 2) != SUPPLY_MV[2]:
            problems.append(f"{where}: the bus did not recover once the line was quiet")
    return problems


@lx_wire_only
def test_reply_after_its_timeout(arm: SimArm) -> None:
    # Delays in units of the per-attempt timeout land the late reply in the first
    # attempt, in a retry, in the next read of servo 2 and in the next read of servo 1.
    unit = arm.bus.timeout_s(6, VIN_REPLY_BYTES)
    problems = _late_reply_outcomes(arm, [k * unit for k in (0.5, 1.2, 2.2, 3.5, 5.9, 6.5)])
    assert not problems, "\n".join(problems)


@lx_wire_only
def test_reply_after_its_timeout_without_retries(arm: SimArm) -> None:
    arm.bus.retries = 0
    unit = arm.bus.timeout_s(6, VIN_REPLY_BYTES)
    problems = _late_reply_outcomes(arm, [k * unit for k in (1.2, 2.0, 2.5)])
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------------- garbled replies


@contextlib.contextmanager
def faulty_bus(kind: str, echo: bool, faults: FaultInjection, **bus_kwargs: object
               ) -> Iterator[tuple[ServoBus, SimBus]]:
    """The arm with fault injection, in-process or on a pty."""
    sim = SimBus.with_ids(timing=WireTiming(), echo=echo, faults=faults)
    kwargs: dict[str, object] = {"echo": "on" if echo else "off", **bus_kwargs}
    server = None
    if kind == "pty":
        server = PtyServer(sim)
        bus = ServoBus.open(server.start(), **kwargs)  # type: ignore[arg-type]
    else:
        bus = ServoBus(SimTransport(sim), **kwargs)  # type: ignore[arg-type]
    try:
        yield bus, sim
    finally:
        bus.close()
        if server is not None:
            server.stop()


WAYS = [("inproc", False), ("inproc", True), ("pty", False), ("pty", True)]
WAY_IDS = ["inproc-noecho", "inproc-echo", "pty-noecho", "pty-echo"]


@pytest.mark.parametrize(("kind", "echo"), WAYS, ids=WAY_IDS)
def test_every_reply_garbled_never_gives_a_value(kind: str, echo: bool) -> None:
    faults = FaultInjection(corrupt_rate=1.0, directions="tx", seed=3)
    with faulty_bus(kind, echo, faults) as (bus, _sim):
        budget = read_budget_s(bus, Command.POS_READ)
        for sid in (1, 2, 10, 1):
            t0 = time.monotonic()
            with pytest.raises(TYPED):
                value = bus.read_position_pulses(sid)
                pytest.fail(f"servo {sid}: garbled reply taken as position {value}")
            assert time.monotonic() - t0 <= budget
        assert bus.stats["retries"] == 4 * bus.retries


@pytest.mark.parametrize(("kind", "echo"), WAYS, ids=WAY_IDS)
def test_some_replies_garbled_give_right_values_or_checksum_errors(
    kind: str, echo: bool
) -> None:
    # One byte in ten corrupted: a reply whose header survives and whose body does not
    # is a ChecksumError (no retries here, so each read is one attempt).
    faults = FaultInjection(corrupt_rate=0.1, directions="tx", seed=11)
    with faulty_bus(kind, echo, faults, retries=0) as (bus, sim):
        now = time.monotonic()
        for sid, pulses in {1: 100.0, 2: 300.0, 3: 700.0}.items():
            sim.servo(sid).move_by_hand(pulses, now)
        outcomes: dict[str, int] = {}
        rng = random.Random(2)
        for _ in range(120):
            sid = rng.choice((1, 2, 3))
            try:
                value = bus.read_position_pulses(sid)
            except TYPED as exc:
                key = type(exc).__name__
            else:
                assert value == {1: 100, 2: 300, 3: 700}[sid], f"servo {sid}: wrong {value}"
                key = "right"
            outcomes[key] = outcomes.get(key, 0) + 1
        assert outcomes.get("right", 0) > 40, outcomes
        assert outcomes.get(ChecksumError.__name__, 0) > 0, outcomes


# ---------------------------------------------------------------------- no servo at all


def test_pyserial_loop_is_an_echoing_adapter_with_no_servo() -> None:
    bus = ServoBus.open("loop://")
    try:
        assert bus.echo is True, "loop:// hands back every byte: echo must be detected"
        for sid, read in ((1, bus.read_position_pulses), (2, bus.read_temp_c)):
            t0 = time.monotonic()
            with pytest.raises(BusTimeoutError) as info:
                read(sid)
            assert time.monotonic() - t0 <= read_budget_s(bus, Command.POS_READ)
            assert info.value.servo_id == sid
        # Its own ID_READ request coming back is not a servo answering.
        assert bus.scan(range(4)).found == []
    finally:
        bus.close()


def test_silent_pty_times_out_within_budget() -> None:
    # A pseudo-terminal whose other end nobody reads: the request goes nowhere.
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    try:
        bus = ServoBus.open(path)
        try:
            assert bus.echo is False
            for command in (Command.POS_READ, Command.VIN_LIMIT_READ):
                t0 = time.monotonic()
                with pytest.raises(BusTimeoutError) as info:
                    bus.query(3, command)
                elapsed = time.monotonic() - t0
                assert elapsed <= read_budget_s(bus, command), f"{elapsed * 1e3:.1f} ms"
                assert info.value.command == command
            assert bus.stats["retries"] == 2 * bus.retries
        finally:
            bus.close()
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("retries", [0, 2, 5])
def test_bus_without_servos_times_out_within_budget(retries: int) -> None:
    sim = SimBus([], timing=WireTiming())
    bus = ServoBus(SimTransport(sim), echo="off", retries=retries)
    t0 = time.monotonic()
    with pytest.raises(BusTimeoutError, match="did not answer"):
        bus.read_temp_c(4)
    elapsed = time.monotonic() - t0
    assert elapsed <= read_budget_s(bus, Command.TEMP_READ), f"{elapsed * 1e3:.1f} ms"
    # ... and it really waited for each attempt: retries are not skipped.
    assert bus.stats["retries"] == retries
    assert sim.frames_received == retries + 1
