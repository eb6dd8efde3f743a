"""Issue 31: the board's PWM servo, OLED, RGB, motor duty, battery-warning, gamepad and SBUS
frames round-trip for every value the wire carries, and the parser finds them behind any
garbage (hypothesis). Frames are checked against a bitwise CRC-8/MAXIM written here."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from busarm.bus.board import REPORT_MAX_DATA
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

SETTINGS = settings(max_examples=120, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
U8, S8, U16, S16 = (0, 255), (-128, 127), (0, 65535), (-32768, 32767)
ports = st.integers(1, 4)
f32s = st.floats(width=32, allow_nan=False, allow_infinity=False)


def oracle_crc8(data: bytes) -> int:
    crc = 0
    for byte in data:
        for _ in range(8):
            mix = (crc ^ byte) & 1
            crc >>= 1
            if mix:
                crc ^= 0x8C
            byte >>= 1
    return crc


new_requests: st.SearchStrategy[BoardRequest] = st.one_of(
    st.builds(PwmServoMove, st.integers(*U16),
              st.lists(st.tuples(ports, st.integers(*U16)), min_size=1, max_size=83).map(tuple)),
    st.builds(PwmServoRead, st.sampled_from([PwmSub.READ_POSITION, PwmSub.READ_OFFSET]), ports),
    st.builds(PwmServoSetOffset, ports, st.integers(*S8)),
    st.builds(OledText, st.integers(*U8), st.text(max_size=60)),
    st.builds(RgbSet, st.lists(st.tuples(st.integers(1, 256), st.integers(*U8),
                                         st.integers(*U8), st.integers(*U8)),
                               min_size=1, max_size=63).map(tuple)),
    st.builds(MotorDuties, st.lists(st.tuples(st.integers(1, 4), f32s), min_size=1,
                                    max_size=4).map(tuple)),
    st.builds(BatteryWarning, st.integers(*U16).map(lambda mv: mv / 1000)),
)
NewReport = PwmServoReply | GamepadState | SbusState
new_reports: st.SearchStrategy[NewReport] = st.one_of(
    st.builds(PwmServoReply, ports, st.just(PwmSub.READ_POSITION), st.integers(*U16)),
    st.builds(PwmServoReply, ports, st.just(PwmSub.READ_OFFSET), st.integers(*S8)),
    st.builds(GamepadState, st.integers(*U16), st.integers(*U8),
              st.tuples(*[st.integers(*S8)] * 4)),
    st.builds(SbusState, st.tuples(*[st.integers(*S16)] * 16), st.booleans(), st.booleans(),
              st.booleans(), st.booleans()),
)


@SETTINGS
@given(new_requests)
def test_every_new_request_round_trips(request_: BoardRequest) -> None:
    raw = request_.encode()
    assert raw[-1] == oracle_crc8(raw[2:-1]) and len(raw) == raw[3] + 5
    # duties are drawn as float32 already, so equality is exact
    assert decode_request(BoardFrameParser().feed(raw)[0]) == request_


@SETTINGS
@given(new_reports)
def test_every_new_report_round_trips_through_the_links_parser(report: NewReport) -> None:
    raw = report.encode()
    assert raw[-1] == oracle_crc8(raw[2:-1])
    frames = BoardFrameParser(REPORT_MAX_DATA).feed(raw)
    assert len(frames) == 1 and decode_report(frames[0]) == report


@SETTINGS
@given(st.lists(st.tuples(st.binary(max_size=10), st.one_of(new_requests, new_reports)),
                min_size=1, max_size=6),
       st.integers(1, 40))
def test_new_frames_are_found_behind_garbage_in_any_chunks(
        items: list[tuple[bytes, BoardRequest | NewReport]], chunk: int) -> None:
    stream = bytearray()
    sent: list[bytes] = []
    for garbage, message in items:
        raw = message.encode()
        # garbage that cannot end in a frame's header, so the frame after it stays whole
        stream += garbage.replace(b"\xaa", b"\x00") + raw
        sent.append(raw)
    parser = BoardFrameParser()
    found = [f.to_bytes() for at in range(0, len(stream), chunk)
             for f in parser.feed(stream[at:at + chunk])]
    found += [f.to_bytes() for f in parser.flush()]
    assert found == sent  # the garbage holds no AA, so it can hide no frame of its own
