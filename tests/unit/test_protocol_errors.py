"""Bad input to the protocol layer: every failure is a typed busarm error that says why."""

from __future__ import annotations

import pytest

from busarm.errors import ChecksumError, ConfigError, ProtocolError
from busarm.protocol import (
    SPECS,
    Command,
    Frame,
    PositionReply,
    Request,
    TempReply,
    check_servo_id,
    decode_frame,
    decode_message,
    decode_reply,
    decode_request,
    encode_reply,
    encode_request,
)

C = Command

# A known-good request and reply, and their bytes (from the vector suite).
POS_READ_REQUEST = bytes.fromhex("55 55 01 03 1c df")
POS_READ_REPLY = bytes.fromhex("55 55 01 05 1c f4 01 e8")
MOVE_WRITE_REQUEST = bytes.fromhex("55 55 01 07 01 f4 01 e8 03 16")


def _frame(servo_id: int, command: int, params: bytes) -> bytes:
    """A frame with a correct checksum, built independently of busarm."""
    body = bytes((servo_id, len(params) + 3, command)) + params
    return b"\x55\x55" + body + bytes(((~sum(body)) & 0xFF,))


# ---------------------------------------------------------------- servo IDs


@pytest.mark.parametrize(
    ("servo_id", "allow_broadcast", "range_text"),
    [
        (-1, False, "0..253"),
        (254, False, "0..253"),
        (255, False, "0..253"),
        (-1, True, "0..254"),
        (255, True, "0..254"),
        (1000, True, "0..254"),
    ],
)
def test_check_servo_id_rejects_out_of_range(
    servo_id: int, allow_broadcast: bool, range_text: str
) -> None:
    with pytest.raises(ConfigError) as info:
        check_servo_id(servo_id, allow_broadcast=allow_broadcast)
    assert str(servo_id) in str(info.value)
    assert range_text in str(info.value)


@pytest.mark.parametrize("servo_id", [True, False, 1.0, "1", None, b"\x01"])
def test_check_servo_id_rejects_non_integers(servo_id: object) -> None:
    with pytest.raises(ConfigError, match="servo ID"):
        check_servo_id(servo_id, allow_broadcast=True)


@pytest.mark.parametrize(("servo_id", "allow_broadcast"), [(0, False), (253, False), (254, True)])
def test_check_servo_id_accepts_edges(servo_id: int, allow_broadcast: bool) -> None:
    assert check_servo_id(servo_id, allow_broadcast=allow_broadcast) == servo_id


@pytest.mark.parametrize("servo_id", [-1, 255, 256])
def test_requests_reject_out_of_range_ids(servo_id: int) -> None:
    with pytest.raises(ConfigError, match="servo ID"):
        encode_request(servo_id, C.POS_READ)


# ---------------------------------------------------------------- request fields

# (command, args, field named in the message, bad value, allowed range text)
OUT_OF_RANGE = [
    (C.MOVE_TIME_WRITE, (-1, 0), "position_pulses", -1, "0..1000"),
    (C.MOVE_TIME_WRITE, (1001, 0), "position_pulses", 1001, "0..1000"),
    (C.MOVE_TIME_WRITE, (500, -1), "time_ms", -1, "0..30000"),
    (C.MOVE_TIME_WRITE, (500, 30001), "time_ms", 30001, "0..30000"),
    (C.MOVE_TIME_WAIT_WRITE, (1001, 0), "position_pulses", 1001, "0..1000"),
    (C.MOVE_TIME_WAIT_WRITE, (0, 30001), "time_ms", 30001, "0..30000"),
    (C.MOVE_TIME_WAIT_WRITE, (-1, 100), "position_pulses", -1, "0..1000"),
    (C.ID_WRITE, (254,), "new_id", 254, "0..253"),
    (C.ID_WRITE, (-1,), "new_id", -1, "0..253"),
    (C.ANGLE_OFFSET_ADJUST, (-126,), "offset_pulses", -126, "-125..125"),
    (C.ANGLE_OFFSET_ADJUST, (126,), "offset_pulses", 126, "-125..125"),
    (C.ANGLE_LIMIT_WRITE, (-1, 1000), "min_pulses", -1, "0..1000"),
    (C.ANGLE_LIMIT_WRITE, (0, 1001), "max_pulses", 1001, "0..1000"),
    (C.VIN_LIMIT_WRITE, (4499, 12000), "min_mv", 4499, "4500..12000"),
    (C.VIN_LIMIT_WRITE, (4500, 12001), "max_mv", 12001, "4500..12000"),
    (C.TEMP_MAX_LIMIT_WRITE, (49,), "temp_max_c", 49, "50..100"),
    (C.TEMP_MAX_LIMIT_WRITE, (101,), "temp_max_c", 101, "50..100"),
    (C.OR_MOTOR_MODE_WRITE, (2, 0, 0), "mode", 2, "0..1"),
    (C.OR_MOTOR_MODE_WRITE, (-1, 0, 0), "mode", -1, "0..1"),
    (C.OR_MOTOR_MODE_WRITE, (1, 0, -1001), "motor_speed", -1001, "-1000..1000"),
    (C.OR_MOTOR_MODE_WRITE, (1, 0, 1001), "motor_speed", 1001, "-1000..1000"),
    (C.OR_MOTOR_MODE_WRITE, (1, 1, 0), "null", 1, "0..0"),
    (C.LOAD_OR_UNLOAD_WRITE, (2,), "is_loaded", 2, "0..1"),
    (C.LOAD_OR_UNLOAD_WRITE, (-1,), "is_loaded", -1, "0..1"),
    (C.LED_CTRL_WRITE, (2,), "is_led_off", 2, "0..1"),
    (C.LED_ERROR_WRITE, (8,), "alarm_mask", 8, "0..7"),
    (C.LED_ERROR_WRITE, (-1,), "alarm_mask", -1, "0..7"),
]


def test_every_write_command_with_parameters_has_out_of_range_cases() -> None:
    with_params = {c for c, s in SPECS.items() if s.request}
    assert {case[0] for case in OUT_OF_RANGE} == with_params


@pytest.mark.parametrize(("command", "args", "field", "bad", "range_text"), OUT_OF_RANGE)
def test_out_of_range_field_names_field_value_and_range(
    command: Command, args: tuple[int, ...], field: str, bad: int, range_text: str
) -> None:
    with pytest.raises(ConfigError) as info:
        encode_request(1, command, *args)
    message = str(info.value)
    assert command.name in message
    assert f"{field} = {bad}" in message
    assert range_text in message


@pytest.mark.parametrize(
    ("command", "args"),
    [
        (C.ANGLE_LIMIT_WRITE, (500, 500)),
        (C.ANGLE_LIMIT_WRITE, (600, 500)),
        (C.ANGLE_LIMIT_WRITE, (1000, 0)),
        (C.VIN_LIMIT_WRITE, (6000, 6000)),
        (C.VIN_LIMIT_WRITE, (12000, 4500)),
    ],
)
def test_limit_minimum_must_be_below_maximum(command: Command, args: tuple[int, int]) -> None:
    with pytest.raises(ConfigError) as info:
        encode_request(1, command, *args)
    assert f"minimum {args[0]}" in str(info.value)
    assert f"maximum {args[1]}" in str(info.value)


def _wrong_counts() -> list[tuple[Command, int]]:
    cases = []
    for command, spec in SPECS.items():
        n = len(spec.request)
        cases.append((command, n + 1))
        if n and command is not C.OR_MOTOR_MODE_WRITE:  # (mode, speed) is its short form
            cases.append((command, n - 1))
    return cases


@pytest.mark.parametrize(("command", "count"), _wrong_counts(), ids=str)
def test_wrong_argument_count(command: Command, count: int) -> None:
    args = (0,) * count
    with pytest.raises(ConfigError) as info:
        Request(1, command, args)
    assert f"takes {len(SPECS[command].request)} parameter(s)" in str(info.value)
    assert f"got {count}" in str(info.value)
    with pytest.raises(ConfigError):
        encode_request(1, command, *args)


def test_motor_mode_write_short_form_is_two_arguments_only() -> None:
    with pytest.raises(ConfigError, match="got 1"):
        encode_request(1, C.OR_MOTOR_MODE_WRITE, 1)
    with pytest.raises(ConfigError, match="got 4"):
        encode_request(1, C.OR_MOTOR_MODE_WRITE, 1, 0, 0, 0)


@pytest.mark.parametrize(
    ("command", "args", "field", "bad", "range_text"),
    [
        (C.MOVE_TIME_WRITE, (True, 1000), "position_pulses", True, "0..1000"),
        (C.MOVE_TIME_WRITE, (500.0, 1000), "position_pulses", 500.0, "0..1000"),
        (C.MOVE_TIME_WRITE, (500, 1000.5), "time_ms", 1000.5, "0..30000"),
        (C.MOVE_TIME_WRITE, ("500", 1000), "position_pulses", "500", "0..1000"),
        (C.MOVE_TIME_WRITE, (None, 1000), "position_pulses", None, "0..1000"),
        (C.ID_WRITE, (False,), "new_id", False, "0..253"),
        (C.ANGLE_OFFSET_ADJUST, (1.0,), "offset_pulses", 1.0, "-125..125"),
        (C.TEMP_MAX_LIMIT_WRITE, ("85",), "temp_max_c", "85", "50..100"),
        (C.OR_MOTOR_MODE_WRITE, (True, 0, 0), "mode", True, "0..1"),
        (C.OR_MOTOR_MODE_WRITE, (1, 0, 500.0), "motor_speed", 500.0, "-1000..1000"),
        (C.LOAD_OR_UNLOAD_WRITE, ("1",), "is_loaded", "1", "0..1"),
        (C.LED_CTRL_WRITE, (1.0,), "is_led_off", 1.0, "0..1"),
        (C.LED_ERROR_WRITE, (True,), "alarm_mask", True, "0..7"),
    ],
)
def test_non_integer_fields_are_rejected(
    command: Command, args: tuple[object, ...], field: str, bad: object, range_text: str
) -> None:
    with pytest.raises(ConfigError) as info:
        encode_request(1, command, *args)  # type: ignore[arg-type]
    message = str(info.value)
    assert f"{field} = {bad!r}" in message
    assert "must be an integer" in message
    assert range_text in message


@pytest.mark.parametrize("command", [0, 3, 37, 255, -1])
def test_unknown_command_number_in_request(command: int) -> None:
    with pytest.raises(ConfigError, match="known commands"):
        encode_request(1, command)  # type: ignore[arg-type]


@pytest.mark.parametrize("command", [True, "POS_READ", 28.0, None])
def test_non_command_in_request(command: object) -> None:
    with pytest.raises(ConfigError, match="command"):
        Request(1, command)  # type: ignore[arg-type]


def test_reply_that_does_not_fit_the_wire_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="wire format"):
        encode_reply(1, PositionReply(position_pulses=40000))
    with pytest.raises(ConfigError, match="wire format"):
        encode_reply(1, TempReply(temp_c=-1))


# ---------------------------------------------------------------- decode_frame


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (b"", "too short"),
        (bytes.fromhex("55 55 01 03 1c"), "too short"),
        (bytes.fromhex("55 55 01 03 1c df 00"), "means 6 bytes, got 7"),
        (bytes.fromhex("55 55 01 05 1c df"), "means 8 bytes, got 6"),
        (bytes.fromhex("55 55 01 07 01 f4 01 e8 03"), "means 10 bytes, got 9"),
        (bytes.fromhex("55 54 01 03 1c df"), "must start with 55 55"),
        (bytes.fromhex("aa 55 01 03 1c df"), "must start with 55 55"),
        (bytes.fromhex("55 55 01 02 1c e0"), "below the minimum"),
        (bytes.fromhex("55 55 01 00 1c e2"), "below the minimum"),
    ],
)
def test_decode_frame_rejects_malformed(raw: bytes, reason: str) -> None:
    with pytest.raises(ProtocolError, match=reason) as info:
        decode_frame(raw)
    assert not isinstance(info.value, ChecksumError)
    assert info.value.raw == raw


@pytest.mark.parametrize(
    "raw",
    [
        bytes.fromhex("55 55 01 03 1c de"),
        bytes.fromhex("55 55 01 03 1c 00"),
        bytes.fromhex("55 55 02 03 1c df"),
        bytes.fromhex("55 55 01 07 01 f4 01 e8 03 17"),
    ],
)
def test_decode_frame_rejects_bad_checksum(raw: bytes) -> None:
    with pytest.raises(ChecksumError) as info:
        decode_frame(raw)
    assert info.value.raw == raw
    assert isinstance(info.value, ProtocolError)


def test_decode_frame_takes_bytearray_and_keeps_raw_as_bytes() -> None:
    assert decode_frame(bytearray(POS_READ_REQUEST)) == Frame(1, 28, b"")
    with pytest.raises(ChecksumError) as info:
        decode_frame(bytearray.fromhex("55 55 01 03 1c de"))
    assert type(info.value.raw) is bytes


# ---------------------------------------------------------------- request vs reply


def test_decode_reply_rejects_a_request() -> None:
    with pytest.raises(ProtocolError, match="not a reply") as info:
        decode_reply(decode_frame(POS_READ_REQUEST))
    assert info.value.raw == POS_READ_REQUEST


def test_decode_reply_rejects_a_write_command() -> None:
    with pytest.raises(ProtocolError, match="not a reply") as info:
        decode_reply(decode_frame(MOVE_WRITE_REQUEST))
    assert info.value.raw == MOVE_WRITE_REQUEST


def test_decode_request_rejects_a_reply() -> None:
    with pytest.raises(ProtocolError, match="not a request") as info:
        decode_request(decode_frame(POS_READ_REPLY))
    assert info.value.raw == POS_READ_REPLY


@pytest.mark.parametrize(
    "raw",
    [
        _frame(1, 28, b"\x01"),  # POS_READ with 1 parameter: neither request (0) nor reply (2)
        _frame(1, 1, b"\x01\x02"),  # MOVE_TIME_WRITE with 2 parameters instead of 4
        _frame(1, 11, b"\x00"),  # MOVE_START with a parameter
    ],
)
def test_decode_message_rejects_lengths_of_neither(raw: bytes) -> None:
    frame = decode_frame(raw)
    for decode in (decode_message, decode_request, decode_reply):
        with pytest.raises(ProtocolError) as info:
            decode(frame)
        assert info.value.raw == raw


@pytest.mark.parametrize("command", [0, 3, 4, 5, 6, 9, 10, 15, 16, 37, 255])
def test_unknown_command_number_in_frame(command: int) -> None:
    raw = _frame(1, command, b"")
    frame = decode_frame(raw)
    for decode in (decode_message, decode_request, decode_reply):
        with pytest.raises(ProtocolError, match=f"unknown command {command}") as info:
            decode(frame)
        assert info.value.raw == raw


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (_frame(1, 1, bytes.fromhex("e9 03 00 00")), "position_pulses = 1001"),
        (_frame(1, 1, bytes.fromhex("00 00 31 75")), "time_ms = 30001"),
        (_frame(1, 17, bytes.fromhex("82")), "offset_pulses = -126"),
        (_frame(1, 20, bytes.fromhex("f4 01 f4 01")), "minimum 500"),
        (_frame(1, 29, bytes.fromhex("01 07 00 00")), "null = 7"),
        (_frame(1, 29, bytes.fromhex("01 00 17 fc")), "motor_speed = -1001"),
        (_frame(1, 13, bytes.fromhex("fe")), "new_id = 254"),
        (_frame(255, 28, b""), "servo ID 255"),
    ],
)
def test_decode_request_with_bad_fields_is_a_protocol_error(raw: bytes, reason: str) -> None:
    with pytest.raises(ProtocolError, match=reason) as info:
        decode_request(decode_frame(raw))
    assert not isinstance(info.value, ConfigError)
    assert info.value.raw == raw


@pytest.mark.parametrize(
    ("raw", "reason"),
    [
        (_frame(1, 30, bytes.fromhex("02 00 00 00")), "mode = 2"),
        (_frame(1, 30, bytes.fromhex("ff 00 00 00")), "mode = 255"),
        (_frame(1, 32, bytes.fromhex("03")), "is_loaded = 3"),
        (_frame(1, 34, bytes.fromhex("02")), "is_led_off = 2"),
        (_frame(1, 36, bytes.fromhex("09")), "alarm_mask = 9"),
        (_frame(1, 36, bytes.fromhex("08")), "alarm_mask = 8"),
    ],
)
def test_strict_reply_fields_out_of_range(raw: bytes, reason: str) -> None:
    with pytest.raises(ProtocolError, match=reason) as info:
        decode_reply(decode_frame(raw))
    assert info.value.raw == raw
