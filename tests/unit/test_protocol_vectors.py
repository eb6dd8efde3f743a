"""Byte vectors written by hand from the vendor manual.

Every expected frame below was worked out from the manual's Table 1 layout
(55 55 ID LEN CMD PARAMS CHECKSUM, little-endian parameters, checksum = low byte of
~(ID + LEN + CMD + PARAMS)) without using busarm, so these tests are an oracle
independent of the codec: a request is encoded and compared byte for byte, and
decoded back; a reply is decoded into its typed dataclass and re-encoded.
"""

from __future__ import annotations

import pytest

from busarm.errors import ConfigError
from busarm.protocol import (
    REPLY_TYPES,
    SPECS,
    AlarmFlag,
    AngleLimitReply,
    AngleOffsetReply,
    Command,
    IdReply,
    LedCtrlReply,
    LedErrorReply,
    LoadReply,
    ModeReply,
    MoveTimeReply,
    MoveTimeWaitReply,
    PositionReply,
    Reply,
    Request,
    ServoMode,
    TempMaxLimitReply,
    TempReply,
    VinLimitReply,
    VinReply,
    decode_frame,
    decode_message,
    decode_reply,
    decode_request,
    encode_reply,
    encode_request,
)

# The manual's command table: name -> (command value, request Length byte).
MANUAL_REQUESTS = {
    "SERVO_MOVE_TIME_WRITE": (1, 7),
    "SERVO_MOVE_TIME_READ": (2, 3),
    "SERVO_MOVE_TIME_WAIT_WRITE": (7, 7),
    "SERVO_MOVE_TIME_WAIT_READ": (8, 3),
    "SERVO_MOVE_START": (11, 3),
    "SERVO_MOVE_STOP": (12, 3),
    "SERVO_ID_WRITE": (13, 4),
    "SERVO_ID_READ": (14, 3),
    "SERVO_ANGLE_OFFSET_ADJUST": (17, 4),
    "SERVO_ANGLE_OFFSET_WRITE": (18, 3),
    "SERVO_ANGLE_OFFSET_READ": (19, 3),
    "SERVO_ANGLE_LIMIT_WRITE": (20, 7),
    "SERVO_ANGLE_LIMIT_READ": (21, 3),
    "SERVO_VIN_LIMIT_WRITE": (22, 7),
    "SERVO_VIN_LIMIT_READ": (23, 3),
    "SERVO_TEMP_MAX_LIMIT_WRITE": (24, 4),
    "SERVO_TEMP_MAX_LIMIT_READ": (25, 3),
    "SERVO_TEMP_READ": (26, 3),
    "SERVO_VIN_READ": (27, 3),
    "SERVO_POS_READ": (28, 3),
    "SERVO_OR_MOTOR_MODE_WRITE": (29, 7),
    "SERVO_OR_MOTOR_MODE_READ": (30, 3),
    "SERVO_LOAD_OR_UNLOAD_WRITE": (31, 4),
    "SERVO_LOAD_OR_UNLOAD_READ": (32, 3),
    "SERVO_LED_CTRL_WRITE": (33, 4),
    "SERVO_LED_CTRL_READ": (34, 3),
    "SERVO_LED_ERROR_WRITE": (35, 4),
    "SERVO_LED_ERROR_READ": (36, 3),
}

# The manual's Table 4: name -> reply Length byte.
MANUAL_REPLIES = {
    "SERVO_MOVE_TIME_READ": 7,
    "SERVO_MOVE_TIME_WAIT_READ": 7,
    "SERVO_ID_READ": 4,
    "SERVO_ANGLE_OFFSET_READ": 4,
    "SERVO_ANGLE_LIMIT_READ": 7,
    "SERVO_VIN_LIMIT_READ": 7,
    "SERVO_TEMP_MAX_LIMIT_READ": 4,
    "SERVO_TEMP_READ": 4,
    "SERVO_VIN_READ": 5,
    "SERVO_POS_READ": 5,
    "SERVO_OR_MOTOR_MODE_READ": 7,
    "SERVO_LOAD_OR_UNLOAD_READ": 4,
    "SERVO_LED_CTRL_READ": 4,
    "SERVO_LED_ERROR_READ": 4,
}

# (servo ID, command, args, expected frame): at least one per command, range edges included.
REQUEST_VECTORS = [
    (1, Command.MOVE_TIME_WRITE, (500, 1000), "55 55 01 07 01 f4 01 e8 03 16"),
    (1, Command.MOVE_TIME_WRITE, (0, 0), "55 55 01 07 01 00 00 00 00 f6"),
    (253, Command.MOVE_TIME_WRITE, (1000, 30000), "55 55 fd 07 01 e8 03 30 75 6a"),
    (1, Command.MOVE_TIME_READ, (), "55 55 01 03 02 f9"),
    (2, Command.MOVE_TIME_WAIT_WRITE, (1000, 30000), "55 55 02 07 07 e8 03 30 75 5f"),
    (2, Command.MOVE_TIME_WAIT_READ, (), "55 55 02 03 08 f2"),
    (254, Command.MOVE_START, (), "55 55 fe 03 0b f3"),
    (3, Command.MOVE_STOP, (), "55 55 03 03 0c ed"),
    (1, Command.ID_WRITE, (253,), "55 55 01 04 0d fd f0"),
    (7, Command.ID_WRITE, (0,), "55 55 07 04 0d 00 e7"),
    (254, Command.ID_READ, (), "55 55 fe 03 0e f0"),
    (1, Command.ANGLE_OFFSET_ADJUST, (-125,), "55 55 01 04 11 83 66"),
    (1, Command.ANGLE_OFFSET_ADJUST, (125,), "55 55 01 04 11 7d 6c"),
    (4, Command.ANGLE_OFFSET_ADJUST, (-1,), "55 55 04 04 11 ff e7"),
    (1, Command.ANGLE_OFFSET_WRITE, (), "55 55 01 03 12 e9"),
    (5, Command.ANGLE_OFFSET_READ, (), "55 55 05 03 13 e4"),
    (1, Command.ANGLE_LIMIT_WRITE, (0, 1000), "55 55 01 07 14 00 00 e8 03 f8"),
    (1, Command.ANGLE_LIMIT_READ, (), "55 55 01 03 15 e6"),
    (1, Command.VIN_LIMIT_WRITE, (4500, 12000), "55 55 01 07 16 94 11 e0 2e 2e"),
    (10, Command.VIN_LIMIT_READ, (), "55 55 0a 03 17 db"),
    (1, Command.TEMP_MAX_LIMIT_WRITE, (50,), "55 55 01 04 18 32 b0"),
    (1, Command.TEMP_MAX_LIMIT_WRITE, (100,), "55 55 01 04 18 64 7e"),
    (1, Command.TEMP_MAX_LIMIT_READ, (), "55 55 01 03 19 e2"),
    (1, Command.TEMP_READ, (), "55 55 01 03 1a e1"),
    (1, Command.VIN_READ, (), "55 55 01 03 1b e0"),
    (1, Command.POS_READ, (), "55 55 01 03 1c df"),
    (0, Command.POS_READ, (), "55 55 00 03 1c e0"),
    (1, Command.OR_MOTOR_MODE_WRITE, (1, 0, -1000), "55 55 01 07 1d 01 00 18 fc c5"),
    (1, Command.OR_MOTOR_MODE_WRITE, (1, 0, 1000), "55 55 01 07 1d 01 00 e8 03 ee"),
    (1, Command.OR_MOTOR_MODE_WRITE, (0, 0, 0), "55 55 01 07 1d 00 00 00 00 da"),
    (1, Command.OR_MOTOR_MODE_READ, (), "55 55 01 03 1e dd"),
    (1, Command.LOAD_OR_UNLOAD_WRITE, (1,), "55 55 01 04 1f 01 da"),
    (254, Command.LOAD_OR_UNLOAD_WRITE, (0,), "55 55 fe 04 1f 00 de"),
    (1, Command.LOAD_OR_UNLOAD_READ, (), "55 55 01 03 20 db"),
    (1, Command.LED_CTRL_WRITE, (1,), "55 55 01 04 21 01 d8"),
    (1, Command.LED_CTRL_READ, (), "55 55 01 03 22 d9"),
    (1, Command.LED_ERROR_WRITE, (7,), "55 55 01 04 23 07 d0"),
    (1, Command.LED_ERROR_WRITE, (0,), "55 55 01 04 23 00 d7"),
    (1, Command.LED_ERROR_READ, (), "55 55 01 03 24 d7"),
]

# (frame a servo sends, the typed reply it means): every reply of Table 4.
REPLY_VECTORS = [
    ("55 55 01 07 02 e8 03 30 75 65", MoveTimeReply(position_pulses=1000, time_ms=30000)),
    ("55 55 01 07 02 00 00 00 00 f5", MoveTimeReply(position_pulses=0, time_ms=0)),
    ("55 55 02 07 08 f4 01 e8 03 0e", MoveTimeWaitReply(position_pulses=500, time_ms=1000)),
    ("55 55 01 04 0e 01 eb", IdReply(reported_id=1)),
    ("55 55 fd 04 0e fd f3", IdReply(reported_id=253)),
    ("55 55 01 04 13 83 64", AngleOffsetReply(offset_pulses=-125)),
    ("55 55 01 04 13 7d 6a", AngleOffsetReply(offset_pulses=125)),
    ("55 55 01 04 13 fb ec", AngleOffsetReply(offset_pulses=-5)),
    ("55 55 01 07 15 00 00 e8 03 f7", AngleLimitReply(min_pulses=0, max_pulses=1000)),
    ("55 55 01 07 17 64 19 e0 2e 55", VinLimitReply(min_mv=6500, max_mv=12000)),
    ("55 55 01 04 19 55 8c", TempMaxLimitReply(temp_max_c=85)),
    ("55 55 01 04 1a 2a b6", TempReply(temp_c=42)),
    ("55 55 01 05 1b e8 1c da", VinReply(vin_mv=7400)),
    ("55 55 01 05 1c f4 01 e8", PositionReply(position_pulses=500)),
    ("55 55 01 05 1c fb ff e3", PositionReply(position_pulses=-5)),
    ("55 55 01 05 1c 00 80 5d", PositionReply(position_pulses=-32768)),
    ("55 55 01 05 1c f2 03 e8", PositionReply(position_pulses=1010)),
    ("55 55 01 07 1e 01 00 18 fc c4", ModeReply(mode=ServoMode.MOTOR, motor_speed=-1000)),
    ("55 55 01 07 1e 00 00 00 00 d9", ModeReply(mode=ServoMode.POSITION, motor_speed=0)),
    ("55 55 01 04 20 01 d9", LoadReply(is_loaded=True)),
    ("55 55 01 04 20 00 da", LoadReply(is_loaded=False)),
    ("55 55 01 04 22 01 d7", LedCtrlReply(is_led_off=True)),
    ("55 55 01 04 22 00 d8", LedCtrlReply(is_led_off=False)),
    (
        "55 55 01 04 24 05 d1",
        LedErrorReply(alarm_mask=AlarmFlag.OVER_TEMPERATURE | AlarmFlag.STALLED),
    ),
    ("55 55 01 04 24 00 d6", LedErrorReply(alarm_mask=AlarmFlag.NONE)),
    ("55 55 01 04 24 02 d4", LedErrorReply(alarm_mask=AlarmFlag.OVER_VOLTAGE)),
]


def _id(value: object) -> str:
    return value.name if isinstance(value, Command) else str(value)


# ---------------------------------------------------------------- the command tables


def test_every_command_has_a_request_vector() -> None:
    assert {cmd for _, cmd, _, _ in REQUEST_VECTORS} == set(Command)


def test_every_reply_of_table_4_has_a_vector() -> None:
    assert {type(reply) for _, reply in REPLY_VECTORS} == set(REPLY_TYPES.values())


@pytest.mark.parametrize(("manual_name", "value_and_length"), MANUAL_REQUESTS.items())
def test_command_value_and_request_length_match_manual(
    manual_name: str, value_and_length: tuple[int, int]
) -> None:
    value, length = value_and_length
    command = Command(value)
    assert command.manual_name == manual_name
    assert SPECS[command].request_length == length


def test_commands_are_exactly_the_manuals_28() -> None:
    assert len(Command) == 28
    assert {c.manual_name for c in Command} == set(MANUAL_REQUESTS)


@pytest.mark.parametrize("command", list(Command), ids=_id)
def test_reply_length_matches_table_4(command: Command) -> None:
    expected = MANUAL_REPLIES.get(command.manual_name)
    assert SPECS[command].reply_length == expected
    assert SPECS[command].is_read == (expected is not None)


# ---------------------------------------------------------------- requests


@pytest.mark.parametrize(("servo_id", "command", "args", "expected"), REQUEST_VECTORS, ids=_id)
def test_request_encodes_to_manual_bytes(
    servo_id: int, command: Command, args: tuple[int, ...], expected: str
) -> None:
    assert encode_request(servo_id, command, *args) == bytes.fromhex(expected)
    assert Request(servo_id, command, args).to_bytes() == bytes.fromhex(expected)


@pytest.mark.parametrize(("servo_id", "command", "args", "expected"), REQUEST_VECTORS, ids=_id)
def test_manual_bytes_decode_to_request(
    servo_id: int, command: Command, args: tuple[int, ...], expected: str
) -> None:
    frame = decode_frame(bytes.fromhex(expected))
    assert (frame.servo_id, frame.command) == (servo_id, command)
    request = decode_request(frame)
    assert request == Request(servo_id, command, args)
    assert isinstance(request.command, Command)
    assert decode_message(frame) == request


def test_motor_mode_write_fills_in_the_null_byte() -> None:
    assert encode_request(1, Command.OR_MOTOR_MODE_WRITE, 1, -1000) == bytes.fromhex(
        "55 55 01 07 1d 01 00 18 fc c5"
    )


def test_request_accepts_a_plain_command_number() -> None:
    request = Request(1, 28)  # type: ignore[arg-type]
    assert request.command is Command.POS_READ
    assert request.to_bytes() == bytes.fromhex("55 55 01 03 1c df")


def test_flag_fields_accept_bools() -> None:
    assert encode_request(1, Command.LOAD_OR_UNLOAD_WRITE, True) == bytes.fromhex(
        "55 55 01 04 1f 01 da"
    )
    assert encode_request(1, Command.LED_CTRL_WRITE, False) == bytes.fromhex(
        "55 55 01 04 21 00 d9"
    )


def test_request_values_are_named_without_the_null_byte() -> None:
    request = Request(1, Command.OR_MOTOR_MODE_WRITE, (1, 0, -1000))
    assert request.values == {"mode": 1, "motor_speed": -1000}


# ---------------------------------------------------------------- replies


@pytest.mark.parametrize(("wire", "expected"), REPLY_VECTORS, ids=lambda v: str(v))
def test_manual_bytes_decode_to_typed_reply(wire: str, expected: Reply) -> None:
    frame = decode_frame(bytes.fromhex(wire))
    reply = decode_reply(frame)
    assert reply == expected
    assert type(reply) is type(expected)
    assert decode_message(frame) == expected


@pytest.mark.parametrize(("wire", "expected"), REPLY_VECTORS, ids=lambda v: str(v))
def test_reply_encodes_to_manual_bytes(wire: str, expected: Reply) -> None:
    servo_id = bytes.fromhex(wire)[2]
    assert encode_reply(servo_id, expected) == bytes.fromhex(wire)


@pytest.mark.parametrize(
    ("wire", "field", "value_type"),
    [
        ("55 55 01 07 1e 01 00 18 fc c4", "mode", ServoMode),
        ("55 55 01 04 20 01 d9", "is_loaded", bool),
        ("55 55 01 04 20 00 da", "is_loaded", bool),
        ("55 55 01 04 22 01 d7", "is_led_off", bool),
        ("55 55 01 04 24 05 d1", "alarm_mask", AlarmFlag),
        ("55 55 01 05 1c fb ff e3", "position_pulses", int),
    ],
)
def test_reply_fields_have_their_python_types(wire: str, field: str, value_type: type) -> None:
    reply = decode_reply(decode_frame(bytes.fromhex(wire)))
    assert type(getattr(reply, field)) is value_type


def test_negative_position_and_offset_read_as_signed() -> None:
    position = decode_reply(decode_frame(bytes.fromhex("55 55 01 05 1c fb ff e3")))
    assert isinstance(position, PositionReply)
    assert position.position_pulses == -5
    assert position.position_deg == pytest.approx((-5 - 500) * 0.24)
    offset = decode_reply(decode_frame(bytes.fromhex("55 55 01 04 13 83 64")))
    assert isinstance(offset, AngleOffsetReply)
    assert offset.offset_pulses == -125
    assert offset.offset_deg == pytest.approx(-30.0)


def test_mode_reply_values() -> None:
    reply = decode_reply(decode_frame(bytes.fromhex("55 55 01 07 1e 01 00 18 fc c4")))
    assert isinstance(reply, ModeReply)
    assert reply.mode is ServoMode.MOTOR
    assert reply.motor_speed == -1000


def test_led_error_reply_flags() -> None:
    reply = decode_reply(decode_frame(bytes.fromhex("55 55 01 04 24 05 d1")))
    assert isinstance(reply, LedErrorReply)
    assert AlarmFlag.OVER_TEMPERATURE in reply.alarm_mask
    assert AlarmFlag.STALLED in reply.alarm_mask
    assert AlarmFlag.OVER_VOLTAGE not in reply.alarm_mask


def test_reply_unit_conversions() -> None:
    vin = decode_reply(decode_frame(bytes.fromhex("55 55 01 05 1b e8 1c da")))
    assert isinstance(vin, VinReply)
    assert vin.vin_v == pytest.approx(7.4)
    move = decode_reply(decode_frame(bytes.fromhex("55 55 01 07 02 e8 03 30 75 65")))
    assert isinstance(move, MoveTimeReply)
    assert move.position_deg == pytest.approx(120.0)
    assert move.time_s == pytest.approx(30.0)


def test_reply_keeps_the_sender_id_in_the_frame() -> None:
    frame = decode_frame(bytes.fromhex("55 55 fd 04 0e fd f3"))
    assert frame.servo_id == 253
    assert decode_reply(frame) == IdReply(reported_id=253)


# ---------------------------------------------------------------- Command.parse


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("28", Command.POS_READ),
        (" 1 ", Command.MOVE_TIME_WRITE),
        ("036", Command.LED_ERROR_READ),
        ("SERVO_POS_READ", Command.POS_READ),
        ("POS_READ", Command.POS_READ),
        ("pos_read", Command.POS_READ),
        ("pos-read", Command.POS_READ),
        ("servo-pos-read", Command.POS_READ),
        ("Servo_Or_Motor_Mode_Write", Command.OR_MOTOR_MODE_WRITE),
        ("or-motor-mode-write", Command.OR_MOTOR_MODE_WRITE),
        ("SERVO_MOVE_TIME_WAIT_WRITE", Command.MOVE_TIME_WAIT_WRITE),
    ],
)
def test_command_parse_accepts_numbers_and_names(text: str, expected: Command) -> None:
    assert Command.parse(text) is expected


@pytest.mark.parametrize("command", list(Command), ids=_id)
def test_command_parse_round_trips_every_spelling(command: Command) -> None:
    spellings = (
        str(command.value),
        command.name,
        command.manual_name,
        command.manual_name.lower().replace("_", "-"),
    )
    assert {Command.parse(s) for s in spellings} == {command}


@pytest.mark.parametrize(
    "text", ["0", "3", "37", "255", "-1", "", "POS", "SERVO_", "SERVO_SERVO_POS_READ", "0x1c"]
)
def test_command_parse_rejects_unknown_with_the_known_list(text: str) -> None:
    with pytest.raises(ConfigError) as info:
        Command.parse(text)
    message = str(info.value)
    assert repr(text) in message
    assert "POS_READ(28)" in message
    assert "MOVE_TIME_WRITE(1)" in message
    assert "LED_ERROR_READ(36)" in message
