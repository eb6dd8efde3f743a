"""The RPLIDAR codec's sample rate, scan-mode configuration and express capsules: byte
vectors worked out here from Slamtec's protocol description, round trips (hypothesis),
and the capsule parser recovering capsules from garbage."""

from __future__ import annotations

import itertools

import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.rplidar import (
    SAMPLERATE_DESCRIPTOR,
    Cmd,
    ConfType,
    SampleRate,
    ScanMode,
    conf_descriptor,
    conf_payload,
    decode_conf,
    decode_q8,
    decode_samplerate,
    encode_request,
)
from busarm.protocol.rplidar_express import (
    CAPSULE_SAMPLES,
    EXPRESS_DESCRIPTOR,
    Capsule,
    CapsuleParser,
    capsule_nodes,
    decode_capsule,
    express_payload,
    is_capsule,
)


def test_request_and_answer_bytes() -> None:
    # A5 84 04 | 70 00 00 00 | A5^84^04^70 = 55: "how many scan modes?"
    assert encode_request(Cmd.GET_LIDAR_CONF, conf_payload(ConfType.SCAN_MODE_COUNT)) == \
        bytes.fromhex("A5 84 04 70 00 00 00 55")
    # Mode 1's name: type 7F, then the mode id 01 00; A5^84^06^7F^01 = 59.
    assert encode_request(Cmd.GET_LIDAR_CONF, conf_payload(ConfType.SCAN_MODE_NAME, 1)) == \
        bytes.fromhex("A5 84 06 7F 00 00 00 01 00 59")
    # Legacy express scan: working mode 0 and 4 reserved bytes; A5^82^05 = 22.
    assert encode_request(Cmd.EXPRESS_SCAN, express_payload(0)) == \
        bytes.fromhex("A5 82 05 00 00 00 00 00 22")
    assert SAMPLERATE_DESCRIPTOR.encode() == bytes.fromhex("A5 5A 04 00 00 00 15")
    assert EXPRESS_DESCRIPTOR.encode() == bytes.fromhex("A5 5A 54 00 00 40 82")
    assert conf_descriptor(2).encode() == bytes.fromhex("A5 5A 06 00 00 00 20")
    # 500 us standard, 250 us express.
    assert SampleRate(500, 250).encode() == bytes.fromhex("F4 01 FA 00")
    assert decode_samplerate(bytes.fromhex("F4 01 FA 00")) == SampleRate(500, 250)
    # 250 us in Q8 = 64000 = 0x0000FA00; 12 m in Q8 = 3072 = 0x00000C00.
    express = ScanMode(1, "Express", 250.0, 12.0, 0x82)
    assert express.value(ConfType.SCAN_MODE_US_PER_SAMPLE) == bytes.fromhex("00 FA 00 00")
    assert express.value(ConfType.SCAN_MODE_MAX_DISTANCE) == bytes.fromhex("00 0C 00 00")
    assert express.value(ConfType.SCAN_MODE_NAME) == b"Express\0"
    assert decode_q8(bytes.fromhex("00 FA 00 00")) == 250.0
    assert decode_conf(bytes.fromhex("7C 00 00 00 01 00"), ConfType.SCAN_MODE_TYPICAL) == \
        b"\x01\x00"
    with pytest.raises(ProtocolError, match="asked configuration 0x70, got 0x7C"):
        decode_conf(bytes.fromhex("7C 00 00 00 01 00"), ConfType.SCAN_MODE_COUNT)
    with pytest.raises(ConfigError, match="needs a scan mode id"):
        conf_payload(ConfType.SCAN_MODE_NAME)


def test_a_capsule_worked_by_hand() -> None:
    # Start angle 90 degrees (q6 5760 = 0x1680) with S: word 0x9680. Sample 0: 1000 mm,
    # offset 0x25 (high bits 10, low 0101); sample 1: 2 mm, offset 0x03; the rest 0.
    body = bytes.fromhex("80 96") + (1000 << 2 | 0b10).to_bytes(2, "little") + \
        (2 << 2).to_bytes(2, "little") + bytes((0x5 | 0x3 << 4,)) + bytes(75)
    checksum = 0
    for b in body:
        checksum ^= b
    wire = bytes((0xA0 | checksum & 0xF, 0x50 | checksum >> 4)) + body
    capsule = decode_capsule(wire)
    assert capsule.start and capsule.start_angle_q6 == 5760
    assert capsule.distances_mm[:3] == (1000, 2, 0) and capsule.offsets_q3[:3] == (0x25, 3, 0)
    assert capsule.encode() == wire
    # The next capsule starts 32 degrees on: samples 1 degree apart, less their offsets.
    following = Capsule(False, 5760 + 32 * 64, (0,) * 32, (0,) * 32)
    nodes = capsule_nodes(capsule, following)
    assert nodes[0].angle_q6 == 5760 - 0x25 * 8 and nodes[0].distance_q2 == 4000
    assert nodes[1].angle_q6 == 5760 + 64 - 3 * 8 and nodes[2].angle_q6 == 5760 + 128
    assert not is_capsule(wire[:-1] + bytes((wire[-1] ^ 1,)))


capsules = st.builds(
    Capsule, st.booleans(), st.integers(0, 360 * 64 - 1),
    st.lists(st.integers(0, 0x3FFF), min_size=32, max_size=32).map(tuple),
    st.lists(st.integers(0, 0x3F), min_size=32, max_size=32).map(tuple))


@given(capsules)
def test_capsules_round_trip(capsule: Capsule) -> None:
    assert decode_capsule(capsule.encode()) == capsule


# Noise in which no capsule can start (no byte has the sync nibble A): the guarantee is
# then exact. (Noise that starts with A can fake a capsule only by also passing the
# second nibble and the 8-bit checksum: 1 window in 65,536.)
noise_bytes = st.binary(max_size=12).map(lambda b: bytes(x & 0x7F for x in b))


@given(st.lists(capsules, min_size=3, max_size=6),
       st.lists(noise_bytes, min_size=6, max_size=6), st.integers(1, 200))
def test_the_capsule_parser_recovers_every_capsule_after_garbage(
    sent: list[Capsule], noise: list[bytes], piece: int
) -> None:
    # Capsules after the first are not starts (a start discards the capsule before it).
    sent = [sent[0]] + [Capsule(False, c.start_angle_q6, c.distances_mm, c.offsets_q3)
                        for c in sent[1:]]
    wire = b"".join(n + c.encode() for n, c in zip(noise, sent, strict=False))
    parser = CapsuleParser()
    got = []
    for at in range(0, len(wire), piece):
        got += parser.feed(wire[at : at + piece])
    want = [n for a, b in itertools.pairwise(sent) for n in capsule_nodes(a, b)]
    assert got == want
    assert parser.skipped_bytes == sum(map(len, noise[: len(sent)]))
    assert len(got) == CAPSULE_SAMPLES * (len(sent) - 1)


def test_a_lost_capsule_drops_the_one_before_it_not_its_angles() -> None:
    # Four capsules 32 degrees apart; the third corrupted (a stray byte inside it): the
    # second cannot know where its samples end, so it is dropped, not spread over 64.
    sent = [Capsule(False, k * 32 * 64, tuple(range(500 + k, 532 + k)), (0,) * 32)
            for k in range(5)]
    wires = [c.encode() for c in sent]
    wires[2] = wires[2][:40] + b"\x5a" + wires[2][40:]
    parser = CapsuleParser()
    got = parser.feed(b"".join(wires))
    assert parser.skipped_bytes == len(wires[2])
    assert got == capsule_nodes(sent[0], sent[1]) + capsule_nodes(sent[3], sent[4])
    assert max(n.angle_q6 for n in got[:32]) < 32 * 64
