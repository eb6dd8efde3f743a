"""Line glitches: stray bytes, stray frames, late and garbled replies, no servo at all.

The rule every test checks: a read returns the right value or raises a typed busarm
error (BusTimeoutError, ProtocolError), within its time budget, and a glitch never
leaks into a later read, of another servo or of the same one.

Tests taking ``way`` run conftest's LX ways (in-process and pty, echo on and off).
In-process the simulated servos run on a simulated clock: a read's time is exact, and it
is checked against the driver's budget with no slack at all; late replies are tested
there only (see LATE_WAYS). Through a pty the servos answer in wall-clock time, the
subject of those ways: the bus there has a generous margin in every deadline (conftest's
``PTY_MARGIN_S``; ``LATE_MARGIN_S`` where the test waits out deadlines by design), and
the time a read took is checked with slack for scheduling (a bound on a hang).
"""

from __future__ import annotations

import contextlib
import os
import random
import tty
from collections.abc import Iterator

import pytest

from busarm.bus.driver import ServoBus
from busarm.clock import WALL_CLOCK
from busarm.errors import BusTimeoutError, ChecksumError, ProtocolError
from busarm.protocol import Command, PositionReply, TempReply, VinReply, encode_reply
from busarm.sim.bus import FaultInjection, SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport
from conftest import LX_WAYS, PTY_MARGIN_S, SimArm, sim_arm_way, wait_for

WALL_SLACK_S = 0.5
"""What each attempt of a read on the wall clock may take beyond its deadline: a loaded
2-core machine (other tests, CPU-bound programs: a load of 20 was seen) may wake a
waiting thread 400 ms late, and each attempt's deadline starts where the one before it
ended. A bound on a hang: on a simulated clock (the in-process ways) a read is
held to its budget exactly."""
VIN_REPLY_BYTES = 8
TYPED = (BusTimeoutError, ProtocolError)
TYPED_NAMES = ("BusTimeoutError", "UnreliableLineError", "ProtocolError", "ChecksumError")
"""The typed errors a read may end with (UnreliableLineError: a timeout from a servo that
answered before, or on a line seen delivering replies late or damaged)."""

LATE_MARGIN_S = 0.1
"""The reply margin through a pty of the tests that wait out deadlines by design (a
scan's silent IDs, every reply damaged), instead of conftest's ``PTY_MARGIN_S``: each
silent ID or damaged reply waits it out, and a reply a loaded machine hears later still
ends in one of the typed outcomes these tests allow."""

SUPPLY_MV = {1: 11100, 2: 10200, 3: 9300, 4: 8400, 5: 7500, 10: 11900}
"""Distinct supplies, so that one servo's VIN reply is never right for another."""


@pytest.fixture(autouse=True)
def _no_gc_pauses_on_the_wall_clock(request: pytest.FixtureRequest) -> None:
    """A read timed on the wall clock must not be charged a collection of the earlier
    tests' objects (tens of ms); on a simulated clock a collection takes no time."""
    if request.node.get_closest_marker("wallclock") is not None:
        request.getfixturevalue("no_gc_pauses")


def read_budget_s(bus: ServoBus, command: Command) -> float:
    """The driver's stated worst case for a read: exactly, on a simulated clock (but for
    floating-point rounding); on the wall clock plus scheduling slack for each attempt."""
    budget = bus.read_budget_s(command)
    if bus.clock.is_simulated:
        return budget + 1e-9
    return budget + (bus.retries + 1) * WALL_SLACK_S


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
    """Wait (polling the simulator, on its clock) until nothing it owes is still on its
    way, then read another servo so that the last bytes out of the simulator are flushed
    or ignored."""

    def quiet() -> bool:
        if arm.sim.next_output_at() is None:
            return True
        arm.bus.transport.reset_input()
        return False

    assert wait_for(quiet, 5.0, arm.sim.clock), "the simulator kept sending"
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


@contextlib.contextmanager
def lx_arm(way: str, pty_margin_s: float = PTY_MARGIN_S) -> Iterator[SimArm]:
    """conftest's arm, one of ``LX_WAYS`` (parametrized by ``way``: conftest marks the pty
    ways ``wallclock``); through a pty with ``pty_margin_s``."""
    kwargs = {"timeout_margin_s": pty_margin_s} if way.startswith("pty") else {}
    with sim_arm_way(way, **kwargs) as arm:
        yield arm


# Stray bytes and late replies on the LX wire: behind a controller board the host never
# sees that line's bytes, so these run the LX ways only.
@pytest.mark.parametrize("way", LX_WAYS)
@pytest.mark.parametrize("stray", list(STRAYS.values()), ids=list(STRAYS))
def test_stray_bytes_before_the_reply(way: str, stray: bytes) -> None:
    with lx_arm(way) as arm:
        _read_after_stray_bytes(arm, stray)


def _read_after_stray_bytes(arm: SimArm, stray: bytes) -> None:
    set_supplies(arm, SUPPLY_MV)
    arm.sim.inject_stray_bytes(stray)
    clock = arm.sim.clock
    t0 = clock.now()
    assert vin_or_error(arm.bus, 1) == SUPPLY_MV[1]
    assert clock.now() - t0 <= read_budget_s(arm.bus, Command.VIN_READ)
    assert arm.bus.read_vin_v(2) == SUPPLY_MV[2] / 1000
    arm.sim.servo(1).supply_mv = 6800
    assert arm.bus.read_vin_v(1) == 6.8


@pytest.mark.parametrize("way", LX_WAYS)
def test_stray_bytes_before_every_reply_of_a_scan(way: str) -> None:
    # Scans read many replies back to back; a stray frame naming an absent ID between
    # them must not be reported, and the real servos still must be.
    with lx_arm(way, LATE_MARGIN_S) as arm:
        arm.sim.inject_stray_bytes(b"\x00\x55" + encode_reply(7, PositionReply(500)))
        # A scan's own deadlines are short (SCAN_MARGIN_S); through a pty they get
        # LATE_MARGIN_S (a reply later still is collected in the scan's wait for
        # stragglers): a servo a busy computer hears late is not this test's subject.
        on_pty = not arm.sim.clock.is_simulated
        margin = {"margin_s": LATE_MARGIN_S} if on_pty else {}
        assert arm.bus.scan(range(12), **margin).found == [1, 2, 3, 4, 5, 10]


# ---------------------------------------------------------------------- late replies


def _late_reply_outcomes(arm: SimArm, delays_s: list[float]) -> list[str]:
    """For each delay: read servo 1 with its reply that late, then servo 2, then servo 1
    again after its supply changed. Returns what went wrong (empty if nothing)."""
    problems: list[str] = []
    set_supplies(arm, SUPPLY_MV)
    bus, clock = arm.bus, arm.sim.clock
    budget = read_budget_s(bus, Command.VIN_READ)
    for i, delay in enumerate(delays_s):
        first, second = 7000 + 10 * i, 9000 + 10 * i
        arm.sim.servo(1).supply_mv = first
        arm.sim.delay_next_reply(delay)
        t0 = clock.now()
        a = vin_or_error(bus, 1)
        took = clock.now() - t0
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


# In this process only, on the simulated clock: the delays are the simulator's and the
# deadlines the driver's, on one clock, so each delay lands exactly where it is meant to.
# Through a pty on a loaded machine (a load of 10-20 seen) a reply meant on time was heard
# after 3 attempts of 100 ms, and a longer margin stretches the delays past the driver's
# STALE_REPLY_S (1 s: how long it expects a timed-out reply), which the test must not.
# Bytes through a pty around glitches: the stray-byte and garbled-reply tests.
LATE_WAYS = ["inproc-noecho", "inproc-echo"]


@pytest.mark.parametrize("way", LATE_WAYS)
def test_reply_after_its_timeout(way: str) -> None:
    # Delays in units of the per-attempt timeout land the late reply in the first
    # attempt, in a retry, in the next read of servo 2 and in the next read of servo 1.
    with lx_arm(way) as arm:
        unit = arm.bus.timeout_s(6, VIN_REPLY_BYTES)
        problems = _late_reply_outcomes(arm, [k * unit for k in (0.5, 1.2, 2.2, 3.5, 5.9, 6.5)])
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("way", LATE_WAYS)
def test_reply_after_its_timeout_without_retries(way: str) -> None:
    with lx_arm(way) as arm:
        arm.bus.retries = 0
        unit = arm.bus.timeout_s(6, VIN_REPLY_BYTES)
        problems = _late_reply_outcomes(arm, [k * unit for k in (1.2, 2.0, 2.5)])
    assert not problems, "\n".join(problems)


# ---------------------------------------------------------------------- garbled replies


@contextlib.contextmanager
def faulty_bus(way: str, faults: FaultInjection, **bus_kwargs: object
               ) -> Iterator[tuple[ServoBus, SimBus]]:
    """The arm with fault injection, one of conftest's ``LX_WAYS``: in-process on a
    simulated clock, or on a pty on the wall clock (with ``LATE_MARGIN_S``: every reply
    damaged, each read waits out its deadlines by design)."""
    kind, line = way.split("-")
    echo = line == "echo"
    sim = SimBus.with_ids(timing=WireTiming(), echo=echo, faults=faults,
                          clock=WALL_CLOCK if kind == "pty" else None)
    kwargs: dict[str, object] = {"echo": "on" if echo else "off", **bus_kwargs}
    server = None
    if kind == "pty":
        kwargs.setdefault("timeout_margin_s", LATE_MARGIN_S)
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


# Parametrized by ``way``: conftest marks the pty ways ``wallclock``.
@pytest.mark.parametrize("way", LX_WAYS)
def test_every_reply_garbled_never_gives_a_value(way: str) -> None:
    faults = FaultInjection(corrupt_rate=1.0, directions="tx", seed=3)
    with faulty_bus(way, faults) as (bus, sim):
        budget = read_budget_s(bus, Command.POS_READ)
        for sid in (1, 2, 10, 1):
            t0 = sim.clock.now()
            with pytest.raises(TYPED):
                value = bus.read_position_pulses(sid)
                pytest.fail(f"servo {sid}: garbled reply taken as position {value}")
            assert sim.clock.now() - t0 <= budget
        assert bus.stats["retries"] == 4 * bus.retries


# In this process only: which replies come back damaged is the simulator's doing, not
# the pty's (damaged bytes through a pty: test_every_reply_garbled_never_gives_a_value),
# and through a pty a loaded machine's late reply would be a timeout, not a value.
@pytest.mark.parametrize("way", ["inproc-noecho", "inproc-echo"])
def test_some_replies_garbled_give_right_values_or_checksum_errors(way: str) -> None:
    # One byte in ten corrupted: a reply whose header survives and whose body does not
    # is a ChecksumError (no retries here, so each read is one attempt).
    faults = FaultInjection(corrupt_rate=0.1, directions="tx", seed=11)
    with faulty_bus(way, faults, retries=0) as (bus, sim):
        now = sim.clock.now()
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


@pytest.mark.wallclock("pyserial's loop:// is a real transport: the deadlines a read "
                        "waits out are wall time")
def test_pyserial_loop_is_an_echoing_adapter_with_no_servo() -> None:
    bus = ServoBus.open("loop://")
    try:
        assert bus.echo is True, "loop:// hands back every byte: echo must be detected"
        for sid, read in ((1, bus.read_position_pulses), (2, bus.read_temp_c)):
            t0 = bus.clock.now()
            with pytest.raises(BusTimeoutError) as info:
                read(sid)
            assert bus.clock.now() - t0 <= read_budget_s(bus, Command.POS_READ)
            assert info.value.servo_id == sid
        # Its own ID_READ request coming back is not a servo answering.
        assert bus.scan(range(4)).found == []
    finally:
        bus.close()


@pytest.mark.wallclock("a real pty nobody answers: the read's deadline is waited out in "
                        "wall time")
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
                t0 = bus.clock.now()
                with pytest.raises(BusTimeoutError) as info:
                    bus.query(3, command)
                elapsed = bus.clock.now() - t0
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
    sim = SimBus([], timing=WireTiming())  # on a simulated clock: its time is exact
    bus = ServoBus(SimTransport(sim), echo="off", retries=retries)
    t0 = sim.clock.now()
    with pytest.raises(BusTimeoutError, match="did not answer"):
        bus.read_temp_c(4)
    elapsed = sim.clock.now() - t0
    assert elapsed <= read_budget_s(bus, Command.TEMP_READ), f"{elapsed * 1e3:.1f} ms"
    # ... and it really waited for each attempt: retries are not skipped.
    attempt_s = bus.timeout_s(6, 7)  # TEMP_READ: a 6-byte request, a 7-byte reply
    assert elapsed >= (retries + 1) * attempt_s - 1e-9, f"{elapsed * 1e3:.1f} ms"
    assert bus.stats["retries"] == retries
    assert sim.frames_received == retries + 1
