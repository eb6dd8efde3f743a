"""Byte vectors of the controller board's protocol, from field-notes section 5.

Every expected frame was written from the notes' layouts (``AA 55 | func | len | data |
crc8``, little-endian fields) and checksummed with a bitwise CRC-8/MAXIM written from
its definition (reflected polynomial 0x8C, init 0, no final XOR), not with busarm, so
these tests are an oracle independent of the codec. That CRC reproduces the notes'
check value and both of their worked examples.
"""

from __future__ import annotations

import math
import re

import pytest

from busarm.errors import ChecksumError, ConfigError, ProtocolError
from busarm.protocol.board import (
    LX_COMMANDS,
    READ_FORMATS,
    WRITE_FORMATS,
    Battery,
    BoardFrame,
    BoardFrameParser,
    BoardReport,
    BoardRequest,
    BuzzerBeep,
    Func,
    GamepadState,
    ImuSample,
    KeyEvent,
    KeyEventKind,
    LedBlink,
    MotorSpeeds,
    OledText,
    PwmServoMove,
    SbusState,
    ServoMove,
    ServoRead,
    ServoReply,
    ServoStop,
    ServoSub,
    ServoWrite,
    crc8_maxim,
    decode_frame,
    decode_report,
    decode_request,
    encode_frame,
)
from busarm.protocol.commands import Command

WORKED_MOVE = "aa 55 05 07 01 e8 03 01 01 f4 01 f5"
"""The notes' example: move servo 1 to 500 in 1000 ms."""
WORKED_READ = "aa 55 05 02 05 01 6f"
"""The notes' example: read servo 1's position."""
S = ServoSub


def oracle_crc8(data: bytes) -> int:
    """CRC-8/MAXIM bit by bit, straight from its definition."""
    crc = 0
    for byte in data:
        for _ in range(8):
            mix = (crc ^ byte) & 1
            crc >>= 1
            if mix:
                crc ^= 0x8C
            byte >>= 1
    return crc


def oracle_frame(func: int, data: bytes) -> bytes:
    body = bytes((func, len(data))) + data
    return b"\xaa\x55" + body + bytes((oracle_crc8(body),))


# (typed request, the bytes the notes' layout gives): every BUS_SERVO sub-command and
# every other request.
REQUEST_VECTORS: list[tuple[BoardRequest, str]] = [
    (ServoMove(1000, ((1, 500),)), WORKED_MOVE),
    (ServoMove(0, ((1, 0), (254, 1000))), "aa 55 05 0a 01 00 00 02 01 00 00 fe e8 03 87"),
    (ServoStop((1, 2, 3)), "aa 55 05 05 03 03 01 02 03 3c"),
    (ServoRead(S.READ_POSITION, 1), WORKED_READ),
    (ServoRead(S.READ_VOLTAGE, 1), "aa 55 05 02 07 01 fe"),
    (ServoRead(S.READ_TEMPERATURE, 1), "aa 55 05 02 09 01 22"),
    (ServoRead(S.READ_TORQUE, 1), "aa 55 05 02 0d 01 19"),
    (ServoRead(S.READ_ID, 1), "aa 55 05 02 12 01 ed"),
    (ServoRead(S.READ_ID, 254), "aa 55 05 02 12 fe d8"),
    (ServoRead(S.READ_OFFSET, 1), "aa 55 05 02 22 01 c0"),
    (ServoRead(S.READ_ANGLE_LIMITS, 1), "aa 55 05 02 32 01 2c"),
    (ServoRead(S.READ_VOLTAGE_LIMITS, 1), "aa 55 05 02 36 01 17"),
    (ServoRead(S.READ_TEMP_LIMIT, 1), "aa 55 05 02 3a 01 5a"),
    (ServoWrite(S.TORQUE_OFF, 1), "aa 55 05 02 0b 01 b3"),
    (ServoWrite(S.TORQUE_ON, 1), "aa 55 05 02 0c 01 dd"),
    (ServoWrite(S.SET_ID, 1, (2,)), "aa 55 05 03 10 01 02 68"),
    (ServoWrite(S.SET_OFFSET, 1, (-5,)), "aa 55 05 03 20 01 fb 5e"),
    (ServoWrite(S.SAVE_OFFSET, 1), "aa 55 05 02 24 01 6a"),
    (ServoWrite(S.SET_ANGLE_LIMITS, 1, (0, 1000)), "aa 55 05 06 30 01 00 00 e8 03 19"),
    (ServoWrite(S.SET_VOLTAGE_LIMITS, 1, (6500, 12000)), "aa 55 05 06 34 01 64 19 e0 2e 37"),
    (ServoWrite(S.SET_TEMP_LIMIT, 1, (85,)), "aa 55 05 03 38 01 55 81"),
    # [0x01, N, (motor_id - 1, float32 rev/s) x N]: motor 1 at 1.0, motor 4 at -0.5 rev/s.
    (MotorSpeeds(((1, 1.0), (4, -0.5))), "aa 55 03 0c 01 02 00 00 00 80 3f 03 00 00 00 bf 27"),
    (LedBlink(1, 100, 200, 3), "aa 55 01 07 01 64 00 c8 00 03 00 26"),
    (BuzzerBeep(2400, 100, 50, 1), "aa 55 02 08 60 09 64 00 32 00 01 00 61"),
]
# Requests the simulated board does not model (decode_request rejects them): encode only.
ENCODE_ONLY_VECTORS: list[tuple[BoardRequest, str]] = [
    (PwmServoMove(500, ((1, 1500),)), "aa 55 04 07 01 f4 01 01 01 dc 05 22"),
    (OledText(1, "hi"), "aa 55 0a 04 01 02 68 69 c5"),
]

IMU_HEX = ("aa 55 07 18 00 00 00 00 00 00 00 00 00 00 80 3f 00 00 00 00 00 00 00 00 "
           "00 00 b4 42 53")
SBUS_HEX = ("aa 55 09 24 00 00 64 00 c8 00 2c 01 90 01 f4 01 58 02 bc 02 20 03 84 03 e8 03 "
            "4c 04 b0 04 14 05 78 05 dc 05 00 00 01 00 59")
# (bytes the board sends, the typed report they mean): every read's reply with the value
# format of its LX reply, and every report.
REPORT_VECTORS: list[tuple[str, BoardReport]] = [
    ("aa 55 05 05 01 05 00 f4 01 92", ServoReply(1, S.READ_POSITION, 0, (500,))),
    ("aa 55 05 05 01 05 00 fb ff e1", ServoReply(1, S.READ_POSITION, 0, (-5,))),
    ("aa 55 05 05 01 05 ff 00 00 bc", ServoReply(1, S.READ_POSITION, -1, (0,))),
    ("aa 55 05 05 01 07 00 e8 1c 54", ServoReply(1, S.READ_VOLTAGE, 0, (7400,))),
    ("aa 55 05 04 01 09 00 2a a8", ServoReply(1, S.READ_TEMPERATURE, 0, (42,))),
    ("aa 55 05 04 01 0d 00 01 35", ServoReply(1, S.READ_TORQUE, 0, (1,))),
    ("aa 55 05 04 fe 12 00 01 cb", ServoReply(254, S.READ_ID, 0, (1,))),
    ("aa 55 05 04 01 22 00 fb f4", ServoReply(1, S.READ_OFFSET, 0, (-5,))),
    ("aa 55 05 07 01 32 00 00 00 e8 03 89", ServoReply(1, S.READ_ANGLE_LIMITS, 0, (0, 1000))),
    ("aa 55 05 07 01 36 00 64 19 e0 2e a7",
     ServoReply(1, S.READ_VOLTAGE_LIMITS, 0, (6500, 12000))),
    ("aa 55 05 04 01 3a 00 55 2b", ServoReply(1, S.READ_TEMP_LIMIT, 0, (85,))),
    ("aa 55 00 03 04 e8 1c 2b", Battery(7.4)),  # [0x04, uint16 mV]
    # Six float32 in g and deg/s: az = 1 g, gz = 90 deg/s.
    (IMU_HEX, ImuSample((0.0, 0.0, 9.80665), (0.0, 0.0, math.pi / 2))),
    ("aa 55 06 02 01 20 a1", KeyEvent(1, KeyEventKind.CLICK)),
    ("aa 55 06 02 02 01 89", KeyEvent(2, KeyEventKind.PRESSED)),
    ("aa 55 08 07 02 01 03 80 7f 00 ff d2", GamepadState(0x0102, 3, (-128, 127, 0, -1))),
    (SBUS_HEX, SbusState(tuple(range(0, 1600, 100)), signal_lost=True, fail_safe=False)),
]
READ_VALUE_BYTES = {S.READ_POSITION: 2, S.READ_VOLTAGE: 2, S.READ_TEMPERATURE: 1,
                    S.READ_TORQUE: 1, S.READ_ID: 1, S.READ_OFFSET: 1, S.READ_ANGLE_LIMITS: 4,
                    S.READ_VOLTAGE_LIMITS: 4, S.READ_TEMP_LIMIT: 1}
"""Each read's value size in its reply (the LX reply's parameter bytes)."""


def _id(value: object) -> str:
    return type(value).__name__


def _shown(data_hex: str) -> str:
    """The pattern of data bytes as the codec's errors show them."""
    return re.escape(data_hex) if data_hex else r"\(no data\)"


# ---------------------------------------------------------------- CRC and worked examples


def test_crc8_maxim_check_value_and_oracle_agree() -> None:
    assert crc8_maxim(b"123456789") == 0xA1
    assert oracle_crc8(b"123456789") == 0xA1
    assert crc8_maxim(b"") == 0
    every_byte = bytes(range(256))
    assert crc8_maxim(every_byte) == oracle_crc8(every_byte)


def test_worked_examples_of_the_notes() -> None:
    move, read = bytes.fromhex(WORKED_MOVE), bytes.fromhex(WORKED_READ)
    assert oracle_frame(5, move[4:-1]) == move
    assert oracle_frame(5, read[4:-1]) == read
    assert ServoMove(1000, ((1, 500),)).encode() == move
    assert ServoRead(ServoSub.READ_POSITION, 1).encode() == read
    assert decode_request(decode_frame(move)) == ServoMove(1000, ((1, 500),))
    assert decode_request(decode_frame(read)) == ServoRead(ServoSub.READ_POSITION, 1)
    assert decode_frame(move) == BoardFrame(Func.BUS_SERVO, move[4:-1])


# ---------------------------------------------------------------- requests


def test_every_servo_sub_command_has_a_vector() -> None:
    subs = {r.sub for r, _ in REQUEST_VECTORS if isinstance(r, ServoRead | ServoWrite)}
    subs |= {S.MOVE, S.STOP}
    assert subs == set(ServoSub)
    assert {int(s) for s in READ_FORMATS} | {int(s) for s in WRITE_FORMATS} | {1, 3} == {
        0x01, 0x03, 0x05, 0x07, 0x09, 0x0B, 0x0C, 0x0D, 0x10, 0x12, 0x20, 0x22, 0x24, 0x30,
        0x32, 0x34, 0x36, 0x38, 0x3A}


@pytest.mark.parametrize(("request_", "expected"), REQUEST_VECTORS, ids=_id)
def test_request_encodes_byte_exact_and_decodes_back(
    request_: BoardRequest, expected: str
) -> None:
    raw = bytes.fromhex(expected)
    assert oracle_frame(raw[2], raw[4:-1]) == raw  # the vector itself is well formed
    assert request_.encode() == raw
    assert decode_request(decode_frame(raw)) == request_


@pytest.mark.parametrize(("request_", "expected"), ENCODE_ONLY_VECTORS, ids=_id)
def test_pwm_and_oled_requests_encode_byte_exact(request_: BoardRequest, expected: str) -> None:
    raw = bytes.fromhex(expected)
    assert oracle_frame(raw[2], raw[4:-1]) == raw
    assert request_.encode() == raw


def test_torque_sub_commands_have_the_firmwares_meaning() -> None:
    # The vendor SDK's "enable torque" sends 0x0B, which the firmware treats as power off.
    assert (ServoSub.TORQUE_OFF, ServoSub.TORQUE_ON) == (0x0B, 0x0C)
    assert ServoWrite(ServoSub.TORQUE_OFF, 3).encode()[4:-1] == b"\x0b\x03"
    assert ServoWrite(ServoSub.TORQUE_ON, 3).encode()[4:-1] == b"\x0c\x03"
    assert LX_COMMANDS[ServoSub.TORQUE_OFF] is Command.LOAD_OR_UNLOAD_WRITE
    assert LX_COMMANDS[ServoSub.TORQUE_ON] is Command.LOAD_OR_UNLOAD_WRITE


# ---------------------------------------------------------------- reports


@pytest.mark.parametrize(("wire", "report"), REPORT_VECTORS, ids=_id)
def test_report_decodes_to_its_typed_value(wire: str, report: BoardReport) -> None:
    raw = bytes.fromhex(wire)
    assert oracle_frame(raw[2], raw[4:-1]) == raw
    decoded = decode_report(decode_frame(raw))
    assert type(decoded) is type(report)
    if isinstance(report, ImuSample):
        assert isinstance(decoded, ImuSample)
        assert decoded.accel_mps2 == pytest.approx(report.accel_mps2, abs=1e-12)
        assert decoded.gyro_rad_s == pytest.approx(report.gyro_rad_s, abs=1e-12)
    else:
        assert decoded == report
    encode = getattr(report, "encode", None)
    if encode is not None:  # the simulated board's side: the same bytes back
        assert encode() == raw


def test_every_read_reply_carries_its_lx_value_bytes() -> None:
    replies = [r for _, r in REPORT_VECTORS if isinstance(r, ServoReply)]
    assert {r.sub for r in replies} == set(READ_FORMATS)
    for reply in replies:
        assert len(reply.value_bytes) == READ_VALUE_BYTES[reply.sub]
        assert reply.ok is (reply.status == 0)


# ---------------------------------------------------------------- malformed frames


@pytest.mark.parametrize("func", [12, 13, 0x7F, 0xFF])
def test_unknown_function_code_is_rejected_both_ways_and_skipped(func: int) -> None:
    raw = oracle_frame(func, b"\x01")
    with pytest.raises(ProtocolError, match=rf"unknown function code {func} .*0\.\.11"):
        decode_frame(raw)
    with pytest.raises(ProtocolError, match=rf"function code {func} is not one of the board's"):
        encode_frame(func, b"\x01")
    parser = BoardFrameParser()
    good = bytes.fromhex(WORKED_READ)
    assert parser.feed(raw + good) == [BoardFrame(Func.BUS_SERVO, b"\x05\x01")]
    assert parser.skipped_bytes == len(raw)
    assert parser.pending == b""


@pytest.mark.parametrize(("raw", "error", "message"), [
    ("", ProtocolError, r"not a board frame .*: nothing"),
    ("aa 55 05 02", ProtocolError, r"needs AA 55 and at least 5 bytes"),
    ("55 aa 05 00 00", ProtocolError, r"not a board frame"),
    ("aa 55 05 03 05 01 6f", ProtocolError, r"frame says 3 data bytes but has 2"),
    ("aa 55 05 02 05 01 6f 00", ProtocolError, r"frame says 2 data bytes but has 3"),
    ("aa 55 05 02 05 01 6e", ChecksumError, r"bad CRC-8 6E \(expected 6F\)"),
])
def test_malformed_frame_is_one_clear_error(raw: str, error: type[Exception],
                                            message: str) -> None:
    data = bytes.fromhex(raw)
    with pytest.raises(error, match=message) as info:
        decode_frame(data)
    assert isinstance(info.value, ProtocolError)
    assert info.value.raw == data


def test_frame_longer_than_255_data_bytes_is_not_encoded() -> None:
    assert len(encode_frame(Func.OLED, bytes(255))) == 260
    with pytest.raises(ProtocolError, match=r"256 data bytes do not fit one board frame"):
        encode_frame(Func.OLED, bytes(256))


@pytest.mark.parametrize(("func", "data"), [
    (Func.BUS_SERVO, "02 01"),  # no such sub-command
    (Func.BUS_SERVO, ""),
    (Func.BUS_SERVO, "05 01 00"),  # a read with a stray byte
    (Func.BUS_SERVO, "01 e8 03 02 01 f4 01"),  # move announcing 2 servos, carrying 1
    (Func.BUS_SERVO, "01 e8 03 00"),  # move of no servo
    (Func.BUS_SERVO, "03 02 01"),  # stop announcing 2 IDs, carrying 1
    (Func.BUS_SERVO, "10 01"),  # set ID without the new ID
    (Func.MOTOR, "01 01 04 00 00 80 3f"),  # motor index 4 is a fifth motor
    (Func.MOTOR, "01 01 00 00 00"),
    (Func.LED, "01 64 00 c8 00 03"),
    (Func.BUZZER, "60 09 64 00 32 00 01 00 00"),
    (Func.IMU, ""),
    (Func.PWM_SERVO, "01 f4 01 02 01 dc 05"),  # PWM move announcing 2 ports, carrying 1
    (Func.PWM_SERVO, "01 f4 01 01 05 dc 05"),  # PWM port 5: the board has 4
])
def test_bad_request_is_one_protocol_error_naming_its_bytes(func: Func, data: str) -> None:
    raw = bytes.fromhex(data)
    with pytest.raises(ProtocolError, match=rf"not a request this board model takes: "
                                            rf"{func.name} {_shown(data)}$"):
        decode_request(BoardFrame(func, raw))


@pytest.mark.parametrize(("func", "data"), [
    (Func.BUS_SERVO, "01 02 00 f4 01"),  # a reply to a write: not a read's
    (Func.BUS_SERVO, "01 05 00 f4"),  # position cut short
    (Func.BUS_SERVO, "01 05 00 f4 01 00"),
    (Func.BUS_SERVO, "01 05"),
    (Func.SYS, "05 e8 1c"),  # not the battery
    (Func.SYS, "04 e8"),
    (Func.IMU, bytes(23).hex(" ")),
    (Func.KEY, "01"),
    (Func.GAMEPAD, bytes(6).hex(" ")),
    (Func.SBUS, bytes(35).hex(" ")),
    (Func.LED, "01 64 00 c8 00 03 00"),  # host to board only
])
def test_bad_report_is_one_protocol_error_naming_its_bytes(func: Func, data: str) -> None:
    raw = bytes.fromhex(data)
    with pytest.raises(ProtocolError, match=rf"not a report the board sends: {func.name} "
                                            rf"{_shown(data)}$") as info:
        decode_report(BoardFrame(func, raw))
    assert info.value.raw == encode_frame(func, raw)


# ---------------------------------------------------------------- out-of-range requests


def _move_of(n: int) -> ServoMove:
    return ServoMove(1000, tuple((i % 254, 500) for i in range(n)))


@pytest.mark.parametrize(("request_", "message"), [
    (ServoMove(1000, ((255, 500),)), r"servo ID = 255; allowed: 0\.\.254"),
    (ServoMove(1000, ((-1, 500),)), r"servo ID = -1; allowed: 0\.\.254"),
    (ServoMove(1000, ((1, 1001),)), r"position_pulses = 1001; allowed: 0\.\.1000"),
    (ServoMove(1000, ((1, -1),)), r"position_pulses = -1; allowed: 0\.\.1000"),
    (ServoMove(-1, ((1, 500),)), r"duration_ms = -1; allowed: 0\.\.65535"),
    (ServoMove(65536, ((1, 500),)), r"duration_ms = 65536; allowed: 0\.\.65535"),
    (_move_of(84), r"servo count = 84; allowed: 1\.\.83"),
    (ServoMove(1000, ()), r"servo count = 0; allowed: 1\.\.83"),
    (ServoStop(()), r"servo count = 0; allowed: 1\.\.253"),
    (ServoStop((1, 300)), r"servo ID = 300; allowed: 0\.\.254"),
    (ServoRead(S.READ_POSITION, 255), r"servo ID = 255; allowed: 0\.\.254"),
    (ServoRead(S.MOVE, 1), r"is not a read"),
    (ServoWrite(S.READ_POSITION, 1), r"is not a single-servo write"),
    (ServoWrite(S.SET_ID, 1), r"SET_ID takes 1 value\(s\) after the servo ID, got 0"),
    (ServoWrite(S.SET_ID, 1, (256,)), r"\(1, 256\) .*0 <= number <= 255"),
    (ServoWrite(S.SET_OFFSET, 1, (-129,)), r"\(1, -129\) .*-128 <= number <= 127"),
    (MotorSpeeds(((0, 1.0),)), r"motor = 0; allowed: 1\.\.4"),
    (MotorSpeeds(((5, 1.0),)), r"motor = 5; allowed: 1\.\.4"),
    (MotorSpeeds(((1, math.nan),)), r"motor 1 speed = nan rev/s; allowed: a finite number"),
    (MotorSpeeds(((2, math.inf),)), r"motor 2 speed = inf rev/s; allowed: a finite number"),
    (MotorSpeeds(((3, -1e39),)), r"motor 3 speed = -1e\+39 rev/s; allowed: .*3\.403e\+38"),
    (MotorSpeeds(()), r"motor count = 0; allowed: 1\.\.4"),
    (MotorSpeeds(tuple((m, 0.0) for m in (1, 2, 3, 4, 1))), r"motor count = 5; allowed: 1\.\.4"),
    (LedBlink(1, 70000, 0), r"LED: \(1, 70000, 0, 1\) .*0 <= number <= 65535"),
    (BuzzerBeep(-1, 100, 100), r"buzzer: \(-1, 100, 100, 1\) .*0 <= number <= 65535"),
    (PwmServoMove(500, ((5, 1500),)), r"PWM port = 5; allowed: 1\.\.4"),
    (PwmServoMove(500, ((1, 1500),) * 84), r"PWM servo count = 84; allowed: 1\.\.83"),
    (OledText(1, "x" * 254), r"OLED text bytes \(UTF-8\) = 254; allowed: 0\.\.253"),
    (OledText(256, "x"), r"OLED line = 256; allowed: 0\.\.255"),
], ids=lambda v: v if isinstance(v, str) else type(v).__name__)
def test_out_of_range_request_is_a_config_error_naming_value_and_range(
    request_: BoardRequest, message: str
) -> None:
    with pytest.raises(ConfigError, match=message):
        request_.encode()


def test_largest_requests_fill_one_frame() -> None:
    assert len(_move_of(83).encode()) == 5 + 4 + 3 * 83
    assert len(OledText(0, "x" * 253).encode()) == 5 + 255
    assert len(PwmServoMove(0, ((4, 2500),) * 83).encode()) == 5 + 4 + 3 * 83
