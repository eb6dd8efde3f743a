"""Properties of the protocol codec and the incremental frame parser (hypothesis).

The value ranges below are copied from the manual, not from busarm's tables, and
frames are checksummed here with the manual's formula, so the properties do not
merely restate the implementation.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable

from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st

from busarm.errors import BusArmError, ConfigError
from busarm.protocol import (
    AlarmFlag,
    AngleLimitReply,
    AngleOffsetReply,
    Command,
    Frame,
    FrameParser,
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

SETTINGS = settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
STREAM_SETTINGS = settings(SETTINGS, max_examples=100)
"""For the parser-stream properties, whose examples are larger."""

C = Command
U8, S8, U16, S16 = (0, 255), (-128, 127), (0, 65535), (-32768, 32767)

# Request parameter ranges from the manual (the mode command's null byte is 0..0).
REQUEST_RANGES: dict[Command, tuple[tuple[int, int], ...]] = {
    C.MOVE_TIME_WRITE: ((0, 1000), (0, 30000)),
    C.MOVE_TIME_WAIT_WRITE: ((0, 1000), (0, 30000)),
    C.ID_WRITE: ((0, 253),),
    C.ANGLE_OFFSET_ADJUST: ((-125, 125),),
    C.ANGLE_LIMIT_WRITE: ((0, 1000), (0, 1000)),
    C.VIN_LIMIT_WRITE: ((4500, 12000), (4500, 12000)),
    C.TEMP_MAX_LIMIT_WRITE: ((50, 100),),
    C.OR_MOTOR_MODE_WRITE: ((0, 1), (0, 0), (-1000, 1000)),
    C.LOAD_OR_UNLOAD_WRITE: ((0, 1),),
    C.LED_CTRL_WRITE: ((0, 1),),
    C.LED_ERROR_WRITE: ((0, 7),),
}
MIN_BELOW_MAX = {C.ANGLE_LIMIT_WRITE, C.VIN_LIMIT_WRITE}

# Every reply with the full range its wire layout can carry; enums and flags only
# within the manual's values (anything else is rejected on decode by design).
REPLY_STRATEGIES: list[st.SearchStrategy[Reply]] = [
    st.builds(MoveTimeReply, st.integers(*U16), st.integers(*U16)),
    st.builds(MoveTimeWaitReply, st.integers(*U16), st.integers(*U16)),
    st.builds(IdReply, st.integers(*U8)),
    st.builds(AngleOffsetReply, st.integers(*S8)),
    st.builds(AngleLimitReply, st.integers(*U16), st.integers(*U16)),
    st.builds(VinLimitReply, st.integers(*U16), st.integers(*U16)),
    st.builds(TempMaxLimitReply, st.integers(*U8)),
    st.builds(TempReply, st.integers(*U8)),
    st.builds(VinReply, st.integers(*U16)),
    st.builds(PositionReply, st.integers(*S16)),
    st.builds(ModeReply, st.sampled_from(ServoMode), st.integers(*S16)),
    st.builds(LoadReply, st.booleans()),
    st.builds(LedCtrlReply, st.booleans()),
    st.builds(LedErrorReply, st.integers(0, 7).map(AlarmFlag)),
]

servo_ids = st.integers(0, 254)
replies = st.one_of(REPLY_STRATEGIES)


@st.composite
def requests(draw: st.DrawFn) -> Request:
    command = draw(st.sampled_from(Command))
    ranges = REQUEST_RANGES.get(command, ())
    if command in MIN_BELOW_MAX:
        (lo, hi), _ = ranges
        a = draw(st.integers(lo, hi - 1))
        args: tuple[int, ...] = (a, draw(st.integers(a + 1, hi)))
    else:
        args = tuple(draw(st.integers(lo, hi)) for lo, hi in ranges)
    return Request(draw(servo_ids), command, args)


def checksum(body: bytes) -> int:
    return (~sum(body)) & 0xFF


def frame_bytes(servo_id: int, command: int, params: bytes) -> bytes:
    body = bytes((servo_id, len(params) + 3, command)) + params
    return b"\x55\x55" + body + bytes((checksum(body),))


# Anything a host or a servo sends on the bus: encoded requests and replies.
wire_frames = st.one_of(
    requests().map(lambda r: r.to_bytes()),
    st.tuples(servo_ids, replies).map(lambda t: encode_reply(*t)),
)
# Garbage that cannot contain (part of) a header: the 0x55 bytes are removed.
garbage = st.binary(max_size=24).map(lambda b: b.replace(b"\x55", b""))
chunk_sizes = st.lists(st.integers(1, 16), min_size=1, max_size=8)


def feed_in_chunks(parser: FrameParser, data: bytes, sizes: list[int]) -> list[bytes]:
    """Feed ``data`` in chunks cycling through ``sizes``; return the frames found, as bytes."""
    out: list[Frame] = []
    i = 0
    k = 0
    while i < len(data):
        n = sizes[k % len(sizes)]
        out += parser.feed(data[i : i + n])
        i += n
        k += 1
    return [f.to_bytes() for f in out]


def spurious_frame_starts_in(stream: bytes, start: int, stop: int) -> bool:
    """Whether a checksum-valid frame candidate starts at any index in start..stop-1.

    Inside damaged bytes such a window is a real ambiguity (the damage happened to
    produce a valid frame, possibly overlapping the next real one): no parser can
    tell it from a genuine frame, so properties about damage assume it away.
    """
    for p in range(start, stop):
        if stream[p : p + 2] != b"\x55\x55" or p + 4 > len(stream):
            continue
        end = p + stream[p + 3] + 3
        if (
            stream[p + 3] >= 3
            and end <= len(stream)
            and stream[end - 1] == checksum(stream[p + 2 : end - 1])
        ):
            return True
    return False


# ---------------------------------------------------------------- (a) round trips


@SETTINGS
@given(requests())
def test_request_round_trip(req: Request) -> None:
    raw = req.to_bytes()
    assert raw == encode_request(req.servo_id, req.command, *req.args)
    assert len(raw) == raw[3] + 3
    assert raw[-1] == checksum(raw[2:-1])
    frame = decode_frame(raw)
    assert decode_request(frame) == req
    assert decode_message(frame) == req


@SETTINGS
@given(servo_ids, replies)
def test_reply_round_trip(servo_id: int, reply: Reply) -> None:
    raw = encode_reply(servo_id, reply)
    assert raw[-1] == checksum(raw[2:-1])
    frame = decode_frame(raw)
    assert frame.servo_id == servo_id
    decoded = decode_reply(frame)
    assert decoded == reply
    assert type(decoded) is type(reply)
    assert decode_message(frame) == reply


# ---------------------------------------------------------------- (b) garbage and chunks


@STREAM_SETTINGS
@given(st.lists(st.tuples(garbage, wire_frames), max_size=8), garbage, chunk_sizes)
def test_parser_recovers_every_frame_from_garbage_in_any_chunking(
    pieces: list[tuple[bytes, bytes]], tail: bytes, sizes: list[int]
) -> None:
    stream = b"".join(g + f for g, f in pieces) + tail
    parser = FrameParser()
    found = feed_in_chunks(parser, stream, sizes)
    assert found == [f for _, f in pieces]
    assert parser.pending == b""
    assert parser.skipped_bytes == sum(len(g) for g, _ in pieces) + len(tail)
    assert parser.checksum_failures == 0
    assert parser.flush() == []


@STREAM_SETTINGS
@given(st.one_of(st.just(b"\x55"), st.binary(min_size=1, max_size=4)), wire_frames, chunk_sizes)
@example(b"\x55", bytes.fromhex("55 55 07 03 1c d9"), [16])
@example(b"\x55", bytes.fromhex("55 55 05 03 1c db"), [1])
def test_frame_behind_stray_bytes_is_delivered_without_waiting(
    junk: bytes, frame: bytes, sizes: list[int]
) -> None:
    # A stray 0x55 makes "55 55 55 ID ..." look like a header whose length byte is the
    # frame's ID; the parser must not sit on the real frame waiting for that phantom.
    stream = junk + frame
    assume(not spurious_frame_starts_in(stream, 0, len(junk)))
    parser = FrameParser()
    assert feed_in_chunks(parser, stream, sizes) == [frame]
    assert parser.pending == b""


# ---------------------------------------------------------------- (c) corruption


@STREAM_SETTINGS
@given(
    st.lists(wire_frames, max_size=4),
    wire_frames,
    st.lists(st.tuples(garbage, wire_frames), min_size=1, max_size=4),
    st.data(),
    chunk_sizes,
)
def test_corrupted_frame_loses_at_most_itself(
    before: list[bytes],
    victim: bytes,
    after: list[tuple[bytes, bytes]],
    data: st.DataObject,
    sizes: list[int],
) -> None:
    index = data.draw(st.integers(0, len(victim) - 1), label="index")
    value = data.draw(st.integers(0, 255).filter(lambda v: v != victim[index]), label="value")
    damaged = victim[:index] + bytes((value,)) + victim[index + 1 :]
    head = b"".join(before)
    stream = head + damaged + b"".join(g + f for g, f in after)
    assume(not spurious_frame_starts_in(stream, len(head), len(head) + len(damaged)))

    parser = FrameParser()
    found = feed_in_chunks(parser, stream, sizes) + [f.to_bytes() for f in parser.flush()]
    assert found == before + [f for _, f in after]
    assert parser.pending == b""


# ---------------------------------------------------------------- (d) truncation


@STREAM_SETTINGS
@given(
    st.lists(wire_frames, max_size=3),
    wire_frames,
    st.data(),
    garbage,
    st.lists(wire_frames, max_size=4),
    chunk_sizes,
)
def test_truncated_frame_does_not_hide_the_frames_after_it(
    before: list[bytes],
    victim: bytes,
    data: st.DataObject,
    gap: bytes,
    after: list[bytes],
    sizes: list[int],
) -> None:
    cut = data.draw(st.integers(1, len(victim) - 1), label="cut")
    head = b"".join(before)
    stream = head + victim[:cut] + gap + b"".join(after)
    assume(not spurious_frame_starts_in(stream, len(head), len(head) + cut))

    parser = FrameParser()
    found = feed_in_chunks(parser, stream, sizes) + [f.to_bytes() for f in parser.flush()]
    assert found == before + after
    assert parser.pending == b""


@STREAM_SETTINGS
@given(wire_frames, st.data(), st.lists(wire_frames, min_size=1, max_size=4), chunk_sizes)
def test_flush_after_an_idle_line_drops_the_partial_frame(
    victim: bytes, data: st.DataObject, after: list[bytes], sizes: list[int]
) -> None:
    cut = data.draw(st.integers(1, len(victim) - 1), label="cut")
    parser = FrameParser()
    assert feed_in_chunks(parser, victim[:cut], sizes) == []
    assert parser.flush() == []
    assert parser.pending == b""
    assert feed_in_chunks(parser, b"".join(after), sizes) == after


# ---------------------------------------------------------------- (e) never crash


@SETTINGS
@given(st.binary(max_size=300), chunk_sizes)
def test_parser_never_raises_and_accounts_for_every_byte(data: bytes, sizes: list[int]) -> None:
    parser = FrameParser()
    found = feed_in_chunks(parser, data, sizes)
    assert parser.skipped_bytes + sum(map(len, found)) + len(parser.pending) == len(data)
    found += [f.to_bytes() for f in parser.flush()]
    assert parser.pending == b""
    assert parser.skipped_bytes + sum(map(len, found)) == len(data)
    # Every frame found is checksum-valid and occurs in the input, in order, without overlap.
    at = 0
    for raw in found:
        decode_frame(raw)
        at = data.index(raw, at) + len(raw)


# Frames with a valid checksum and an arbitrary (often known) command and parameters:
# they get past decode_frame, so they exercise decode_request/decode_reply fully.
checksummed_frames = st.builds(
    frame_bytes,
    st.integers(0, 255),
    st.one_of(st.sampled_from([int(c) for c in Command]), st.integers(0, 255)),
    st.binary(max_size=6),
)
DECODERS: list[Callable[[Frame], object]] = [decode_request, decode_reply, decode_message]


@SETTINGS
@given(st.one_of(st.binary(max_size=16), checksummed_frames))
def test_decoders_raise_only_busarm_errors(raw: bytes) -> None:
    try:
        frame = decode_frame(raw)
    except BusArmError:
        return
    for decode in DECODERS:
        with contextlib.suppress(BusArmError):
            decode(frame)


@SETTINGS
@given(
    st.one_of(st.integers(), st.sampled_from(Command)),
    st.integers(-300, 300),
    st.lists(st.one_of(st.integers(), st.integers(-2000, 40000)), max_size=5),
)
def test_encode_request_raises_only_config_error(
    command: int, servo_id: int, args: list[int]
) -> None:
    try:
        raw = encode_request(servo_id, command, *args)  # type: ignore[arg-type]
    except ConfigError:
        return
    assert decode_request(decode_frame(raw)).args[-1:] == tuple(args[-1:])


@SETTINGS
@given(st.text(max_size=30))
def test_command_parse_raises_only_config_error(text: str) -> None:
    try:
        command = Command.parse(text)
    except ConfigError:
        return
    assert isinstance(command, Command)
