"""The ``zenoh`` servo port: the servos of a robot served on another computer.

The robot's computer serves its LX line (``busarm ros bridge``: busarm.robot.remote and
busarm.bus.zenoh_link.BusServer), each request checked there before it reaches the line
(the joints' limits, the halt); here a ``ZenohTransport`` carries the LX driver's bytes
over the link, the link's round trip added to every reply's deadline. When this side's
link goes, the robot's side stops every servo where it is.
"""

from __future__ import annotations

from typing import Any

from busarm.bus.driver import ServoBus
from busarm.errors import ConfigError

__all__ = ["remote_servo_port"]


def remote_servo_port(transport: Any, **options: Any) -> ServoBus:
    """The LX driver on a served robot's link (a ``ZenohTransport``, e.g. from
    ``zenoh://HOST``); ``options`` as ``ServoBus``'s (echo, retries, timeout_margin_s)."""
    from busarm.bus.zenoh_link import ZenohTransport  # its link, imported when chosen

    if not isinstance(transport, ZenohTransport):
        raise ConfigError(f"the zenoh servo port needs a Zenoh link (zenoh://HOST), not "
                          f"{getattr(transport, 'name', type(transport).__name__)}")
    return ServoBus(transport, **options)
