"""A ROS 2 node on a Zenoh session, as rmw_zenoh makes one (no ROS installed).

``RosNode`` declares its liveliness token (so ``ros2 node list`` sees it), and makes
publishers and subscriptions that declare theirs (``ros2 topic list``), publish CDR with
rmw_zenoh's attachment on rmw_zenoh's key expressions, and take in only what is what it
says: an incoming sample whose type or type hash is not the subscription's, whose
attachment is malformed, or whose CDR does not parse is dropped and counted, with the
reason logged, and never reaches the callback.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from busarm.errors import BusArmError, ProtocolError
from busarm.protocol.rmw_zenoh import (
    RELIABLE,
    TYPE_HASH_NOT_SUPPORTED,
    Attachment,
    Durability,
    Entity,
    History,
    Qos,
    Reliability,
    gid_of,
    parse_topic_key,
    topic_key,
    topic_key_any_type,
)
from busarm.ros.messages import decode, encode, ros_type

if TYPE_CHECKING:
    import zenoh
    import zenoh.ext

__all__ = [
    "DEFAULT_NODE",
    "MISS_HEARTBEAT_S",
    "Drops",
    "Received",
    "RosNode",
    "RosPublisher",
    "RosSubscription",
]


log = logging.getLogger(__name__)

DEFAULT_NODE = "busarm"
MISS_HEARTBEAT_S = 0.5
"""How often a reliable transient-local publisher tells its last sequence number, when it
changed (rmw_zenoh's sporadic heartbeat)."""


@dataclass(frozen=True)
class Received:
    """Where an accepted message came from."""

    topic: str
    sequence_number: int
    source_timestamp_ns: int
    gid: bytes
    received_ns: int


@dataclass
class Drops:
    """Samples a subscription refused, by reason (the last one kept in words)."""

    count: int = 0
    by_reason: dict[str, int] = field(default_factory=dict)
    last: str = ""

    def add(self, reason: str, detail: str) -> None:
        self.count += 1
        self.by_reason[reason] = self.by_reason.get(reason, 0) + 1
        self.last = detail


class RosPublisher:
    """One topic's publisher; ``publish(message)`` (a rosbags message of its type)."""

    def __init__(self, node: RosNode, topic: str, type_name: str, qos: Qos) -> None:
        import zenoh

        self.topic = topic
        self.type = ros_type(type_name)
        self.key = topic_key(node.domain_id, topic, type_name, self.type.type_hash)
        self.entity = node.entity("MP", topic, type_name, qos)
        self.gid = gid_of(self.entity.token())
        self._sequence = itertools.count(1)
        self._lock = threading.Lock()
        # Never block the robot's loops on a slow subscriber: drop instead, except for
        # reliable keep-all, which blocks as rmw_zenoh's does (a publisher that asks for
        # every message to arrive); express: no batching, the least latency.
        keep_all = (qos.reliability == Reliability.RELIABLE
                    and qos.history == History.KEEP_ALL)
        options: dict[str, Any] = {
            "express": True,
            "congestion_control": (zenoh.CongestionControl.BLOCK if keep_all
                                   else zenoh.CongestionControl.DROP),
            "reliability": (zenoh.Reliability.BEST_EFFORT
                            if qos.reliability == Reliability.BEST_EFFORT
                            else zenoh.Reliability.RELIABLE)}
        self._publisher: zenoh.Publisher | zenoh.ext.AdvancedPublisher
        if qos.durability == Durability.TRANSIENT_LOCAL:
            self._publisher = _transient_local_publisher(node.session, self.key, qos, options)
        else:
            self._publisher = node.session.declare_publisher(self.key, **options)
        self._token = node.session.liveliness().declare_token(self.entity.token())
        self._closed = False

    @property
    def matched(self) -> bool:
        """Whether anyone subscribes (else a costly message need not be made at all)."""
        import zenoh

        if not isinstance(self._publisher, zenoh.Publisher):
            return True  # a transient-local one caches for late joiners: always publish
        return bool(self._publisher.matching_status)

    def publish(self, message: Any) -> int:
        """Publish; returns the message's sequence number."""
        return self.publish_cdr(encode(message, self.type.name))

    def publish_cdr(self, payload: bytes) -> int:
        with self._lock:
            seq = next(self._sequence)
            attachment = Attachment(seq, time.time_ns(), self.gid).encode()
            self._publisher.put(payload, attachment=attachment)
        return seq

    def close(self) -> None:
        """Undeclare it (again: nothing)."""
        if self._closed:
            return
        self._closed = True
        self._token.undeclare()
        self._publisher.undeclare()  # type: ignore[no-untyped-call]  # zenoh.ext's stub


def _transient_local_publisher(session: zenoh.Session, key: str, qos: Qos,
                               options: dict[str, Any]) -> zenoh.ext.AdvancedPublisher:
    """A publisher as rmw_zenoh makes a transient-local one: a cache of the last ``depth``
    samples that late subscribers query, the publisher detectable (so a subscriber that
    came first asks it when it appears), and, when reliable, sporadic heartbeats so a
    subscriber notices a missed sample and fetches it from the cache."""
    import zenoh.ext

    miss = (zenoh.ext.MissDetectionConfig(heartbeat=None,
                                          sporadic_heartbeat=MISS_HEARTBEAT_S)
            if qos.reliability == Reliability.RELIABLE else None)
    return zenoh.ext.declare_advanced_publisher(
        session, key, cache=zenoh.ext.CacheConfig(max_samples=qos.depth),
        publisher_detection=True, sample_miss_detection=miss, **options)


class RosSubscription:
    """One topic's subscription: ``on_message(message, received)`` for each good sample,
    called on Zenoh's thread (keep it short: hand long work to a thread of your own)."""

    def __init__(self, node: RosNode, topic: str, type_name: str,
                 on_message: Callable[[Any, Received], None], qos: Qos,
                 *, decoded: bool = True) -> None:
        self.topic = topic
        self.decoded = decoded
        """False: ``on_message`` gets the CDR bytes, checked for type, hash and
        attachment but not parsed (a recorder's way: it keeps them as they came)."""
        self.type = ros_type(type_name)
        self.entity = node.entity("MS", topic, type_name, qos)
        self.drops = Drops()
        self.accepted = 0
        self._on_message = on_message
        # Every type and hash on the topic: a wrong one is heard, refused and counted.
        key = topic_key_any_type(node.domain_id, topic)
        self._subscriber: zenoh.Subscriber[None] | zenoh.ext.AdvancedSubscriber[None]
        if qos.durability == Durability.TRANSIENT_LOCAL:
            import zenoh.ext

            # As rmw_zenoh's transient-local subscription: ask the publishers' caches for
            # what they kept (up to our depth), now and from any publisher that joins later.
            self._subscriber = zenoh.ext.declare_advanced_subscriber(
                node.session, key, self._on_sample, history=zenoh.ext.HistoryConfig(
                    detect_late_publishers=True, max_samples=qos.depth))
        else:
            self._subscriber = node.session.declare_subscriber(key, self._on_sample)
        self._token = node.session.liveliness().declare_token(self.entity.token())
        self._closed = False

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            message, received = self._take(sample)
        except ProtocolError:
            return  # counted and logged where it was found
        except Exception as exc:  # never let a bad sample kill Zenoh's callback thread
            self._drop("error", f"{self.topic}: {type(exc).__name__}: {exc}")
            return
        self.accepted += 1
        try:
            self._on_message(message, received)
        except BusArmError as exc:
            self._drop("refused", f"{self.topic}: {exc}")
        except Exception:
            log.exception("%s: the handler failed", self.topic)

    def _take(self, sample: zenoh.Sample) -> tuple[Any, Received]:
        key = str(sample.key_expr)
        try:
            got = parse_topic_key(key)
        except ProtocolError as exc:
            self._drop("key", f"{self.topic}: {exc}")
            raise
        if got.ros_type != self.type.name or got.type_hash not in (self.type.type_hash,
                                                                    TYPE_HASH_NOT_SUPPORTED):
            why = (f"{self.topic}: a {got.ros_type} ({got.type_hash[:20]}...) where "
                   f"{self.type.name} ({self.type.type_hash[:20]}...) is expected")
            self._drop("type", why)
            raise ProtocolError(why)
        raw = sample.attachment
        try:
            attachment = Attachment.decode(raw.to_bytes() if raw is not None else b"")
            payload = bytes(sample.payload.to_bytes())
            message = decode(payload, self.type.name) if self.decoded else payload
        except ProtocolError as exc:
            self._drop("attachment" if "attachment" in str(exc) or "GID" in str(exc)
                       else "payload", f"{self.topic}: {exc}")
            raise
        return message, Received(self.topic, attachment.sequence_number,
                                 attachment.source_timestamp_ns, attachment.gid,
                                 time.time_ns())

    def _drop(self, reason: str, detail: str) -> None:
        self.drops.add(reason, detail)
        log.warning("dropped: %s", detail)

    def close(self) -> None:
        """Undeclare it (again: nothing)."""
        if self._closed:
            return
        self._closed = True
        self._token.undeclare()
        self._subscriber.undeclare()  # type: ignore[no-untyped-call]  # zenoh.ext's stub


class RosNode:
    """A node named ``name`` in ``namespace`` on domain ``domain_id``, on ``session``
    (which it does not own: close the session after the node)."""

    def __init__(self, session: zenoh.Session, name: str = DEFAULT_NODE, *,
                 namespace: str = "/", domain_id: int = 0) -> None:
        self.session = session
        self.name = name
        self.namespace = namespace
        self.domain_id = domain_id
        self.zid = str(session.zid())
        self._ids = itertools.count(1)
        self._node_entity = Entity(domain_id, self.zid, 0, 0, "NN", name, namespace)
        self._token = session.liveliness().declare_token(self._node_entity.token())
        self._endpoints: list[RosPublisher | RosSubscription] = []

    def entity(self, kind: str, topic: str, type_name: str, qos: Qos) -> Entity:
        return Entity(self.domain_id, self.zid, 0, next(self._ids), kind, self.name,
                      self.namespace, topic=topic, ros_type=type_name,
                      type_hash=ros_type(type_name).type_hash, qos=qos)

    def publisher(self, topic: str, type_name: str, qos: Qos = RELIABLE) -> RosPublisher:
        pub = RosPublisher(self, topic, type_name, qos)
        self._endpoints.append(pub)
        return pub

    def subscribe(self, topic: str, type_name: str,
                  on_message: Callable[[Any, Received], None],
                  qos: Qos = RELIABLE, *, decoded: bool = True) -> RosSubscription:
        sub = RosSubscription(self, topic, type_name, on_message, qos, decoded=decoded)
        self._endpoints.append(sub)
        return sub

    def close(self) -> None:
        for endpoint in reversed(self._endpoints):
            endpoint.close()
        self._endpoints.clear()
        self._token.undeclare()
