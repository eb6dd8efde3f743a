"""Property tests of rmw_zenoh's wire format: what is encoded decodes to itself, and any
bytes or key decode to a value or a ProtocolError, never anything else."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from busarm.errors import ProtocolError
from busarm.protocol.rmw_zenoh import (
    Attachment,
    Durability,
    Entity,
    History,
    Qos,
    Reliability,
    TopicKey,
    parse_token,
    parse_topic_key,
    topic_key,
)

INT64 = st.integers(-(2**63), 2**63 - 1)
NAME = st.from_regex(r"[a-z][a-z0-9_]{0,8}", fullmatch=True)
TOPIC = st.lists(NAME, min_size=1, max_size=3).map(lambda parts: "/" + "/".join(parts))
TYPE = st.tuples(NAME, st.from_regex(r"[A-Z][A-Za-z0-9]{0,8}", fullmatch=True)).map(
    lambda t: f"{t[0]}/msg/{t[1]}")
HASH = st.one_of(st.just("TypeHashNotSupported"),
                 st.from_regex(r"RIHS01_[0-9a-f]{64}", fullmatch=True))
QOS = st.builds(Qos, st.sampled_from(Reliability), st.sampled_from(Durability),
                st.sampled_from(History), st.integers(1, 10_000), st.integers(0, 10**12))


@given(INT64, INT64, st.binary(min_size=16, max_size=16))
def test_an_attachment_decodes_to_itself(seq: int, stamp: int, gid: bytes) -> None:
    assert Attachment.decode(Attachment(seq, stamp, gid).encode()) == Attachment(seq, stamp, gid)


@given(st.binary(max_size=64))
def test_any_bytes_are_an_attachment_or_a_protocol_error(raw: bytes) -> None:
    try:
        got = Attachment.decode(raw)
    except ProtocolError:
        return
    assert got.encode() == raw


@given(st.integers(0, 232), TOPIC, TYPE, HASH)
def test_a_topic_key_parses_back(domain: int, topic: str, ros_type: str, h: str) -> None:
    key = parse_topic_key(topic_key(domain, topic, ros_type, h))
    assert (key.domain_id, key.topic, key.ros_type, key.type_hash) == (domain, topic,
                                                                       ros_type, h)


@given(st.integers(0, 232), st.integers(0, 10**6), st.sampled_from(["MP", "MS"]), NAME,
       st.one_of(st.just("/"), TOPIC), TOPIC, TYPE, HASH, QOS)
def test_a_token_parses_back(domain: int, eid: int, kind: str, node: str, ns: str,
                             topic: str, ros_type: str, h: str, qos: Qos) -> None:
    entity = Entity(domain, "ab12", 0, eid, kind, node, ns, topic=topic, ros_type=ros_type,
                    type_hash=h, qos=qos)
    assert parse_token(entity.token()) == entity


@given(st.one_of(st.text(max_size=120), st.lists(
    st.one_of(NAME, st.sampled_from(["@ros2_lv", "MP", "NN", "%", "0", "::,:,:,:,,",
                                     "a::msg::dds_::B_", "TypeHashNotSupported"])),
    max_size=14).map("/".join)))
def test_any_text_is_a_token_or_a_protocol_error(text: str) -> None:
    for parse, kind in ((parse_token, Entity), (parse_topic_key, TopicKey)):
        try:
            got = parse(text)
        except ProtocolError:
            continue
        assert isinstance(got, kind)
