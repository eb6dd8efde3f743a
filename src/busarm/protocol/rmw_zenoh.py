"""rmw_zenoh's wire format: key expressions, attachments and liveliness tokens (no I/O).

What a ROS 2 node using rmw_zenoh (Jazzy and later) puts on Zenoh, from its design
document and its sources (see ../shared/reference/field-notes.md, section 6):

- a message is published on ``<domain>/<topic without leading slash>/<DDS type>/<hash>``,
  e.g. ``0/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e...``; its payload
  is CDR (busarm.ros.messages) and it carries a 33-byte attachment: the sequence number
  and the source timestamp in ns (int64, little-endian), the byte 16 (the length of what
  follows), the publisher's 16-byte GID;
- every node, publisher, subscription, service and client declares a liveliness token
  ``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>``
  and, for a topic, ``/<topic>/<DDS type>/<hash>/<QoS>``, names with ``/`` written ``%``.
  ``ros2 topic list`` is made from these tokens.

Everything here is a pure function or a frozen value, so it has property tests.
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from enum import IntEnum

import xxhash

from busarm.errors import ConfigError, ProtocolError

__all__ = [
    "ADMIN_SPACE",
    "ATTACHMENT_SIZE",
    "ENTITY_KINDS",
    "GID_SIZE",
    "LATCHED",
    "RELIABLE",
    "ROSOUT",
    "SENSOR_DATA",
    "TYPE_HASH_NOT_SUPPORTED",
    "Attachment",
    "Durability",
    "Entity",
    "History",
    "Qos",
    "Reliability",
    "TopicKey",
    "check_ros_type",
    "check_topic",
    "check_type_hash",
    "dds_type_name",
    "gid_of",
    "mangle",
    "parse_token",
    "parse_topic_key",
    "ros_type_name",
    "topic_key",
    "topic_key_any_type",
    "unmangle",
]


ADMIN_SPACE = "@ros2_lv"
ATTACHMENT_SIZE = 33
GID_SIZE = 16
TYPE_HASH_NOT_SUPPORTED = "TypeHashNotSupported"
"""What Humble's rmw_zenoh puts where the type hash goes."""

_ATTACHMENT = struct.Struct("<qqB16s")
_ROS_TYPE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)/(msg|srv)/([A-Za-z][A-Za-z0-9_]*)$")
_TOPIC = re.compile(r"^/?[A-Za-z~{][A-Za-z0-9_/{}~]*$")
_HASH = re.compile(r"^(RIHS01_[0-9a-f]{64}|TypeHashNotSupported)$")

ENTITY_KINDS = ("NN", "MP", "MS", "SS", "SC")
"""Node, publisher, subscription, service server, service client."""


class Reliability(IntEnum):
    """rmw's reliability policy values, as they appear in a token's QoS."""

    RELIABLE = 1
    BEST_EFFORT = 2


class Durability(IntEnum):
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class History(IntEnum):
    KEEP_LAST = 1
    KEEP_ALL = 2


@dataclass(frozen=True)
class Qos:
    """The QoS a token announces (rmw_zenoh's defaults: reliable, volatile, keep last 42,
    no lifespan)."""

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 42
    lifespan_ns: int = 0
    """How long a sample stays valid; 0: for ever (rmw's default)."""

    def key(self) -> str:
        """The token's QoS field: each value that differs from the default, else empty.

        Deadline and liveliness lease are always the defaults here (infinite), so their
        fields are empty: ``rel:dur:hist,depth:,:lifespan_s,lifespan_ns:,,``."""
        default = Qos()
        rel = "" if self.reliability == default.reliability else str(int(self.reliability))
        dur = "" if self.durability == default.durability else str(int(self.durability))
        hist = "" if self.history == default.history else str(int(self.history))
        depth = "" if self.depth == default.depth else str(self.depth)
        # rmw_zenoh writes the seconds and the nanoseconds apart, each only if not 0.
        sec, nsec = divmod(self.lifespan_ns, 1_000_000_000)
        life = f"{sec or ''},{nsec or ''}"
        return f"{rel}:{dur}:{hist},{depth}:,:{life}:,,"

    @classmethod
    def parse(cls, text: str) -> Qos:
        """The QoS in a token's field; ProtocolError when it is not one."""
        parts = text.split(":")
        if len(parts) != 6 or len(parts[2].split(",")) != 2 \
                or len(parts[4].split(",")) != 2:
            raise ProtocolError(f"not an rmw_zenoh QoS field: {text!r}")
        hist, depth = parts[2].split(",")
        sec, nsec = parts[4].split(",")
        try:
            return cls(reliability=Reliability(int(parts[0])) if parts[0] else cls.reliability,
                       durability=Durability(int(parts[1])) if parts[1] else cls.durability,
                       history=History(int(hist)) if hist else cls.history,
                       depth=int(depth) if depth else cls.depth,
                       lifespan_ns=int(sec or 0) * 1_000_000_000 + int(nsec or 0))
        except ValueError as exc:
            raise ProtocolError(f"bad value in the QoS field {text!r}: {exc}") from exc


RELIABLE = Qos()
LATCHED = Qos(durability=Durability.TRANSIENT_LOCAL, depth=1)
"""``/robot_description`` and ``/map``: a late subscriber still gets the last one."""
ROSOUT = Qos(durability=Durability.TRANSIENT_LOCAL, depth=1000, lifespan_ns=10_000_000_000)
"""``/rosout``, as rcl's logging publishes it (rcl_qos_profile_rosout_default): reliable,
transient local, keep last 1000, a lifespan of 10 s; a late ``ros2 topic echo`` or
rqt_console sees the lines logged before it joined."""
SENSOR_DATA = Qos(reliability=Reliability.BEST_EFFORT, depth=5)
"""Camera frames and scans: a late frame is worth less than the next one."""


def check_ros_type(ros_type: str) -> tuple[str, str, str]:
    """``pkg/msg/Name`` split in three; ConfigError for anything else."""
    match = _ROS_TYPE.match(ros_type)
    if match is None:
        raise ConfigError(f"not a ROS 2 type name: {ros_type!r} (e.g. sensor_msgs/msg/JointState)")
    return match.group(1), match.group(2), match.group(3)


def dds_type_name(ros_type: str) -> str:
    """``sensor_msgs/msg/JointState`` -> ``sensor_msgs::msg::dds_::JointState_``."""
    package, kind, name = check_ros_type(ros_type)
    return f"{package}::{kind}::dds_::{name}_"


def ros_type_name(dds_name: str) -> str:
    """The inverse of ``dds_type_name``; ProtocolError if ``dds_name`` is not one."""
    parts = dds_name.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise ProtocolError(f"not a DDS-mangled ROS 2 type name: {dds_name!r}")
    ros_type = f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"
    if _ROS_TYPE.match(ros_type) is None:
        raise ProtocolError(f"not a DDS-mangled ROS 2 type name: {dds_name!r}")
    return ros_type


def check_topic(topic: str) -> str:
    """A ROS 2 topic name, returned with its leading ``/``; ConfigError if not one."""
    if not isinstance(topic, str) or _TOPIC.match(topic) is None or "//" in topic \
            or topic.rstrip("/") != topic or topic in ("", "/"):
        raise ConfigError(f"not a ROS 2 topic name: {topic!r} (e.g. /joint_states)")
    return topic if topic.startswith("/") else "/" + topic


def check_type_hash(type_hash: str) -> str:
    if _HASH.match(type_hash) is None:
        raise ConfigError(f"not a ROS 2 type hash: {type_hash!r} (RIHS01_ and 64 hex "
                          f"digits, or {TYPE_HASH_NOT_SUPPORTED})")
    return type_hash


def topic_key(domain_id: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The key expression a message of ``ros_type`` on ``topic`` is published on."""
    _check_domain(domain_id)
    name = check_topic(topic)[1:]
    return f"{domain_id}/{name}/{dds_type_name(ros_type)}/{check_type_hash(type_hash)}"


def topic_key_any_type(domain_id: int, topic: str) -> str:
    """What to subscribe to for ``topic`` whatever type and hash it is published with
    (so that a wrong type or hash is seen, and refused, rather than never heard)."""
    _check_domain(domain_id)
    return f"{domain_id}/{check_topic(topic)[1:]}/*/*"


@dataclass(frozen=True)
class TopicKey:
    """A published message's key expression, taken apart."""

    domain_id: int
    topic: str
    ros_type: str
    type_hash: str


def parse_topic_key(key: str) -> TopicKey:
    """Take ``topic_key``'s result apart; ProtocolError when ``key`` is not one."""
    parts = key.split("/")
    if len(parts) < 4 or not parts[0].isdigit():
        raise ProtocolError(f"not an rmw_zenoh topic key: {key!r}")
    ros_type = ros_type_name(parts[-2])
    if _HASH.match(parts[-1]) is None:
        raise ProtocolError(f"not a ROS 2 type hash in {key!r}: {parts[-1]!r}")
    return TopicKey(int(parts[0]), "/" + "/".join(parts[1:-2]), ros_type, parts[-1])


# ------------------------------------------------------------------ attachment


@dataclass(frozen=True)
class Attachment:
    """What rides beside every rmw_zenoh message."""

    sequence_number: int
    source_timestamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        if len(self.gid) != GID_SIZE:
            raise ConfigError(f"a GID is {GID_SIZE} bytes, got {len(self.gid)}")
        return _ATTACHMENT.pack(self.sequence_number, self.source_timestamp_ns, GID_SIZE,
                                self.gid)

    @classmethod
    def decode(cls, data: bytes) -> Attachment:
        """ProtocolError unless ``data`` is a 33-byte attachment with a 16-byte GID."""
        if len(data) != ATTACHMENT_SIZE:
            raise ProtocolError(f"an rmw_zenoh attachment is {ATTACHMENT_SIZE} bytes, got "
                                f"{len(data)}")
        seq, stamp, size, gid = _ATTACHMENT.unpack(data)
        if size != GID_SIZE:
            raise ProtocolError(f"the attachment's GID length byte is {size}, not {GID_SIZE}")
        return cls(seq, stamp, gid)


# ------------------------------------------------------------------ liveliness


def mangle(name: str) -> str:
    """A name as a token has it: ``/`` written ``%`` (the empty namespace is ``%``)."""
    return name.replace("/", "%") if name else "%"


def unmangle(name: str) -> str:
    return name.replace("%", "/")


@dataclass(frozen=True)
class Entity:
    """A node or one of its endpoints, as its liveliness token describes it."""

    domain_id: int
    zid: str
    node_id: int
    entity_id: int
    kind: str
    node: str
    namespace: str = "/"
    enclave: str = "/"
    topic: str | None = None
    ros_type: str | None = None
    type_hash: str | None = None
    qos: Qos | None = None

    def token(self) -> str:
        """The liveliness token's key expression."""
        _check_domain(self.domain_id)
        if self.kind not in ENTITY_KINDS:
            raise ConfigError(f"entity kind must be one of {', '.join(ENTITY_KINDS)}, got "
                              f"{self.kind!r}")
        head = (f"{ADMIN_SPACE}/{self.domain_id}/{self.zid}/{self.node_id}/{self.entity_id}/"
                f"{self.kind}/{mangle(self.enclave)}/{mangle(self.namespace)}/{self.node}")
        if self.kind == "NN":
            return head
        if self.topic is None or self.ros_type is None or self.type_hash is None:
            raise ConfigError(f"a {self.kind} token needs a topic, a type and a type hash")
        qos = self.qos if self.qos is not None else Qos()
        return (f"{head}/{mangle(check_topic(self.topic))}/{dds_type_name(self.ros_type)}/"
                f"{check_type_hash(self.type_hash)}/{qos.key()}")


def gid_of(token: str) -> bytes:
    """An entity's 16-byte GID: the XXH3-128 of its token, low half first (little-endian),
    as rmw_zenoh computes it, so a ROS 2 graph and our attachments agree on it."""
    return xxhash.xxh3_128_intdigest(token.encode()).to_bytes(GID_SIZE, "little")


def parse_token(key: str) -> Entity:
    """The entity a liveliness token describes; ProtocolError when ``key`` is not one."""
    parts = key.split("/")
    if len(parts) not in (9, 13) or parts[0] != ADMIN_SPACE or parts[5] not in ENTITY_KINDS:
        raise ProtocolError(f"not an rmw_zenoh liveliness token: {key!r}")
    if not (parts[1].isdigit() and parts[3].isdigit() and parts[4].isdigit()):
        raise ProtocolError(f"not an rmw_zenoh liveliness token (ids): {key!r}")
    entity = Entity(int(parts[1]), parts[2], int(parts[3]), int(parts[4]), parts[5],
                    node=parts[8], namespace=unmangle(parts[7]), enclave=unmangle(parts[6]))
    if len(parts) == 9:
        return entity
    if _HASH.match(parts[11]) is None:
        raise ProtocolError(f"not a ROS 2 type hash in token {key!r}")
    return Entity(entity.domain_id, entity.zid, entity.node_id, entity.entity_id,
                  entity.kind, entity.node, entity.namespace, entity.enclave,
                  topic=unmangle(parts[9]), ros_type=ros_type_name(parts[10]),
                  type_hash=parts[11], qos=Qos.parse(parts[12]))


def _check_domain(domain_id: int) -> None:
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) \
            or not 0 <= domain_id <= 232:
        raise ConfigError(f"ROS domain id must be 0..232, got {domain_id!r}")
