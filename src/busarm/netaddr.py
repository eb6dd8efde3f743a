"""Network addresses as the servers and links judge them: one rule for "this computer
only" (loopback), which decides whether a token is needed."""

from __future__ import annotations

import ipaddress

__all__ = [
    "is_loopback",
]


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address, maybe in [brackets], or ``localhost``) is this
    computer only."""
    bare = host.strip("[]")
    if bare == "localhost":
        return True
    try:
        return ipaddress.ip_address(bare).is_loopback
    except ValueError:
        return False
