"""A Zenoh session made the busarm way: peers on endpoints named, nothing found by itself.

Multicast scouting is off (nothing is sent to other addresses than those given); peers
learn of each other only through the sessions they open (gossip over those links). A
session listens on 127.0.0.1 unless told otherwise, and a listener off loopback needs a
token: Zenoh's user-password authentication, the user ``busarm``, the token the password,
which every peer must then give too (``--token``, or ``BUSARM_TOKEN``).

Endpoints are Zenoh locators: ``tcp/127.0.0.1:7447``, ``tcp/[::1]:7447``,
``tcp/robot.local:7447``. ``zenoh`` (the ``busarm[ros]`` extra) is imported here only.
"""

from __future__ import annotations

import json
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from busarm.errors import ConfigError, TransportError
from busarm.netaddr import is_loopback

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "DEFAULT_ENDPOINT",
    "DEFAULT_PORT",
    "LEASE_MS",
    "TOKEN_ENV",
    "TOKEN_USER",
    "endpoint_host",
    "is_loopback",
    "need_zenoh",
    "open_session",
    "session_config",
]


DEFAULT_PORT = 7447
"""Zenoh's port, and rmw_zenoh's router's."""
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
TOKEN_USER = "busarm"
TOKEN_ENV = "BUSARM_TOKEN"
LEASE_MS = 250
"""How long peers believe this session alive when they hear nothing from it (Zenoh's
default is 10 s): a robot learns that a busarm driving it is gone (its link silently
dropped) within about 0.2 s, and stops. Keep-alives go every quarter of it."""


def need_zenoh() -> None:
    """ConfigError saying what to install when the ``busarm[ros]`` extra is missing."""
    try:
        import zenoh  # noqa: F401
    except ImportError as exc:
        raise ConfigError("this needs Zenoh: pip install 'busarm[ros]' (eclipse-zenoh, "
                          "rosbags)") from exc


def endpoint_host(endpoint: str) -> tuple[str, int]:
    """(host, port) of a ``tcp/HOST:PORT`` or ``udp/HOST:PORT`` locator; ConfigError else."""
    proto, sep, address = endpoint.partition("/")
    host, colon, port_text = address.rpartition(":")
    if not sep or proto not in ("tcp", "udp", "quic", "tls") or not colon or not host:
        raise ConfigError(f"endpoint {endpoint!r}: give tcp/HOST:PORT, e.g. {DEFAULT_ENDPOINT}")
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 1 <= port <= 65535:
        raise ConfigError(f"endpoint {endpoint!r}: port {port_text!r}; allowed: 1..65535")
    return host.strip("[]"), port


def session_config(*, listen: Sequence[str] = (), connect: Sequence[str] = (),
                   token: str | None = None, users_file: Path | None = None) -> zenoh.Config:
    """The session's Zenoh config (checked: each endpoint well formed, a listener off
    loopback only with a token; with a token, ``users_file`` is the file of users a
    listener checks peers against)."""
    import zenoh

    for endpoint in [*listen, *connect]:
        endpoint_host(endpoint)
    exposed = [e for e in listen if not is_loopback(endpoint_host(e)[0])]
    if exposed and not token:
        raise ConfigError(f"listening on {', '.join(exposed)} (off this computer) needs a "
                          f"token: --token SECRET or {TOKEN_ENV}; every peer gives the same")
    if token and any(c in token for c in ":\n\r"):
        raise ConfigError("a token cannot contain ':' or a line break")
    transport: dict[str, object] = {"link": {"tx": {"lease": LEASE_MS, "keep_alive": 4}}}
    if token:
        transport["auth"] = {"usrpwd": {"user": TOKEN_USER, "password": token,
                                        "dictionary_file": str(users_file)}}
    config = {
        "mode": "peer",
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": True}},
        "listen": {"endpoints": list(listen)},
        "connect": {"endpoints": list(connect)},
        "transport": transport,
    }
    made: zenoh.Config = zenoh.Config.from_json5(json.dumps(config))
    return made


def open_session(*, listen: Sequence[str] = (), connect: Sequence[str] = (),
                 token: str | None = None) -> zenoh.Session:
    """Open a session (see the module docstring); TransportError when an endpoint cannot
    be listened on, with what to do about it."""
    need_zenoh()
    import zenoh

    token = token or os.environ.get(TOKEN_ENV) or None
    with tempfile.TemporaryDirectory(prefix="busarm-zenoh-") as folder:
        # The users a listener checks peers against (one: busarm), read while the
        # session opens; private to this user, and gone after.
        users = Path(folder) / "users.txt"
        config = session_config(listen=listen, connect=connect, token=token, users_file=users)
        if token:
            fd = os.open(users, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "w") as f:
                f.write(f"{TOKEN_USER}:{token}\n")
        try:
            return zenoh.open(config)
        except zenoh.ZError as exc:
            taken = [e for e in listen if _is_taken(e)]
            if taken:
                raise TransportError(
                    f"cannot listen on {taken[0]}: that port is taken (a Zenoh router such "
                    f"as rmw_zenohd, or another busarm, may run there: --connect {taken[0]} "
                    "joins it)") from exc
            raise TransportError(f"cannot open a Zenoh session (listen {list(listen)}, "
                                 f"connect {list(connect)}): {exc}") from exc


def _is_taken(endpoint: str) -> bool:
    import socket

    host, port = endpoint_host(endpoint)
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        try:
            s.bind((host, port))
        except OSError:
            return True
    return False
