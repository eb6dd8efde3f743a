"""Properties of the controller board's codec and its frame parser (hypothesis).

Value ranges come from field-notes section 5 and the wire layouts, and frames are
checksummed here with a bitwise CRC-8/MAXIM written from its definition, so the
properties do not merely restate the implementation.
"""

from __future__ import annotations

import contextlib
import math
import struct
from collections.abc import Callable

from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from busarm.bus.board import REPORT_MAX_DATA
from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.board import (
    Battery,
    BoardFrame,
    BoardFrameParser,
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
    decode_frame,
    decode_report,
    decode_request,
    encode_frame,
)

SETTINGS = settings(max_examples=150, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
STREAM_SETTINGS = settings(SETTINGS, max_examples=100)
"""For the parser-stream properties, whose examples are larger."""

S = ServoSub
U8, S8, U16, S16 = (0, 255), (-128, 127), (0, 65535), (-32768, 32767)
FUNCS = 12
"""The board's function codes are 0..11 (the notes: the firmware rejects 12 and up)."""
HEADER = b"\xaa\x55"


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
    return HEADER + body + bytes((oracle_crc8(body),))


def f32(value: float) -> float:
    """``value`` as the board's float32 carries it."""
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


# ---------------------------------------------------------------- strategies

servo_ids = st.integers(0, 254)
# Each single-servo write's values after the ID, from the notes' layouts.
WRITE_RANGES: dict[ServoSub, tuple[tuple[int, int], ...]] = {
    S.TORQUE_OFF: (), S.TORQUE_ON: (), S.SAVE_OFFSET: (),
    S.SET_ID: (U8,), S.SET_OFFSET: (S8,), S.SET_TEMP_LIMIT: (U8,),
    S.SET_ANGLE_LIMITS: (U16, U16), S.SET_VOLTAGE_LIMITS: (U16, U16),
}
READ_RANGES: dict[ServoSub, tuple[tuple[int, int], ...]] = {
    S.READ_POSITION: (S16,), S.READ_VOLTAGE: (U16,), S.READ_TEMPERATURE: (U8,),
    S.READ_TORQUE: (S8,), S.READ_ID: (U8,), S.READ_OFFSET: (S8,),
    S.READ_ANGLE_LIMITS: (U16, U16), S.READ_VOLTAGE_LIMITS: (U16, U16),
    S.READ_TEMP_LIMIT: (U8,),
}


def _values(ranges: tuple[tuple[int, int], ...]) -> st.SearchStrategy[tuple[int, ...]]:
    return st.tuples(*(st.integers(lo, hi) for lo, hi in ranges))


@st.composite
def servo_writes(draw: st.DrawFn) -> ServoWrite:
    sub = draw(st.sampled_from(sorted(WRITE_RANGES)))
    return ServoWrite(sub, draw(servo_ids), draw(_values(WRITE_RANGES[sub])))


@st.composite
def servo_replies(draw: st.DrawFn) -> ServoReply:
    sub = draw(st.sampled_from(sorted(READ_RANGES)))
    return ServoReply(draw(st.integers(*U8)), sub, draw(st.integers(*S8)),
                      draw(_values(READ_RANGES[sub])))


wheel_speeds = st.one_of(st.floats(-1e6, 1e6), st.floats(width=32, allow_nan=False,
                                                         allow_infinity=False))
requests: st.SearchStrategy[BoardRequest] = st.one_of(
    st.builds(ServoMove, st.integers(*U16),
              st.lists(st.tuples(servo_ids, st.integers(0, 1000)), min_size=1,
                       max_size=83).map(tuple)),
    st.builds(ServoStop, st.lists(servo_ids, min_size=1, max_size=253).map(tuple)),
    st.builds(ServoRead, st.sampled_from(sorted(READ_RANGES)), servo_ids),
    servo_writes(),
    st.builds(MotorSpeeds, st.lists(st.tuples(st.integers(1, 4), wheel_speeds), min_size=1,
                                    max_size=4).map(tuple)),
    st.builds(LedBlink, st.integers(*U8), st.integers(*U16), st.integers(*U16),
              st.integers(*U16)),
    st.builds(BuzzerBeep, st.integers(*U16), st.integers(*U16), st.integers(*U16),
              st.integers(*U16)),
)
imu_values = st.floats(-1e4, 1e4)
EncodableReport = ServoReply | Battery | ImuSample | KeyEvent
"""The reports with an ``encode`` (the simulated board sends them)."""
reports: st.SearchStrategy[EncodableReport] = st.one_of(
    servo_replies(),
    st.builds(Battery, st.integers(*U16).map(lambda mv: mv / 1000)),
    st.builds(ImuSample, st.tuples(imu_values, imu_values, imu_values),
              st.tuples(imu_values, imu_values, imu_values)),
    st.builds(KeyEvent, st.integers(*U8), st.integers(*U8).map(KeyEventKind)),
)


@st.composite
def gamepad_frames(draw: st.DrawFn) -> tuple[bytes, GamepadState]:
    """The vendor's gamepad layout: buttons (uint16), hat (uint8), four int8 sticks."""
    buttons, hat = draw(st.integers(*U16)), draw(st.integers(*U8))
    sticks = draw(st.tuples(*[st.integers(*S8)] * 4))
    raw = oracle_frame(8, struct.pack("<HB4b", buttons, hat, *sticks))
    return raw, GamepadState(buttons, hat, sticks)


@st.composite
def sbus_frames(draw: st.DrawFn) -> tuple[bytes, SbusState]:
    """The vendor's SBUS layout: 16 int16 channels, two digital ones, lost, fail-safe."""
    channels = draw(st.tuples(*[st.integers(*S16)] * 16))
    digital = draw(st.tuples(st.integers(*U8), st.integers(*U8)))
    lost, fail_safe = draw(st.integers(*U8)), draw(st.integers(*U8))
    raw = oracle_frame(9, struct.pack("<16hBBBB", *channels, *digital, lost, fail_safe))
    return raw, SbusState(channels, bool(lost), bool(fail_safe), bool(digital[0]),
                          bool(digital[1]))


def assert_same_request(got: BoardRequest, sent: BoardRequest) -> None:
    """Equal, speeds compared as the float32 the board carries."""
    if isinstance(sent, MotorSpeeds):
        assert got == MotorSpeeds(tuple((m, f32(v)) for m, v in sent.speeds))
    else:
        assert got == sent


def close(got: tuple[float, ...], sent: tuple[float, ...]) -> bool:
    """Within float32 precision (plus the unit conversions' rounding)."""
    pairs = zip(got, sent, strict=True)
    return all(math.isclose(g, s, rel_tol=1e-6, abs_tol=1e-9) for g, s in pairs)


def parse_one(raw: bytes, max_data_len: int = 255) -> BoardFrame:
    parser = BoardFrameParser(max_data_len)
    frames = parser.feed(raw)
    assert parser.pending == b""
    assert len(frames) == 1
    return frames[0]


# ---------------------------------------------------------------- (a) round trips


@SETTINGS
@given(requests)
def test_every_request_round_trips_through_the_parser(request_: BoardRequest) -> None:
    raw = request_.encode()
    assert raw[:2] == HEADER
    assert len(raw) == raw[3] + 5
    assert raw[-1] == oracle_crc8(raw[2:-1])
    assert_same_request(decode_request(parse_one(raw)), request_)


@SETTINGS
@given(reports)
def test_every_report_round_trips_through_the_links_parser(report: EncodableReport) -> None:
    raw = report.encode()
    assert raw[-1] == oracle_crc8(raw[2:-1])
    decoded = decode_report(parse_one(raw, REPORT_MAX_DATA))
    assert type(decoded) is type(report)
    if isinstance(report, ImuSample):
        assert isinstance(decoded, ImuSample)
        assert close(decoded.accel_mps2, report.accel_mps2)
        assert close(decoded.gyro_rad_s, report.gyro_rad_s)
    else:
        assert decoded == report


@SETTINGS
@given(st.one_of(gamepad_frames(), sbus_frames()))
def test_gamepad_and_sbus_reports_decode_field_by_field(
    case: tuple[bytes, GamepadState | SbusState]
) -> None:
    raw, expected = case
    assert decode_report(parse_one(raw, REPORT_MAX_DATA)) == expected


# ---------------------------------------------------------------- (b) garbage and chunks

# Garbage full of near misses: stray headers and half headers, false headers announcing
# long frames (up to 255 bytes), frames with unknown function codes (CRC correct).
garbage_piece = st.one_of(
    st.binary(min_size=1, max_size=12),
    st.just(HEADER),
    st.just(b"\xaa"),
    st.builds(lambda func, n: HEADER + bytes((func, n)), st.integers(*U8), st.integers(*U8)),
    st.builds(oracle_frame, st.integers(FUNCS, 255), st.binary(max_size=8)),
)
garbage = st.lists(garbage_piece, max_size=4).map(b"".join)

# Anything on the line: typed requests and reports, and arbitrary frames of every function.
frames = st.one_of(
    requests.map(lambda r: r.encode()),
    reports.map(lambda r: r.encode()),
    st.builds(oracle_frame, st.integers(0, FUNCS - 1), st.binary(max_size=40)),
    st.builds(oracle_frame, st.integers(0, FUNCS - 1), garbage),  # headers in the data
)
short_frames = st.one_of(  # what BoardLink's parser (REPORT_MAX_DATA) takes
    reports.map(lambda r: r.encode()),
    st.builds(oracle_frame, st.integers(0, FUNCS - 1), st.binary(max_size=REPORT_MAX_DATA)),
    st.builds(oracle_frame, st.integers(0, FUNCS - 1), garbage.map(lambda g: g[:REPORT_MAX_DATA])),
)
chunk_sizes = st.lists(st.integers(1, 40), min_size=1, max_size=8)


def valid_frame_starts(stream: bytes, max_data_len: int = 255) -> list[int]:
    """Every index where a complete, CRC-valid frame of a known function starts."""
    starts = []
    at = stream.find(HEADER)
    while at >= 0:
        if at + 4 <= len(stream) and stream[at + 2] < FUNCS and stream[at + 3] <= max_data_len:
            end = at + stream[at + 3] + 5
            if end <= len(stream) and stream[end - 1] == oracle_crc8(stream[at + 2 : end - 1]):
                starts.append(at)
        at = stream.find(HEADER, at + 1)
    return starts


def build_stream(pieces: list[tuple[bytes, bytes]], tail: bytes) -> tuple[bytes, list[int]]:
    """The garbage and frames joined, and where each frame starts."""
    stream, starts = b"", []
    for junk, frame in pieces:
        stream += junk
        starts.append(len(stream))
        stream += frame
    return stream + tail, starts


def feed_in_chunks(parser: BoardFrameParser, data: bytes, sizes: list[int]) -> list[bytes]:
    """Feed ``data`` in chunks cycling through ``sizes``; return the frames found, as bytes."""
    out: list[BoardFrame] = []
    i = k = 0
    while i < len(data):
        n = sizes[k % len(sizes)]
        out += parser.feed(data[i : i + n])
        i += n
        k += 1
    return [f.to_bytes() for f in out]


def check_recovery(pieces: list[tuple[bytes, bytes]], tail: bytes, sizes: list[int],
                   max_data_len: int) -> None:
    stream, starts = build_stream(pieces, tail)
    # Garbage that forms a complete CRC-valid frame (alone, or with the start of a real
    # frame after it, or inside a frame's data) IS a frame on the wire: no parser can tell
    # it from one the board sent. Such streams are ambiguous, so they are excluded here;
    # test_garbage_that_forms_a_valid_frame_is_a_frame shows what happens then.
    assume(valid_frame_starts(stream, max_data_len) == starts)
    parser = BoardFrameParser(max_data_len)
    found = feed_in_chunks(parser, stream, sizes)
    sent = [f for _, f in pieces]
    # Every frame is out once its last byte is in: none waits behind a false header.
    assert found == sent
    assert [f.to_bytes() for f in parser.flush()] == []
    assert parser.pending == b""
    assert parser.skipped_bytes == len(stream) - sum(map(len, sent))


@STREAM_SETTINGS
@given(st.lists(st.tuples(garbage, frames), max_size=6), garbage, chunk_sizes)
@example([(HEADER + b"\x05\xff", bytes.fromhex("aa 55 05 02 05 01 6f"))], b"", [1])
@example([(b"\xaa", bytes.fromhex("aa 55 05 02 05 01 6f"))], HEADER + b"\x00\x09", [40])
def test_parser_recovers_every_frame_from_garbage_in_any_chunking(
    pieces: list[tuple[bytes, bytes]], tail: bytes, sizes: list[int]
) -> None:
    check_recovery(pieces, tail, sizes, 255)


@STREAM_SETTINGS
@given(st.lists(st.tuples(garbage, short_frames), max_size=6), garbage, chunk_sizes)
def test_links_parser_recovers_every_report_from_garbage(
    pieces: list[tuple[bytes, bytes]], tail: bytes, sizes: list[int]
) -> None:
    check_recovery(pieces, tail, sizes, REPORT_MAX_DATA)


def test_garbage_that_forms_a_valid_frame_is_a_frame() -> None:
    real = bytes.fromhex("aa 55 05 02 05 01 6f")
    # A false header announcing 4 data bytes, one garbage byte and the real frame's first
    # 3 bytes, whose CRC position falls on the real frame's 4th byte. For exactly one
    # garbage byte the CRC comes out right: then the line holds a valid SYS frame there,
    # which is taken, and the real frame it overlaps is lost (no parser can tell).
    false_header = HEADER + b"\x00\x04"
    collide = [g for g in range(256)
               if oracle_crc8(b"\x00\x04" + bytes((g,)) + real[:3]) == real[3]]
    assert len(collide) == 1
    stream = false_header + bytes(collide) + real
    assert valid_frame_starts(stream) == [0, len(stream) - len(real)]
    parser = BoardFrameParser()
    assert parser.feed(stream) == [BoardFrame(0, bytes(collide) + real[:3])]
    assert parser.flush() == []
    # With any other garbage byte the real frame behind the false header is found.
    other = (collide[0] + 1) % 256
    stream = false_header + bytes((other,)) + real
    assert BoardFrameParser().feed(stream) == [BoardFrame(5, b"\x05\x01")]
    # A valid frame wholly inside garbage is simply one more frame, in its place.
    stray = oracle_frame(6, b"\x01\x20")
    assert BoardFrameParser().feed(b"\x00" + stray + b"\x13" + real) == [
        BoardFrame(6, b"\x01\x20"), BoardFrame(5, b"\x05\x01")]


# ---------------------------------------------------------------- (c) never crash


@SETTINGS
@given(st.binary(max_size=300), chunk_sizes, st.sampled_from([255, REPORT_MAX_DATA, 0]))
def test_parser_never_raises_and_accounts_for_every_byte(
    data: bytes, sizes: list[int], max_data_len: int
) -> None:
    parser = BoardFrameParser(max_data_len)
    found = feed_in_chunks(parser, data, sizes)
    assert parser.skipped_bytes + sum(map(len, found)) + len(parser.pending) == len(data)
    found += [f.to_bytes() for f in parser.flush()]
    assert parser.pending == b""
    assert parser.skipped_bytes + sum(map(len, found)) == len(data)
    at = 0  # every frame found is valid and in the input, in order, without overlap
    for raw in found:
        assert decode_frame(raw).to_bytes() == raw
        assert raw[3] <= max_data_len
        at = data.index(raw, at) + len(raw)


# Frames with a valid CRC whose data starts like the real thing (known sub-commands,
# sub-codes, plausible lengths), so the decoders are exercised past their first checks.
plausible_data = st.one_of(
    st.binary(max_size=40),
    st.tuples(st.sampled_from([int(s) for s in ServoSub] + [0x04, 0x02]),
              st.binary(max_size=8)).map(lambda t: bytes((t[0],)) + t[1]),
    st.tuples(st.integers(*U8), st.sampled_from([int(s) for s in ServoSub]),
              st.binary(max_size=6)).map(lambda t: bytes(t[:2]) + t[2]),
)
checksummed_frames = st.builds(oracle_frame, st.integers(*U8), plausible_data)
DECODERS: list[Callable[[BoardFrame], object]] = [decode_request, decode_report]


@SETTINGS
@given(st.one_of(st.binary(max_size=24), checksummed_frames))
def test_decoders_raise_only_protocol_errors(raw: bytes) -> None:
    try:
        frame = decode_frame(raw)
    except ProtocolError:
        return
    assert frame.to_bytes() == raw
    for decode in DECODERS:
        with contextlib.suppress(ProtocolError):
            decode(frame)


@SETTINGS
@given(st.integers(*U8), plausible_data)
@example(func=int(Func.PWM_SERVO), data=b"")  # a PWM reply too short to name its port
@example(func=int(Func.PWM_SERVO), data=b"\x01")
@example(func=int(Func.OLED), data=b"")
def test_decoders_take_any_frame_object(func: int, data: bytes) -> None:
    for decode in DECODERS:
        with contextlib.suppress(ProtocolError):
            decode(BoardFrame(func, data))


@SETTINGS
@given(st.integers(FUNCS, 255), st.binary(max_size=255))
def test_unknown_function_codes_are_refused_both_ways(func: int, data: bytes) -> None:
    raw = oracle_frame(func, data)
    try:
        decode_frame(raw)
    except ProtocolError as exc:
        assert f"unknown function code {func}" in str(exc)
    else:
        raise AssertionError("decode_frame took an unknown function code")
    try:
        encode_frame(func, data)
    except ProtocolError as exc:
        assert f"function code {func} is not one of the board's" in str(exc)
    else:
        raise AssertionError("encode_frame took an unknown function code")


# ---------------------------------------------------------------- (d) bad values


any_ints = st.one_of(st.integers(-70000, 70000), st.integers())
any_floats = st.floats()  # NaN, infinities, beyond float32
bad_requests: st.SearchStrategy[BoardRequest] = st.one_of(
    st.builds(ServoMove, any_ints,
              st.lists(st.tuples(any_ints, any_ints), max_size=90).map(tuple)),
    st.builds(ServoStop, st.lists(any_ints, max_size=300).map(tuple)),
    st.builds(ServoRead, st.sampled_from(ServoSub), any_ints),
    st.builds(ServoWrite, st.sampled_from(ServoSub), any_ints,
              st.lists(any_ints, max_size=3).map(tuple)),
    st.builds(MotorSpeeds, st.lists(st.tuples(any_ints, any_floats), max_size=6).map(tuple)),
    st.builds(LedBlink, any_ints, any_ints, any_ints, any_ints),
    st.builds(BuzzerBeep, any_ints, any_ints, any_ints, any_ints),
    st.builds(PwmServoMove, any_ints,
              st.lists(st.tuples(any_ints, any_ints), max_size=90).map(tuple)),
    st.builds(OledText, any_ints, st.text(max_size=300)),
)


@SETTINGS
@given(bad_requests)
def test_encoding_any_request_raises_only_config_error(request_: BoardRequest) -> None:
    try:
        raw = request_.encode()
    except ConfigError as exc:
        # Says what is allowed: a range, struct's range, a count or a kind.
        assert any(word in str(exc) for word in ("allowed", "requires", " takes ", " not "))
        return
    frame = decode_frame(raw)  # what encodes is one whole valid frame
    if not isinstance(request_, PwmServoMove | OledText):  # the simulated board's requests
        assert_same_request(decode_request(frame), request_)
