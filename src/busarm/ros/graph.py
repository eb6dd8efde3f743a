"""The ROS 2 graph seen from a Zenoh session: who publishes and subscribes what.

rmw_zenoh keeps no registry: each entity's liveliness token says what it is, and a
``liveliness().get`` on ``@ros2_lv/<domain>/**`` gathers them (as every ROS 2 node does
when it starts). ``echo_messages`` finds a topic's type the same way, then prints what
comes, decoded.
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from busarm.errors import BusTimeoutError, ConfigError, ProtocolError
from busarm.protocol.rmw_zenoh import ADMIN_SPACE, Entity, check_topic, parse_token
from busarm.ros.messages import ros_type
from busarm.ros.node import Received, RosNode

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "GRAPH_WAIT_S",
    "Graph",
    "Topic",
    "echo_messages",
    "plain",
    "read_graph",
]


GRAPH_WAIT_S = 1.0
"""How long to gather tokens (every peer's, through the links this session has)."""


@dataclass
class Topic:
    name: str
    ros_type: str
    type_hash: str
    publishers: int = 0
    subscribers: int = 0


@dataclass
class Graph:
    nodes: list[str] = field(default_factory=list)
    topics: list[Topic] = field(default_factory=list)
    entities: list[Entity] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"nodes": self.nodes,
                "topics": [vars(t) for t in self.topics]}

    def topic(self, name: str) -> Topic | None:
        return next((t for t in self.topics if t.name == name), None)


def read_graph(session: zenoh.Session, domain_id: int, wait_s: float = GRAPH_WAIT_S,
               settle_s: float = 0.3) -> Graph:
    """Every entity on ``domain_id`` the session can see (waiting up to ``settle_s``
    for links to peers to come up, then up to ``wait_s`` for the answers)."""
    time.sleep(settle_s)  # a new session's links come up in the first milliseconds
    entities = []
    for reply in session.liveliness().get(f"{ADMIN_SPACE}/{domain_id}/**", timeout=wait_s):
        if reply.ok is None:
            continue
        try:
            entities.append(parse_token(str(reply.ok.key_expr)))
        except ProtocolError:
            continue  # another tool's token: not ours to judge
    graph = Graph(entities=entities)
    by_name: dict[tuple[str, str], Topic] = {}
    for e in entities:
        if e.kind == "NN":
            graph.nodes.append(f"{e.namespace.rstrip('/')}/{e.node}")
            continue
        if e.topic is None or e.ros_type is None or e.type_hash is None:
            continue
        topic = by_name.setdefault((e.topic, e.ros_type),
                                   Topic(e.topic, e.ros_type, e.type_hash))
        if e.kind == "MP":
            topic.publishers += 1
        elif e.kind == "MS":
            topic.subscribers += 1
    graph.topics = sorted(by_name.values(), key=lambda t: t.name)
    graph.nodes.sort()
    return graph


def plain(value: Any) -> Any:
    """A decoded message as JSON-able values (arrays longer than 16 summarised)."""
    if hasattr(value, "__dataclass_fields__"):
        return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__
                if not k.startswith("__") and not k.isupper()}  # not its constants
    if isinstance(value, np.ndarray):
        if value.size > 16:
            return f"<{value.size} values of {value.dtype}>"
        return value.tolist()
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value


def echo_messages(session: zenoh.Session, domain_id: int, topic: str, count: int,
                  timeout_s: float) -> Iterator[str]:
    """Each of the next ``count`` messages on ``topic`` as a JSON line; BusTimeoutError
    when none comes for ``timeout_s``."""
    name = check_topic(topic)
    found = read_graph(session, domain_id).topic(name)
    if found is None:
        raise ConfigError(f"nobody publishes {name} on domain {domain_id}")
    ros_type(found.ros_type)  # one this typestore knows
    inbox: queue.Queue[tuple[Any, Received]] = queue.Queue()
    node = RosNode(session, "busarm_echo", domain_id=domain_id)
    try:
        node.subscribe(name, found.ros_type, lambda msg, rec: inbox.put((msg, rec)))
        for _ in range(count):
            try:
                msg, _rec = inbox.get(timeout=timeout_s)
            except queue.Empty:
                raise BusTimeoutError(f"no message on {name} in {timeout_s:g} s") from None
            yield json.dumps(plain(msg))
    finally:
        node.close()
