"""The RPLIDAR A1 codec against byte vectors written out from Slamtec's public protocol
document (requests A5 cmd; descriptors A5 5A + 30-bit length | 2-bit mode + type; 5-byte
measurement nodes), not produced by busarm's own encoder."""

from __future__ import annotations

import math

import pytest

from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.rplidar import (
    HEALTH_DESCRIPTOR,
    INFO_DESCRIPTOR,
    SCAN_DESCRIPTOR,
    Cmd,
    DataType,
    Descriptor,
    DeviceInfo,
    HealthStatus,
    Node,
    NodeParser,
    RequestParser,
    decode_descriptor,
    decode_health,
    decode_info,
    decode_node,
    encode_request,
    find_descriptor,
    node_from_si,
)


@pytest.mark.parametrize(("cmd", "wire"), [
    (Cmd.STOP, "a5 25"), (Cmd.RESET, "a5 40"), (Cmd.SCAN, "a5 20"),
    (Cmd.GET_INFO, "a5 50"), (Cmd.GET_HEALTH, "a5 52"),
])
def test_requests_without_payload(cmd: Cmd, wire: str) -> None:
    assert encode_request(cmd) == bytes.fromhex(wire)


def test_a_payload_request_carries_size_and_xor_checksum() -> None:
    # SET_MOTOR_PWM (0xF0) 660: A5 F0 02 94 02, checksum A5^F0^02^94^02 = C1.
    assert encode_request(0xF0, (660).to_bytes(2, "little")) == bytes.fromhex("a5 f0 02 94 02 c1")


def test_descriptors() -> None:
    assert SCAN_DESCRIPTOR.encode() == bytes.fromhex("a5 5a 05 00 00 40 81")
    assert INFO_DESCRIPTOR.encode() == bytes.fromhex("a5 5a 14 00 00 00 04")
    assert HEALTH_DESCRIPTOR.encode() == bytes.fromhex("a5 5a 03 00 00 00 06")
    assert decode_descriptor(bytes.fromhex("a5 5a 05 00 00 40 81")) == Descriptor(
        5, 1, DataType.MEASUREMENT)
    with pytest.raises(ProtocolError, match="A5 5A"):
        decode_descriptor(bytes.fromhex("a5 5b 05 00 00 40 81"))


def test_find_descriptor_skips_what_comes_before_it() -> None:
    found = find_descriptor(bytes.fromhex("00 a5 11 a5 5a 03 00 00 00 06 00 00 00"))
    assert found == (HEALTH_DESCRIPTOR, 10)
    assert find_descriptor(bytes.fromhex("a5 5a 03 00")) is None


def test_measurement_node_bytes() -> None:
    # S=1, quality 47: 47<<2 | 0<<1 | 1 = 0xBD; 90 deg = angle_q6 5760: 5760<<1|1 = 0x2D01;
    # 1000 mm = distance_q2 4000 = 0x0FA0.
    wire = bytes.fromhex("bd 01 2d a0 0f")
    node = decode_node(wire)
    assert node == Node(start=True, quality=47, angle_q6=5760, distance_q2=4000)
    assert node.encode() == wire
    assert node.angle_rad == pytest.approx(math.pi / 2)
    assert node.distance_m == 1.0
    assert Node(False, 47, 5760, 4000).encode() == bytes.fromhex("be 01 2d a0 0f")


@pytest.mark.parametrize("wire", ["bf 01 2d a0 0f", "bc 01 2d a0 0f", "bd 00 2d a0 0f"])
def test_a_node_with_bad_flags_is_refused(wire: str) -> None:
    with pytest.raises(ProtocolError, match="not a measurement node"):
        decode_node(bytes.fromhex(wire))


def test_node_from_si_rounds_to_the_wire_units() -> None:
    node = node_from_si(False, 10, math.radians(359.999), 12.3456)
    assert node.angle_q6 == 0  # wraps to 0 deg
    assert node.distance_q2 == 49382  # 12345.6 mm * 4, rounded
    assert node_from_si(False, 0, 0.0, math.inf).distance_q2 == 0
    with pytest.raises(ConfigError, match="angle_q6"):
        Node(False, 0, 40000, 0).encode()


def test_device_info_and_health() -> None:
    info = decode_info(bytes.fromhex("18 1d 01 07") + bytes(range(16)))
    assert info == DeviceInfo(0x18, (1, 29), 7, bytes(range(16)))
    assert info.serial_hex == "000102030405060708090A0B0C0D0E0F"
    health = decode_health(bytes.fromhex("02 01 80"))
    assert health.status is HealthStatus.ERROR and health.error_code == 0x8001
    with pytest.raises(ProtocolError, match="status 7"):
        decode_health(bytes.fromhex("07 00 00"))
    with pytest.raises(ProtocolError, match="20 bytes"):
        decode_info(b"\x18")


def test_node_parser_resyncs_after_noise() -> None:
    nodes = [Node(True, 47, 0, 4000), Node(False, 47, 64, 4004)]
    stream = bytes.fromhex("00 03 ff") + b"".join(n.encode() for n in nodes)
    parser = NodeParser()
    assert parser.feed(stream[:4]) == []
    assert parser.feed(stream[4:]) == nodes
    assert parser.skipped_bytes == 3


def test_request_parser_finds_requests_in_noise() -> None:
    parser = RequestParser()
    got = parser.feed(bytes.fromhex("00 11 a5 25 a5 f0 02 94 02 c1 a5 f0 02 94 02 00 a5"))
    assert [(r.cmd, r.payload) for r in got] == [(0x25, b""), (0xF0, b"\x94\x02")]
    assert parser.rejected == 1
    assert [r.cmd for r in parser.feed(b"\x50")] == [0x50]
