"""Recording what is published on the session into an MCAP file, as rosbag2 writes one
(profile ``ros2``, ``ros2msg`` schemas, ``cdr`` messages), so that ROS 2 tools
(``ros2 bag play``, Foxglove) replay it. Messages are kept as they came: the CDR bytes,
stamped with when they arrived (log time) and when they were sent (the attachment's
source timestamp: publish time). The file is written under a temporary name and renamed
when it is complete."""

from __future__ import annotations

import os
import threading
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

from mcap.writer import CompressionType, Writer

from busarm.errors import ConfigError
from busarm.protocol.rmw_zenoh import check_topic
from busarm.ros.graph import read_graph
from busarm.ros.messages import TYPESTORE, ros_type
from busarm.ros.node import Received, RosNode

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "McapRecorder",
]


class McapRecorder:
    """Records ``topics`` (default: every topic with a publisher on the domain, as found
    when it starts) until ``close()``."""

    def __init__(self, session: zenoh.Session, path: Path, *, domain_id: int = 0,
                 topics: list[str] | None = None) -> None:
        if not Path(path).parent.is_dir():
            raise ConfigError(f"cannot record into {path}: its folder {Path(path).parent} "
                              "does not exist")
        graph = read_graph(session, domain_id)
        wanted = [check_topic(t) for t in topics] if topics else [
            t.name for t in graph.topics if t.publishers]
        found = {t.name: t for t in graph.topics}
        missing = [t for t in wanted if t not in found]
        if missing:
            raise ConfigError(f"nobody publishes {', '.join(missing)} on domain {domain_id}")
        if not wanted:
            raise ConfigError(f"nothing is published on domain {domain_id} to record")
        self.path = Path(path)
        self.topics = wanted
        self.counts: Counter[str] = Counter()
        self._lock = threading.Lock()
        self._partial = self.path.with_name(f".{self.path.name}.partial")
        self._file = open(self._partial, "wb")  # noqa: SIM115 (closed in close())
        self._writer: Writer | None = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="busarm")
        writer = self._writer
        self._channels: dict[str, int] = {}
        self._node = RosNode(session, "busarm_recorder", domain_id=domain_id)
        for name in wanted:
            type_name = found[name].ros_type
            ros_type(type_name)  # one the typestore knows
            text, _ = TYPESTORE.generate_msgdef(type_name, ros_version=2)
            schema = writer.register_schema(type_name, "ros2msg", text.encode())
            self._channels[name] = writer.register_channel(name, "cdr", schema)
            self._node.subscribe(name, type_name, self._keep, decoded=False)

    def _keep(self, payload: bytes, received: Received) -> None:
        with self._lock:
            if self._writer is None:
                return
            self._writer.add_message(self._channels[received.topic], received.received_ns,
                                     payload, received.source_timestamp_ns,
                                     received.sequence_number & 0xFFFFFFFF)
            self.counts[received.topic] += 1

    def close(self) -> Path:
        """Stop recording and finish the file; returns its path."""
        self._node.close()
        with self._lock:
            writer, self._writer = self._writer, None
            if writer is not None:
                writer.finish()
            self._file.close()
        os.replace(self._partial, self.path)
        return self.path
