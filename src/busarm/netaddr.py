"""Network addresses as the servers and links judge them: one rule for "this computer
only" (loopback), which decides whether a token is needed; and a TCP port to listen on,
had (or refused) before anything else starts: the servers that show a robot (the
dashboard, the Foxglove view) check it before the robot is opened, so that a port in use
costs one clear error and nothing more."""

from __future__ import annotations

import errno
import ipaddress
import socket

from busarm.errors import ConfigError

__all__ = [
    "bind_socket",
    "check_can_listen",
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

def bind_socket(host: str, port: int, option: str = "--http-port") -> socket.socket:
    """A listening TCP socket on ``host``:``port``; ConfigError if it cannot be had,
    naming ``option``, the option the port was given with."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as exc:
        sock.close()
        why = (f"is in use (give another {option}, or 0 for any free port)"
               if exc.errno == errno.EADDRINUSE else f"cannot be used: {exc.strerror or exc}")
        raise ConfigError(f"{host}:{port} {why}") from None
    sock.listen(64)
    return sock


def check_can_listen(host: str, port: int, option: str) -> None:
    """ConfigError now when ``host``:``port`` cannot be listened on (in use, or not an
    address of this computer); port 0 is always free. For a server that binds its own
    socket later (foxglove-sdk's)."""
    bind_socket(host, port, option).close()
