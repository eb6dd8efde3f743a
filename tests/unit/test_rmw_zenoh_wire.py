"""rmw_zenoh's wire format, checked against its design document and sources (field notes,
section 6): key expressions, the 33-byte attachment, liveliness tokens, GIDs."""

from __future__ import annotations

import struct

import pytest
import xxhash

from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.rmw_zenoh import (
    LATCHED,
    SENSOR_DATA,
    Attachment,
    Entity,
    Qos,
    dds_type_name,
    gid_of,
    parse_token,
    parse_topic_key,
    topic_key,
)
from busarm.ros.messages import JOINT_STATE, ros_type

JOINT_STATE_HASH = "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e"
ZID = "1863437b7dc1c46969bfaff068f33402"


def test_joint_states_key_is_the_design_documents() -> None:
    assert ros_type(JOINT_STATE).type_hash == JOINT_STATE_HASH  # rosbags' RIHS01 for Jazzy
    assert topic_key(0, "/joint_states", JOINT_STATE, JOINT_STATE_HASH) == (
        "0/joint_states/sensor_msgs::msg::dds_::JointState_/" + JOINT_STATE_HASH)
    assert topic_key(7, "/arm/joint_states", JOINT_STATE, "TypeHashNotSupported") == (
        "7/arm/joint_states/sensor_msgs::msg::dds_::JointState_/TypeHashNotSupported")
    key = parse_topic_key("0/arm/joint_states/sensor_msgs::msg::dds_::JointState_/"
                          + JOINT_STATE_HASH)
    assert (key.domain_id, key.topic, key.ros_type) == (0, "/arm/joint_states", JOINT_STATE)


def test_the_attachment_is_33_bytes_sequence_stamp_length_gid() -> None:
    gid = bytes(range(16))
    raw = Attachment(7, 1_700_000_000_123_456_789, gid).encode()
    assert len(raw) == 33
    assert raw[:8] == (7).to_bytes(8, "little")
    assert raw[8:16] == (1_700_000_000_123_456_789).to_bytes(8, "little")
    assert raw[16] == 16 and raw[17:] == gid
    assert Attachment.decode(raw) == Attachment(7, 1_700_000_000_123_456_789, gid)


@pytest.mark.parametrize("raw", [b"", b"\x00" * 32, b"\x00" * 34,
                                 struct.pack("<qqB16s", 1, 2, 15, b"x" * 16)])
def test_a_malformed_attachment_is_a_protocol_error(raw: bytes) -> None:
    with pytest.raises(ProtocolError, match="attachment|GID"):
        Attachment.decode(raw)


def test_tokens_are_rmw_zenohs() -> None:
    node = Entity(0, ZID, 0, 0, "NN", "busarm")
    assert node.token() == f"@ros2_lv/0/{ZID}/0/0/NN/%/%/busarm"
    pub = Entity(0, ZID, 0, 3, "MP", "busarm", topic="/joint_states", ros_type=JOINT_STATE,
                 type_hash=JOINT_STATE_HASH, qos=Qos())
    assert pub.token() == (f"@ros2_lv/0/{ZID}/0/3/MP/%/%/busarm/%joint_states/"
                           f"sensor_msgs::msg::dds_::JointState_/{JOINT_STATE_HASH}/::,:,:,:,,")
    # Each QoS field differing from rmw_zenoh's default (reliable, volatile, keep last 42)
    # is written as rmw's enum value: transient local 1, best effort 2, the depth.
    assert LATCHED.key() == ":1:,1:,:,:,,"
    assert SENSOR_DATA.key() == "2::,5:,:,:,,"
    ns = Entity(3, ZID, 0, 1, "MS", "busarm", "/robot1", topic="/robot1/cmd_vel",
                ros_type="geometry_msgs/msg/Twist", type_hash=ros_type(
                    "geometry_msgs/msg/Twist").type_hash, qos=Qos(depth=10))
    assert ns.token().startswith(f"@ros2_lv/3/{ZID}/0/1/MS/%/%robot1/busarm/%robot1%cmd_vel/"
                                 "geometry_msgs::msg::dds_::Twist_/RIHS01_")
    assert ns.token().endswith("/::,10:,:,:,,")
    assert parse_token(ns.token()) == ns


def test_a_gid_is_the_xxh3_128_of_the_token_low_half_first() -> None:
    token = f"@ros2_lv/0/{ZID}/0/3/MP/%/%/busarm/%joint_states/x::msg::dds_::Y_/" \
            "TypeHashNotSupported/::,:,:,:,,"
    digest = xxhash.xxh3_128(token.encode())
    low, high = digest.intdigest() & (2**64 - 1), digest.intdigest() >> 64
    assert gid_of(token) == low.to_bytes(8, "little") + high.to_bytes(8, "little")


@pytest.mark.parametrize("bad", ["", "/", "joint states", "/a//b", "/a/", "/9x"])
def test_a_bad_topic_name_is_refused(bad: str) -> None:
    with pytest.raises(ConfigError, match="not a ROS 2 topic name"):
        topic_key(0, bad, JOINT_STATE, JOINT_STATE_HASH)


@pytest.mark.parametrize("domain", [-1, 233, True, 1.5])
def test_a_domain_outside_0_232_is_refused(domain: object) -> None:
    with pytest.raises(ConfigError, match="0..232"):
        topic_key(domain, "/x", JOINT_STATE, JOINT_STATE_HASH)  # type: ignore[arg-type]


@pytest.mark.parametrize("key", ["0/x", "a/x/sensor_msgs::msg::dds_::JointState_/h",
                                 "0/x/sensor_msgs/msg/JointState/" + JOINT_STATE_HASH,
                                 "0/x/sensor_msgs::msg::dds_::JointState_/RIHS01_zz"])
def test_a_key_that_is_not_rmw_zenohs_is_a_protocol_error(key: str) -> None:
    with pytest.raises(ProtocolError):
        parse_topic_key(key)


def test_dds_names() -> None:
    assert dds_type_name("std_msgs/msg/String") == "std_msgs::msg::dds_::String_"
    with pytest.raises(ConfigError, match="not a ROS 2 type name"):
        dds_type_name("std_msgs/String")
