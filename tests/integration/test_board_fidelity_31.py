"""Issue 31: the simulated board does what the vendor's firmware does with out-of-range
values and PWM servo reads, seen through the real path: frames written as bytes to the
simulated board (SimTransport, simulated clock), answers read back through BoardLink.

The firmware's rules (its published ``serial_servo.c`` and ``packet_handle.c``): a
position above 1000 is sent as 1000 and the rest of the frame still moves; a temperature
limit above 100 is written as 100; angle limits are capped at 1000 and put in order;
voltage limits are held to 4500..14000 mV and put in order; a PWM servo read for ports
1..4 is always answered ``[port, 05, pulse u16]``.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator

import pytest

from busarm.bus.board import BoardLink
from busarm.errors import ConfigError
from busarm.protocol import Command, FrameParser
from busarm.protocol.board import (
    Func,
    PwmServoRead,
    PwmServoReply,
    PwmSub,
    ServoSub,
    ServoWrite,
    decode_frame,
    decode_report,
    encode_frame,
)
from busarm.protocol.frames import Frame
from busarm.sim.board import PWM_START_US, SimBoard
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.transport import SimTransport

S = ServoSub


@pytest.fixture
def link() -> Iterator[tuple[BoardLink, SimBoard]]:
    sim = SimBus.with_ids([4, 5], timing=WireTiming())
    board = SimBoard(sim)
    link = BoardLink(SimTransport(board))
    try:
        yield link, board
    finally:
        link.close()


def _value(link: BoardLink, sub: ServoSub, servo_id: int) -> tuple[int, ...]:
    return tuple(link.servo_read(sub, servo_id).values)


def test_firmware_clamps_and_orders_what_it_writes_and_moves_every_servo(
        link: tuple[BoardLink, SimBoard]) -> None:
    lnk, board = link
    written: list[Frame] = []  # what the board put on the servo line
    lx = FrameParser()
    servos_receive = board.servos.receive

    def tap(data: bytes) -> None:
        written.extend(lx.feed(data))
        servos_receive(data)

    board.servos.receive = tap  # type: ignore[method-assign]
    # The vendor SDK's bus_servo_set_position(0.5, [[4, 400], [5, 1100]]): busarm's own
    # ServoMove refuses 1100, so the frame is written as the SDK writes it.
    lnk.transport.write(encode_frame(Func.BUS_SERVO, bytes.fromhex(
        "01 f4 01 02 04 90 01 05 4c 04")))
    lnk.clock.sleep(0.7)
    assert _value(lnk, S.READ_POSITION, 4) == (400,)
    assert _value(lnk, S.READ_POSITION, 5) == (1000,)  # clamped, and moved
    for write in (ServoWrite(S.SET_TEMP_LIMIT, 4, (120,)),
                  ServoWrite(S.SET_ANGLE_LIMITS, 4, (900, 100)),
                  ServoWrite(S.SET_VOLTAGE_LIMITS, 4, (4500, 14500)),
                  ServoWrite(S.SET_ANGLE_LIMITS, 5, (1200, 300)),
                  ServoWrite(S.SET_VOLTAGE_LIMITS, 5, (12000, 3000))):
        lnk.write(write)
    assert _value(lnk, S.READ_TEMP_LIMIT, 4) == (100,)
    assert _value(lnk, S.READ_ANGLE_LIMITS, 4) == (100, 900)
    assert _value(lnk, S.READ_ANGLE_LIMITS, 5) == (300, 1000)  # capped, then ordered
    limits = [(f.servo_id, struct.unpack("<HH", f.params)) for f in written
              if f.command == Command.VIN_LIMIT_WRITE]
    # The firmware caps the low one at 4500 and the high one at 14000, then orders them:
    # a 3000 given as the high one is not raised (serial_servo_set_vin_limit).
    assert limits == [(4, (4500, 14000)), (5, (3000, 12000))]
    moves = [struct.unpack("<HH", f.params)[0] for f in written
             if f.command == Command.MOVE_TIME_WRITE]
    assert moves == [400, 1000]
    assert board.log.rejected_frames == 0


def test_every_pwm_port_answers_a_read_and_moves_over_its_duration(
        link: tuple[BoardLink, SimBoard]) -> None:
    lnk, board = link
    # Raw reads, as the vendor SDK sends them: each port answers, before any move.
    for port in range(1, 5):
        lnk.transport.write(PwmServoRead(PwmSub.READ_POSITION, port).encode())
    replies: list[PwmServoReply] = []
    for _ in range(20):
        replies += [r for r in lnk.poll(0.01) if isinstance(r, PwmServoReply)]
        if len(replies) == 4:
            break
    assert replies == [PwmServoReply(p, PwmSub.READ_POSITION, PWM_START_US) for p in range(1, 5)]
    lnk.transport.write(PwmServoRead(PwmSub.READ_OFFSET, 3).encode())
    assert PwmServoReply(3, PwmSub.READ_OFFSET, 0) in lnk.poll(0.05)

    lnk.pwm_move({1: 2500, 3: 1000}, duration_s=1.0)
    lnk.clock.sleep(0.5)
    assert lnk.pwm_read_us(1) == pytest.approx(2000, abs=15)  # half way, the firmware's ramp
    lnk.clock.sleep(0.6)
    assert [lnk.pwm_read_us(p) for p in range(1, 5)] == [2500, PWM_START_US, 1000,
                                                         PWM_START_US]
    assert board.log.rejected_frames == 0


@pytest.mark.parametrize(("targets", "message"), [
    ({1: 2600}, r"PWM port 1 pulse_us .*2600.*500\.\.2500 us"),
    ({1: 499}, r"PWM port 1 pulse_us .*499.*500\.\.2500 us"),
    ({5: 1500}, r"PWM port .*5.*1\.\.4"),
    ({}, r"no port"),
])
def test_a_bad_pwm_value_is_refused_naming_it_and_nothing_is_sent(
        link: tuple[BoardLink, SimBoard], targets: dict[int, int], message: str) -> None:
    lnk, board = link
    sent: list[bytes] = []
    write = lnk.transport.write
    lnk.transport.write = lambda data: (sent.append(data), write(data))[1]  # type: ignore[method-assign]
    with pytest.raises(ConfigError, match=message):
        lnk.pwm_move(targets, duration_s=0.5)
    assert sent == []
    assert all(s.target_us == PWM_START_US for s in board.pwm_servos)


def test_a_pwm_reply_decodes_as_the_sdk_unpacks_it() -> None:
    """The SDK unpacks a position reply with ``<BBH`` (id, sub, pulse): no status byte."""
    raw = PwmServoReply(2, PwmSub.READ_POSITION, 1800).encode()
    assert raw[4:-1] == bytes((2, 0x05)) + (1800).to_bytes(2, "little")
    assert decode_report(decode_frame(raw)) == PwmServoReply(2, PwmSub.READ_POSITION, 1800)
