"""The controller board's link on a real pseudo-terminal: a simulated board (SimBoard)
served by PtyServer, opened as ``SerialPort("/dev/pts/N", board=True)`` (the command
line's ``board:///dev/pts/N``) like the real one.

Through the pty the board answers in wall-clock time (those tests are marked
``wallclock``), and the link there has a generous margin (``PTY_LINK_MARGIN_S``) in
every deadline: a reply a busy computer hears late is not what these tests are about.
Replies the board damages or misaddresses are the simulated board's doing, not the
pty's: those reads run in this process on a simulated clock, where each read that waits
out its deadlines is held to its budget exactly. A silent board runs both ways (through
the pty its deadline is the subject; the time check there is a bound on a hang, with
slack for a loaded machine). A flood of reports, the wheels' speeds and counts, and the
stops are the simulated board's own doing: in this process only.

The rule every read test checks: a read through the board returns the servo's true value
or raises a typed busarm error (BusTimeoutError, ProtocolError, ChecksumError), within
``BoardLink.read_budget_s`` (plus scheduling slack) — a silent board, garbled or
misaddressed replies, garbage on the line or a flood of IMU reports never hang a read
nor make it return a wrong value. Then what the board reports on its own (IMU, battery,
keys), the wheel motors, bad input refused with nothing sent, frames the board refuses,
and the emergency stop.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from typing import Any

import pytest

from busarm.bus.board import BoardLink
from busarm.bus.board_bus import BoardServoBus
from busarm.bus.driver import ServoBus
from busarm.bus.ports import SerialPort, open_transport
from busarm.clock import WALL_CLOCK
from busarm.errors import (
    BusArmError,
    BusConflictError,
    BusTimeoutError,
    ChecksumError,
    ConfigError,
    ProtocolError,
)
from busarm.protocol.board import (
    BoardFrameParser,
    BoardRequest,
    Func,
    ImuSample,
    KeyEvent,
    KeyEventKind,
    MotorSpeeds,
    ServoRead,
    ServoReply,
    ServoSub,
    crc8_maxim,
    decode_request,
    encode_frame,
)
from busarm.sim.board import ENCODER_TICKS_PER_REV, BoardFaults, SimBoard
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport
from conftest import wait_for

on_the_pty = pytest.mark.wallclock(
    "a simulated board served on a real pty by a thread, in wall-clock time")
WAYS = ["inproc", "pty"]
"""The board in this process on a simulated clock, or served on a pty (the ``way``
parameter: conftest marks the pty way ``wallclock``)."""

SLACK_S = 0.5
"""What each attempt of a read through the pty may take beyond its deadline: a loaded
2-core machine (other tests, CPU-bound programs: a load of 20 was seen) may wake a
waiting thread 400 ms late, and the board's server thread shares this process. A bound
on a hang, not a speed target: in this process, on the simulated clock, a read is held
to its budget exactly."""
PTY_LINK_MARGIN_S = 0.5
"""The reply margin of a link through the pty, where every read is answered in the end
(free: a read ends with its reply; at a load of 20 a reply was seen 400 ms late). The
silent board's test, which waits out every deadline by design, takes 0.1 s: a reply
cannot come late where none comes."""


@pytest.fixture(autouse=True)
def _no_gc_pauses_on_the_wall_clock(request: pytest.FixtureRequest) -> None:
    """A read timed on the wall clock must not be charged a collection of the earlier
    tests' objects (tens of ms); on a simulated clock a collection takes no time."""
    if request.node.get_closest_marker("wallclock") is not None:
        request.getfixturevalue("no_gc_pauses")
TRUE_PULSES = {1: 120, 2: 480, 3: 910}
"""Distinct resting positions, so that one servo's value is never right for another."""
ABSENT_ID = 9
TYPED = (BusTimeoutError, ProtocolError)  # ChecksumError is a ProtocolError


class ListeningBoard(SimBoard):
    """A simulated board that keeps every request the host sent it, parsed from the bytes."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.heard: list[BoardRequest] = []
        self._wire = BoardFrameParser()

    def receive(self, data: bytes) -> None:
        for frame in self._wire.feed(data):
            with suppress(ProtocolError):  # counted by the board itself (log.rejected_frames)
                self.heard.append(decode_request(frame))
        super().receive(data)

    def motor_requests(self) -> list[MotorSpeeds]:
        return [r for r in self.heard if isinstance(r, MotorSpeeds)]


@dataclass
class Served:
    """A simulated board: the servos behind it, the board, its port (on a pty; None in
    this process)."""

    sim: SimBus
    board: ListeningBoard
    port: SerialPort | None

    def position_pulses(self, servo_id: int) -> float:
        """Where the simulated servo is now."""
        self.sim.advance()
        return self.sim.servo(servo_id).position_pulses

    def true_pulses(self, servo_id: int) -> int:
        """What its POS_READ says now."""
        return round(self.position_pulses(servo_id))


def board_on(sim: SimBus, faults: BoardFaults | None = None, **board_kwargs: Any
             ) -> ListeningBoard:
    """A listening board in front of ``sim``, servos 1-3 moved to TRUE_PULSES."""
    for sid, pulses in TRUE_PULSES.items():
        sim.servo(sid).move_by_hand(pulses, sim.clock.now())
    return ListeningBoard(sim, faults=faults, **board_kwargs)


@contextmanager
def served(faults: BoardFaults | None = None, way: str = "pty", **board_kwargs: Any
           ) -> Iterator[Served]:
    """Servos 1-3 at TRUE_PULSES behind a simulated board served on a pty (wall clock),
    or (``way`` "inproc") in this process on a simulated clock."""
    if way == "inproc":
        sim = SimBus.with_ids(list(TRUE_PULSES), timing=WireTiming())
        yield Served(sim, board_on(sim, faults, **board_kwargs), None)
        return
    sim = SimBus.with_ids(list(TRUE_PULSES), timing=WireTiming(), clock=WALL_CLOCK)
    board = board_on(sim, faults, **board_kwargs)
    server = PtyServer(board)
    try:
        yield Served(sim, board, SerialPort(server.start(), board=True))
    finally:
        server.stop()


@contextmanager
def link_to(s: Served, **options: Any) -> Iterator[BoardLink]:
    """A link to the board ``s``: on its pty (with ``PTY_LINK_MARGIN_S`` unless given),
    or in this process."""
    if s.port is not None:
        options.setdefault("timeout_margin_s", PTY_LINK_MARGIN_S)
    link = BoardLink(open_transport(s.port) if s.port is not None else SimTransport(s.board),
                     **options)
    try:
        yield link
    finally:
        link.close()


@pytest.fixture
def board() -> Iterator[Served]:
    with served() as s:
        yield s


@pytest.fixture
def inproc() -> Iterator[Served]:
    """Servos 1-3 at TRUE_PULSES behind a simulated board in this process, on a
    simulated clock (``sim.clock``)."""
    with served(way="inproc") as s:
        yield s


def timed_read(link: BoardLink, sub: ServoSub, servo_id: int) -> ServoReply | BusArmError:
    """The reply, or the typed error, of one read, checked to end within its budget
    (with ``SLACK_S`` for each attempt on the wall clock)."""
    clock = link.clock
    started = clock.now()
    try:
        result: ServoReply | BusArmError = link.servo_read(sub, servo_id)
    except TYPED as exc:
        result = exc
    elapsed_s = clock.now() - started
    # On a simulated clock a read that waits out every attempt takes its budget exactly
    # (but for floating-point rounding).
    budget_s = link.read_budget_s(sub) + (
        1e-9 if clock.is_simulated else (link.retries + 1) * SLACK_S)
    assert elapsed_s <= budget_s, f"{sub.name} of {servo_id}: {elapsed_s * 1e3:.1f} ms"
    return result


def sync(link: BoardLink, s: Served) -> None:
    """Everything sent before has reached the board: a read after it has come back."""
    reply = link.servo_read(ServoSub.READ_POSITION, 1)
    assert reply.values == (s.true_pulses(1),)


# ---------------------------------------------------------------------- failing reads


@pytest.mark.parametrize("way", WAYS)
def test_a_silent_board_times_out_every_read_within_its_budget(way: str) -> None:
    margin = {"timeout_margin_s": 0.1} if way == "pty" else {}
    with served(BoardFaults(silent=True), way) as s, link_to(s, **margin) as link:
        for sub in (ServoSub.READ_POSITION, ServoSub.READ_VOLTAGE, ServoSub.READ_ANGLE_LIMITS):
            error = timed_read(link, sub, 1)
            assert isinstance(error, BusTimeoutError), error
            assert "nothing came back" in str(error)
        started = link.clock.now()
        with pytest.raises(BusTimeoutError, match="no IMU sample"):
            link.read_imu(timeout_s=0.2)
        assert link.clock.now() - started <= 0.2 + (1e-9 if s.sim.clock.is_simulated else SLACK_S)
        with pytest.raises(BusTimeoutError, match="is it powered"):
            link.check_talking(timeout_s=0.1)


# Damaged and misaddressed replies: the board's doing, in this process on simulated time
# (through the pty, a reply a loaded machine delivers after its margin would be a timeout).
def test_garbled_replies_give_the_true_value_or_a_checksum_error() -> None:
    with (served(BoardFaults(corrupt_rate=0.5, seed=4), "inproc") as s,
          link_to(s, retries=0) as link):
        outcomes = [timed_read(link, ServoSub.READ_POSITION, 1 + i % 3) for i in range(40)]
        for i, outcome in enumerate(outcomes):
            if isinstance(outcome, ServoReply):
                assert outcome.values == (s.true_pulses(1 + i % 3),), (i, outcome)
            else:
                assert isinstance(outcome, ChecksumError), outcome
                assert "damaged frames came back" in str(outcome), outcome
        values = [o for o in outcomes if isinstance(o, ServoReply)]
        assert 5 <= len(values) <= 35, "half the replies should be damaged"


def test_retries_see_through_garbled_replies_and_always_garbled_ones_fail_typed() -> None:
    with served(BoardFaults(corrupt_rate=0.5, seed=7), "inproc") as s, link_to(s) as link:
        for i in range(20):
            outcome = timed_read(link, ServoSub.READ_POSITION, 1 + i % 3)
            if isinstance(outcome, ServoReply):
                assert outcome.values == (s.true_pulses(1 + i % 3),)
            else:
                assert isinstance(outcome, ChecksumError), outcome
    with served(BoardFaults(corrupt_rate=1.0), "inproc") as s, link_to(s) as link:
        for sub in (ServoSub.READ_POSITION, ServoSub.READ_TEMPERATURE):
            error = timed_read(link, sub, 2)
            assert isinstance(error, ChecksumError), error
            assert "in 3 attempts" in str(error)


def test_a_reply_for_another_servo_is_never_taken() -> None:
    with served(BoardFaults(wrong_id_rate=1.0), "inproc") as s, link_to(s) as link:
        for sid in (1, 2):
            error = timed_read(link, ServoSub.READ_POSITION, sid)
            assert isinstance(error, ProtocolError), error
            assert f"a reply for servo {sid + 1} came instead" in str(error)
        assert link.readings.stray_replies >= 2  # (one a read, at least; late ones are polled)
    with (served(BoardFaults(wrong_id_rate=0.5, seed=3), "inproc") as s,
          link_to(s, retries=0) as link):
        outcomes = [timed_read(link, ServoSub.READ_POSITION, 1 + i % 3) for i in range(30)]
        for i, outcome in enumerate(outcomes):
            if isinstance(outcome, ServoReply):
                assert outcome.values == (s.true_pulses(1 + i % 3),), (i, outcome)
            else:
                assert type(outcome) is ProtocolError, outcome
        assert any(isinstance(o, ServoReply) for o in outcomes)
        assert any(isinstance(o, ProtocolError) for o in outcomes)


@on_the_pty
def test_a_servo_absent_behind_the_board_is_a_typed_timeout(board: Served) -> None:
    with link_to(board) as link:
        error = timed_read(link, ServoSub.READ_POSITION, ABSENT_ID)
        assert isinstance(error, BusTimeoutError), error
        assert "the board said the servo did not answer (status -1)" in str(error)
        assert timed_read(link, ServoSub.READ_POSITION, 3) == ServoReply(
            3, ServoSub.READ_POSITION, 0, (TRUE_PULSES[3],))
    with ServoBus.open(board.port, timeout_margin_s=PTY_LINK_MARGIN_S) as bus:
        with pytest.raises(BusTimeoutError, match=f"servo {ABSENT_ID} read position"):
            bus.read_position_pulses(ABSENT_ID)
        assert bus.read_position_pulses(2) == TRUE_PULSES[2]


@on_the_pty
def test_garbage_and_stray_frames_on_the_line_are_never_an_answer(board: Served) -> None:
    stray_same = ServoReply(1, ServoSub.READ_POSITION, 0, (999,)).encode()
    with link_to(board) as link:
        board.board.inject(stray_same)
        assert wait_for(lambda: any(isinstance(r, ServoReply) for r in link.poll(0.05)))
        before = link.readings.stray_replies
        # Noise, half a header, a false header announcing a long frame, a damaged frame,
        # replies for another servo and for another read, then the read itself.
        damaged = bytearray(ServoReply(1, ServoSub.READ_POSITION, 0, (777,)).encode())
        damaged[-2] ^= 0xFF
        board.board.inject(b"\x00\xff\xaa\x13\xaa" + b"\xaa\x55\x05\x30\x01" + bytes(damaged)
                           + ServoReply(2, ServoSub.READ_POSITION, 0, (888,)).encode()
                           + ServoReply(1, ServoSub.READ_VOLTAGE, 0, (4321,)).encode())
        for _ in range(5):
            reply = timed_read(link, ServoSub.READ_POSITION, 1)
            assert isinstance(reply, ServoReply) and reply.values == (TRUE_PULSES[1],), reply
        assert link.readings.stray_replies >= before + 2
        assert link.servo_read(ServoSub.READ_POSITION, 2).values == (TRUE_PULSES[2],)


def test_a_flood_of_imu_reports_neither_delays_nor_replaces_servo_reads() -> None:
    # 4000 Hz asks for more than the 1,000,000 baud line carries (29-byte reports). In
    # this process on simulated time: through a pty a loaded machine stalls the board's
    # server thread, which then sends fewer reports (no flood) and replies late.
    subs = (ServoSub.READ_POSITION, ServoSub.READ_VOLTAGE, ServoSub.READ_ID)
    with served(imu_hz=4000.0, way="inproc") as s, link_to(s) as link:
        started = link.clock.now()
        reads = 0
        while link.clock.now() - started < 0.8:
            sid, sub = 1 + reads % 3, subs[reads % len(subs)]
            reply = timed_read(link, sub, sid)
            assert isinstance(reply, ServoReply), reply
            want = {ServoSub.READ_POSITION: s.true_pulses(sid),
                    ServoSub.READ_VOLTAGE: s.sim.servo(sid).supply_mv,
                    ServoSub.READ_ID: sid}[sub]
            assert reply.values == (want,), (sub, sid, reply)
            reads += 1
        elapsed_s = link.clock.now() - started
        assert reads > 20
        assert link.readings.reports > 1000 * elapsed_s, "not a flood"


# ---------------------------------------------------------------------- what the board reports


@on_the_pty
def test_imu_and_battery_readings_come_through_in_si_units() -> None:
    with served(battery_hz=20.0, battery_v=11.1) as s:
        s.board.imu_gyro_rad_s = (0.1, -0.2, 0.3)
        with link_to(s) as link:
            sync(link, s)  # after it, each IMU sample is of the gyro turning
            sample = link.read_imu()
            assert isinstance(sample, ImuSample)
            assert sample.accel_mps2 == pytest.approx((0.0, 0.0, 9.80665), abs=0.1)
            assert sample.gyro_rad_s == pytest.approx((0.1, -0.2, 0.3), abs=0.01)
            battery_v = link.read_battery_v()
            assert isinstance(battery_v, float) and battery_v == pytest.approx(11.1, abs=0.05)

            s.board.imu_gyro_rad_s = (0.0, 0.0, -1.0)
            s.board.imu_accel_mps2 = (9.80665, 0.0, 0.0)  # on its side
            s.board.battery_v = 10.4
            # A servo's reply comes after every report the board made before it (one
            # line, in order): after it, each IMU sample is of the board on its side.
            sync(link, s)
            sample = link.read_imu()
            assert sample.accel_mps2 == pytest.approx((9.80665, 0.0, 0.0), abs=0.1)
            assert sample.gyro_rad_s == pytest.approx((0.0, 0.0, -1.0), abs=0.01)
            # The latest battery report may be older than the change: the next one says it.
            assert wait_for(lambda: link.read_battery_v() == pytest.approx(10.4, abs=0.05))


@on_the_pty
def test_key_presses_come_out_of_key_events_once(board: Served) -> None:
    with link_to(board) as link:
        assert link.key_events() == []
        board.board.press_key(1, KeyEventKind.CLICK)
        board.board.press_key(2, KeyEventKind.LONG_PRESS)
        seen: list[KeyEvent] = []

        def both_seen() -> bool:
            seen.extend(link.key_events())
            return len(seen) >= 2

        assert wait_for(both_seen), seen
        assert seen == [KeyEvent(1, KeyEventKind.CLICK), KeyEvent(2, KeyEventKind.LONG_PRESS)]
        sync(link, board)  # everything the board sent after the presses has come
        assert link.key_events() == []


# ---------------------------------------------------------------------- bad input


@on_the_pty
@pytest.mark.parametrize(("speeds", "said"), [
    ({1: 2.0}, "motor 1 speed = 2.0 rev/s is out of range -1.5..1.5 rev/s"),
    ({1: 0.5, 2: -1.6}, "motor 2 speed = -1.6 rev/s is out of range -1.5..1.5 rev/s"),
    ({0: 1.0}, "motor = 0; allowed: 1..4"),
    ({5: 1.0}, "motor = 5; allowed: 1..4"),
    ({1: math.nan}, "motor 1 speed = nan rev/s is out of range -1.5..1.5 rev/s"),
])
def test_bad_wheel_speeds_are_refused_with_nothing_sent(
        board: Served, speeds: dict[int, float], said: str) -> None:
    with link_to(board) as link:
        with pytest.raises(ConfigError) as refused:
            link.set_motor_speeds(speeds)
        assert str(refused.value) == said
        sync(link, board)
    assert board.board.motor_requests() == []
    assert {type(r) for r in board.board.heard} == {ServoRead}  # the sync reads alone
    assert all(w.target_rev_s == 0.0 and w.rev_s == 0.0 for w in board.board.wheels)


def _frame(func: int, data: bytes) -> bytes:
    """A frame with any function code (encode_frame refuses the board's unknown ones)."""
    body = bytes((func, len(data))) + data
    return b"\xaa\x55" + body + bytes((crc8_maxim(body),))


@on_the_pty
def test_frames_the_board_does_not_take_are_refused_without_effect(board: Served) -> None:
    motor_4_at_1 = bytes((0x01, 1, 3)) + struct.pack("<f", 1.0)  # motors count from 0
    damaged = bytearray(encode_frame(Func.MOTOR, motor_4_at_1))
    damaged[-1] ^= 0x5A
    bad = [
        _frame(12, b"\x01"),  # function codes stop at 11
        _frame(200, motor_4_at_1),
        bytes(damaged),  # a bad CRC
        encode_frame(Func.MOTOR, bytes((0x01, 1, 4)) + struct.pack("<f", 1.0)),  # a 5th motor
        encode_frame(Func.MOTOR, bytes((0x01, 2, 0)) + struct.pack("<f", 1.0)),  # 2 said, 1 given
        encode_frame(Func.BUS_SERVO, bytes((ServoSub.READ_POSITION, 1, 0))),  # a byte too many
        encode_frame(Func.BUS_SERVO, bytes((0x7F, 1))),  # no such sub-command
        encode_frame(Func.BUS_SERVO, bytes((ServoSub.MOVE, 0xE8, 0x03, 2, 1, 0xF4, 0x01))),
        encode_frame(Func.BUZZER, b"\x01\x02"),  # too short
    ]
    with link_to(board) as link:
        for frame in bad:
            link.transport.write(frame)
        sync(link, board)
        assert board.board.log.rejected_frames == len(bad)
        assert {type(r) for r in board.board.heard} == {ServoRead}  # the sync reads alone
        assert all(w.target_rev_s == 0.0 for w in board.board.wheels)
        assert board.board.log.buzzer == [] and board.board.log.led == []
        assert {sid: board.true_pulses(sid) for sid in TRUE_PULSES} == TRUE_PULSES
        link.set_motor_speeds({4: 1.0})  # and it still takes good ones
        sync(link, board)
        assert [w.target_rev_s for w in board.board.wheels] == [0.0, 0.0, 0.0, 1.0]
        link.stop_motors()


# ---------------------------------------------------------------------- wheels and stops


def _wheels_now(s: Served) -> list[tuple[float, int]]:
    """Each wheel's speed (rev/s) and encoder count, brought up to now."""
    s.board.next_output_at()  # moves the wheels to the present
    return [(w.rev_s, w.encoder_ticks) for w in s.board.wheels]


def test_wheels_approach_their_speed_and_count_3960_ticks_a_turn(inproc: Served) -> None:
    targets = {1: 1.0, 2: -0.5, 3: 1.5, 4: 0.0}
    clock = inproc.sim.clock
    with link_to(inproc) as link:
        link.set_motor_speeds(targets)
        sync(link, inproc)
        speeds = []
        for _ in range(4):
            speeds.append([rev_s for rev_s, _ in _wheels_now(inproc)])
            clock.sleep(0.05)
        for m in (1, 2, 3):  # every sample nearer the target than the one before
            gaps = [abs(targets[m] - sample[m - 1]) for sample in speeds]
            assert gaps == sorted(gaps, reverse=True) and gaps[0] > gaps[-1], (m, gaps)
        clock.sleep(0.5)  # over 6 time constants: at speed
        started_s, before = clock.now(), _wheels_now(inproc)
        clock.sleep(0.4)
        elapsed_s, after = clock.now() - started_s, _wheels_now(inproc)
        for m, target in targets.items():
            assert after[m - 1][0] == pytest.approx(target, abs=0.01)
            ticks = after[m - 1][1] - before[m - 1][1]
            want = target * ENCODER_TICKS_PER_REV * elapsed_s
            # On the simulated clock the time is exact: the count is off by the part of a
            # turn still spent speeding up (under 0.1 %) and a tick's rounding either end.
            assert ticks == pytest.approx(want, abs=0.001 * ENCODER_TICKS_PER_REV * abs(target)
                                          + 2), (m, ticks, want)
        assert ENCODER_TICKS_PER_REV == 3960
        link.stop_motors()
        sync(link, inproc)
    assert [w.target_rev_s for w in inproc.board.wheels] == [0.0] * 4


def _assert_stopped_and_holding(s: Served, moved_from_pulses: int) -> None:
    """Every wheel stopped; servo 1 stopped short of its target, holding (torque on)."""
    clock = s.sim.clock
    assert wait_for(lambda: all(abs(rev_s) < 0.01 for rev_s, _ in _wheels_now(s)), 2.0, clock)
    assert [w.target_rev_s for w in s.board.wheels] == [0.0] * 4
    at = s.position_pulses(1)
    assert moved_from_pulses < at < 900, at  # stopped on its way to 900
    clock.sleep(0.2)
    assert s.position_pulses(1) == pytest.approx(at, abs=1), "it did not stay stopped"
    assert s.sim.servo(1).is_loaded, "the stop made the servo limp"


def test_the_emergency_stop_stops_the_wheels_and_holds_the_servos(inproc: Served) -> None:
    with BoardServoBus.on(SimTransport(inproc.board)) as bus:
        bus.move_pulses(1, 900, 2000)
        bus.link.set_motor_speeds({1: 1.0, 2: -1.0, 3: 0.5, 4: -0.5})
        inproc.sim.clock.sleep(0.4)
        bus.emergency_stop()
        _assert_stopped_and_holding(inproc, TRUE_PULSES[1])
        assert bus.read_torque(1) is True


@pytest.mark.parametrize("servo_moved", [True, False])
def test_leaving_a_board_bus_by_an_exception_stops_the_wheels(
        inproc: Served, servo_moved: bool) -> None:
    with (pytest.raises(RuntimeError, match="the program failed"),
          BoardServoBus.on(SimTransport(inproc.board)) as bus):
        if servo_moved:
            bus.move_pulses(1, 900, 2000)
        bus.link.set_motor_speeds({1: 1.0, 4: -1.0})
        inproc.sim.clock.sleep(0.4)
        raise RuntimeError("the program failed")
    if servo_moved:
        _assert_stopped_and_holding(inproc, TRUE_PULSES[1])
    else:
        assert wait_for(lambda: all(abs(rev_s) < 0.01 for rev_s, _ in _wheels_now(inproc)),
                        2.0, inproc.sim.clock)
        assert inproc.true_pulses(1) == TRUE_PULSES[1]


@pytest.mark.parametrize("ids", [[1, 3, 3], [1, 2]])
def test_set_id_through_the_board_needs_the_servo_alone_on_the_bus(ids: list[int]) -> None:
    """Two servos sharing an ID look like none through the board, so renumbering is done
    only when the broadcast ID read shows one servo on the bus; nothing is written else."""
    sim = SimBus.with_ids(ids, timing=WireTiming())  # in this process, simulated time
    written: list[object] = []

    def tap(request: Any) -> None:  # what reached the servos, reads aside
        if not request.command.name.endswith("_READ"):
            written.append(request)

    sim.taps.append(tap)
    with BoardServoBus.on(SimTransport(SimBoard(sim))) as bus:
        with pytest.raises(BusConflictError, match="exactly one servo"):
            bus.set_id(1, 3)
        assert written == []
        assert sorted(s.servo_id for s in sim.servos) == sorted(ids)


def test_set_id_through_the_board_renumbers_a_lone_servo() -> None:
    sim = SimBus.with_ids([3], timing=WireTiming())  # in this process, simulated time
    with BoardServoBus.on(SimTransport(SimBoard(sim))) as bus:
        bus.set_id(3, 7)
        assert bus.read_id() == 7
        assert [s.servo_id for s in sim.servos] == [7]
