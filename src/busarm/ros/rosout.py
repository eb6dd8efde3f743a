"""The bridge's log on /rosout (rcl_interfaces/Log), where ROS 2 tools show a node's log:
a refused command says why there, as well as in the bridge's own terminal.

Published with rcl's logging QoS (``ROSOUT``: reliable, transient local, keep last 1000,
lifespan 10 s), from a cache as rmw_zenoh keeps one: a ``ros2 topic echo /rosout`` or
rqt_console started later still gets the last 1000 lines."""

from __future__ import annotations

import logging
import threading
import time

from busarm.protocol.rmw_zenoh import ROSOUT
from busarm.ros.messages import ROSOUT_LOG, message_class, stamp
from busarm.ros.node import RosNode, RosPublisher

__all__ = [
    "RosoutHandler",
]


class RosoutHandler(logging.Handler):
    """Publishes each record of the loggers it is added to (warnings and up, by default)."""

    def __init__(self, node: RosNode, level: int = logging.WARNING) -> None:
        super().__init__(level)
        self.node_name = node.name
        self.publisher: RosPublisher = node.publisher("/rosout", ROSOUT_LOG, ROSOUT)
        self._inside = threading.local()

    def emit(self, record: logging.LogRecord) -> None:
        if getattr(self._inside, "busy", False):
            return  # a record about publishing this one: never loop
        self._inside.busy = True
        try:
            # rcl's levels are Python's: 10 debug, 20 info, 30 warn, 40 error, 50 fatal.
            self.publisher.publish(message_class(ROSOUT_LOG)(
                stamp=stamp(time.time()), level=min(max(record.levelno, 10), 50),
                name=self.node_name, msg=self.format(record), file=record.pathname,
                function=record.funcName, line=record.lineno))
        except Exception:  # a log line must never take the bridge down
            self.handleError(record)
        finally:
            self._inside.busy = False
