"""Issue 31: the board's PWM servo, OLED, RGB, motor duty, battery-warning, gamepad and SBUS
frames, byte-exact both ways, found in garbage, and explained by ``busarm decode``.

The vectors are written from the vendor's published firmware (``packet_handle.c``: the
PWM handler's sub-commands 01/05/07/09 and its replies ``[port, sub, value]``, the OLED
``[line, len, text]``, ``RGBCommandTypeDef``, ``BatteryWarnTypeDef``) and Python SDK
(``pwm_servo_set_position``, ``set_rgb``, ``set_motor_duty``, ``set_oled_text``); the CRC
bytes were computed with a bitwise CRC-8/MAXIM, not with busarm's table.
"""

from __future__ import annotations

import pytest

from busarm.cli.proto_cmds import decode_lines
from busarm.errors import ConfigError
from busarm.protocol.board import (
    BatteryWarning,
    BoardFrameParser,
    BoardRequest,
    GamepadState,
    MotorDuties,
    OledText,
    PwmServoMove,
    PwmServoRead,
    PwmServoReply,
    PwmServoSetOffset,
    PwmSub,
    RgbSet,
    SbusState,
    decode_report,
    decode_request,
)

P = PwmSub
Encodable = BoardRequest | PwmServoReply | GamepadState | SbusState
REQUESTS = [
    # the frame: port 1 to 1500 us in 500 ms
    (PwmServoMove(500, ((1, 1500),)), "aa 55 04 07 01 f4 01 01 01 dc 05 22",
     "PWM servo move port 1 to 1500 us in 500 ms"),
    # the SDK's own test: pwm_servo_set_position(0.1, [[1, 1800], [3, 1500]])
    (PwmServoMove(100, ((1, 1800), (3, 1500))),
     "aa 55 04 0a 01 64 00 02 01 08 07 03 dc 05 14",
     "PWM servo move port 1 to 1800 us, port 3 to 1500 us in 100 ms"),
    (PwmServoRead(P.READ_POSITION, 1), "aa 55 04 02 05 01 e0",
     "PWM servo read position of port 1"),
    (PwmServoRead(P.READ_OFFSET, 2), "aa 55 04 02 09 02 4f", "PWM servo read offset of port 2"),
    (PwmServoSetOffset(1, -10), "aa 55 04 03 07 01 f6 80",
     "PWM servo set offset of port 1 to -10 us"),
    (OledText(1, "hi"), "aa 55 0a 04 01 02 68 69 c5", "OLED line 1: 'hi'"),
    (OledText(2, "192.168.1.2"), "aa 55 0a 0d 02 0b 31 39 32 2e 31 36 38 2e 31 2e 32 97",
     "OLED line 2: '192.168.1.2'"),
    # set_rgb([[1, 255, 0, 255]]): pixel numbers from 1, sent from 0
    (RgbSet(((1, 255, 0, 255),)), "aa 55 0b 06 01 01 00 ff 00 ff 7c",
     "RGB pixel 1 to (255, 0, 255)"),
    (RgbSet(((1, 255, 0, 0), (2, 0, 0, 255))), "aa 55 0b 0a 01 02 00 ff 00 00 01 00 00 ff bd",
     "RGB pixel 1 to (255, 0, 0), pixel 2 to (0, 0, 255)"),
    # set_motor_duty([[1, 50]]): sub-command 05, motor 0, float32 50.0
    (MotorDuties(((1, 50.0),)), "aa 55 03 07 05 01 00 00 00 48 42 cc",
     "motor 1 at duty 50 (open loop)"),
    # battery warning below 10.5 V: SYS sub-command 01, uint16 mV
    (BatteryWarning(10.5), "aa 55 00 03 01 04 29 a7", "warn below battery 10.500 V"),
]
SBUS_HEX = ("aa 55 09 24 00 00 64 00 c8 00 2c 01 90 01 f4 01 58 02 bc 02 20 03 84 03 e8 03 "
            "4c 04 b0 04 14 05 78 05 dc 05 00 00 01 00 59")
REPORTS = [
    (PwmServoReply(1, P.READ_POSITION, 1500), "aa 55 04 04 01 05 dc 05 53",
     "PWM servo port 1 position: 1500 us"),
    (PwmServoReply(2, P.READ_OFFSET, -10), "aa 55 04 03 02 09 f6 c3",
     "PWM servo port 2 offset: -10"),
    (GamepadState(0x0102, 3, (-128, 127, 0, -1)), "aa 55 08 07 02 01 03 80 7f 00 ff d2",
     "gamepad buttons 0x0102, hat 3"),
    (SbusState(tuple(range(0, 1600, 100)), signal_lost=True, fail_safe=False), SBUS_HEX,
     "SBUS channels 0 100 200"),
]


@pytest.mark.parametrize(("request_", "wire", "words"), REQUESTS)
def test_request_encodes_byte_exact_and_decodes_back(request_: BoardRequest, wire: str,
                                                     words: str) -> None:
    raw = request_.encode()
    assert raw.hex(" ") == wire
    frames = BoardFrameParser().feed(raw)
    assert len(frames) == 1
    assert decode_request(frames[0]) == request_


@pytest.mark.parametrize(("report", "wire", "words"), REPORTS)
def test_report_encodes_byte_exact_and_decodes_back(report: Encodable, wire: str,
                                                    words: str) -> None:
    assert report.encode().hex(" ") == wire
    frames = BoardFrameParser().feed(bytes.fromhex(wire))
    assert decode_report(frames[0]) == report


def test_sbus_digital_channels_round_trip() -> None:
    state = SbusState(tuple(range(192, 1792, 100)), False, True, True, False)
    raw = state.encode()
    assert raw[4 + 32:4 + 36] == bytes((1, 0, 0, 1))  # ch17, ch18, lost, fail-safe
    assert decode_report(BoardFrameParser().feed(raw)[0]) == state


def test_busarm_decode_explains_every_new_frame_found_in_garbage() -> None:
    """Every vector behind noise, a false header and a damaged copy: each is found, in
    order, and explained in words."""
    cases = REQUESTS + REPORTS
    stream = bytearray(b"\x00\xaa")
    for i, (_, wire, _) in enumerate(cases):
        raw = bytes.fromhex(wire)
        damaged = bytearray(raw)
        damaged[-1] ^= 0xFF
        stream += bytes((0x55, i)) + b"\xaa\x55\x04\xf0" + bytes(damaged[:-1]) + raw
    parser = BoardFrameParser()
    found = [f for at in range(0, len(stream), 7) for f in parser.feed(stream[at:at + 7])]
    assert [f.to_bytes().hex(" ") for f in found] == [wire for _, wire, _ in cases]
    lines, _ = decode_lines(bytes(stream))
    text = "\n".join(lines)
    for _, wire, words in cases:
        line = next(line for line in lines if line.startswith(wire + " "))
        assert words in line, (line, words)
    assert "not a message this codec knows" not in text


@pytest.mark.parametrize(("request_", "message"), [
    (PwmServoMove(500, ((5, 1500),)), r"PWM port = 5; allowed: 1\.\.4"),
    (PwmServoRead(P.READ_POSITION, 0), r"PWM port = 0; allowed: 1\.\.4"),
    (PwmServoRead(P.MOVE, 1), r"not a read; allowed: READ_POSITION"),
    (PwmServoSetOffset(1, 200), r"PWM offset = 200; allowed: -128\.\.127"),
    (RgbSet(((0, 1, 2, 3),)), r"RGB pixel = 0; allowed: 1\.\.256"),
    (RgbSet(((1, 256, 2, 3),)), r"red = 256; allowed: 0\.\.255"),
    (RgbSet(()), r"RGB pixel count = 0; allowed: 1\.\.63"),
    (MotorDuties(((5, 1.0),)), r"motor = 5; allowed: 1\.\.4"),
    (MotorDuties(((1, float("nan")),)), r"motor 1 duty = nan; allowed: a finite number"),
    (BatteryWarning(70.0), r"battery warning mV = 70000; allowed: 0\.\.65535"),
    (GamepadState(0, 0, (0, 0, 0, 200)), r"gamepad stick = 200; allowed: -128\.\.127"),
    (SbusState((0,) * 15, False, False), r"SBUS channel count = 15; allowed: 16\.\.16"),
])
def test_out_of_range_value_is_one_config_error_naming_it(request_: Encodable,
                                                          message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        request_.encode()
