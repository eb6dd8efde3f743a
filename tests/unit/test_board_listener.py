"""BoardLink's listeners see every report the board sends, in order, dated by when it
came, whoever reads the link (a poll or a servo read); ``poll_if_idle`` never reads a
link that is in use.

Numbered reports (encoder frames whose first count is a sequence number) are put on the
simulated board's line, more at once than one read takes, to check order and dates.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from itertools import pairwise

import pytest

from busarm.bus.board import BoardLink
from busarm.bus.ports import open_transport
from busarm.clock import SimClock
from busarm.protocol.board import (
    FRAME_OVERHEAD,
    BoardReport,
    ImuSample,
    MotorEncoders,
    ServoSub,
)
from busarm.sim.board import SimBoard
from busarm.sim.bus import SimBus
from busarm.sim.spec import BoardSettings, SimSpec
from busarm.sim.transport import SimTransport

BURST = 400
"""Numbered frames put on the line at once: about 8.8 kB, more than one 4 kB read."""
FRAME_BYTES = len(MotorEncoders((0, 0, 0, 0)).encode())
Heard = list[tuple[BoardReport, float]]


def numbered(count: int) -> bytes:
    return b"".join(MotorEncoders((k, 0, 0, 0)).encode() for k in range(count))


def sequence(heard: Heard) -> list[int]:
    return [r.ticks[0] for r, _at in heard if isinstance(r, MotorEncoders)]


@pytest.fixture
def quiet_board() -> Iterator[tuple[SimClock, SimBoard, BoardLink, Heard]]:
    """A simulated board on a simulated clock that reports nothing on its own, its link,
    and what the link's listener heard."""
    clock = SimClock()
    board = SimBoard(SimBus.with_ids([1], clock=clock), imu_hz=0, battery_hz=0,
                     encoders=False)
    link = BoardLink(SimTransport(board))
    heard: Heard = []
    link.add_listener(lambda report, at_s: heard.append((report, at_s)))
    yield clock, board, link, heard
    link.close()


def test_a_burst_read_by_a_poll_reaches_the_listener_in_order(
        quiet_board: tuple[SimClock, SimBoard, BoardLink, Heard]) -> None:
    clock, board, link, heard = quiet_board
    board.inject(numbered(BURST))
    clock.sleep(0.1)  # all of it has come (8.8 ms of line at 1,000,000 baud)
    polled = link.poll()
    assert sequence(heard) == list(range(BURST))
    assert [r for r, _at in heard] == polled
    times = [at for _r, at in heard]
    assert all(b > a for a, b in pairwise(times))
    # Dated back by the line time of the frames behind each one (read at one instant).
    byte_s = 10.0 / link.transport.baudrate
    assert times[-1] == pytest.approx(clock.now())
    assert times[0] == pytest.approx(clock.now() - (BURST - 1) * FRAME_BYTES * byte_s)
    assert FRAME_BYTES == FRAME_OVERHEAD + 17


def test_a_burst_during_a_servo_read_reaches_the_listener_in_order(
        quiet_board: tuple[SimClock, SimBoard, BoardLink, Heard]) -> None:
    clock, board, link, heard = quiet_board
    injected: list[float] = []

    def burst_once() -> None:  # while the read below waits on the clock for its reply
        if not injected:
            injected.append(clock.now())
            board.inject(numbered(BURST // 2))

    clock.attach(burst_once)
    try:
        reply = link.servo_read(ServoSub.READ_POSITION, 1, retries=5)
    finally:
        clock.detach(burst_once)
    assert reply.ok
    assert injected
    link.poll(0.05)
    assert sequence(heard) == list(range(BURST // 2))
    times = [at for _r, at in heard]
    assert all(b >= a for a, b in pairwise(times))
    assert times[0] >= injected[0]


def test_every_report_of_the_board_reaches_the_listener_through_reads_and_polls() -> None:
    """On the wall clock, through ``open_transport``: the board's own IMU, encoder and
    battery stream, read partly by servo reads and partly by polls."""
    link = BoardLink(open_transport(SimSpec(ids=(1,), controller=BoardSettings(
        imu_hz=200, battery_hz=20))))
    heard: Heard = []
    try:
        link.add_listener(lambda report, at_s: heard.append((report, at_s)))
        link.poll(0.05)
        reports_before, started_s = link.readings.reports, link.clock.now()
        heard.clear()
        for k in range(30):
            if k % 3:
                link.servo_read(ServoSub.READ_POSITION, 1)
            else:
                link.poll(0.005)
        link.poll(0.02)
        elapsed_s = link.clock.now() - started_s
        assert len(heard) == link.readings.reports - reports_before
        times = [at for _r, at in heard]
        assert all(b >= a for a, b in pairwise(times))
        # The IMU at 200 Hz: none lost between the reads (a few in flight at either end).
        imu = sum(isinstance(r, ImuSample) for r, _at in heard)
        assert imu == pytest.approx(200 * elapsed_s, abs=3)
        encoders = sum(isinstance(r, MotorEncoders) for r, _at in heard)
        assert encoders == pytest.approx(imu, abs=2)  # sent at the IMU's rate
        assert link.readings.stray_replies == 0
    finally:
        link.close()


def test_poll_if_idle_reads_only_an_idle_link(
        quiet_board: tuple[SimClock, SimBoard, BoardLink, Heard]) -> None:
    clock, board, link, heard = quiet_board
    board.inject(numbered(3))
    clock.sleep(0.01)
    polled = link.poll_if_idle()  # idle: it polls
    assert polled is not None and sequence(heard) == [0, 1, 2]

    # Called back by the clock while this thread's servo read waits on it: None, and the
    # report that came meanwhile is the read's to take (the listener still hears it).
    board.inject(numbered(1))
    inside: list[object] = []

    def during_read() -> None:
        inside.append(link.poll_if_idle())

    clock.attach(during_read)
    try:
        assert link.servo_read(ServoSub.READ_POSITION, 1).ok
    finally:
        clock.detach(during_read)
    assert inside and all(result is None for result in inside)
    assert sequence(heard) == [0, 1, 2, 0]

    # From a listener (the link in use further up this thread's stack), and from another
    # thread while this one has the link: None.
    from_listener: list[object] = []
    from_thread: list[object] = []

    def listener(_report: BoardReport, _at_s: float) -> None:
        from_listener.append(link.poll_if_idle())
        other = threading.Thread(target=lambda: from_thread.append(link.poll_if_idle()))
        other.start()
        other.join(timeout=5)

    link.add_listener(listener)
    board.inject(numbered(1))
    clock.sleep(0.01)
    assert len(link.poll()) == 1
    assert from_listener == [None] and from_thread == [None]

