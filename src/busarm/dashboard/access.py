"""Who may reach the dashboard: the address it binds, its token, and same-origin pages.

Bound to a loopback address (the default, 127.0.0.1) only this computer reaches it, and
a token is optional. Bound to any other address a token is required: given, or made
and printed at start. A request carries it as ``Authorization: Bearer TOKEN``, as
``?token=TOKEN`` (the link printed at start: the page then keeps it in a cookie that
only this site gets), or in that cookie.

Two checks hold whatever the binding: a WebSocket opened by a page of another site is
refused (its ``Origin`` is not this server), so a web page the user happens to visit
cannot drive the robot; and on loopback the ``Host`` must be a loopback name (a DNS
rebinding attack names another host).
"""

from __future__ import annotations

import secrets
from collections.abc import Mapping
from dataclasses import dataclass
from urllib.parse import urlsplit

from busarm.errors import ConfigError
from busarm.netaddr import is_loopback

__all__ = [
    "COOKIE",
    "LOOPBACK_NAMES",
    "Access",
    "is_loopback",
]


COOKIE = "busarm_token"
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "[::1]", "::1")


@dataclass(frozen=True)
class Access:
    """The rules for a server bound to ``bind``; ``token`` None means none needed."""

    bind: str
    token: str | None

    @classmethod
    def for_bind(cls, bind: str, token: str | None = None) -> Access:
        """Loopback: the token given, if any. Elsewhere: the token given, else a new one."""
        if token is not None and len(token) < 16:
            raise ConfigError(f"--token of {len(token)} characters: give at least 16 (or "
                              "none, and one is made)")
        if token is None and not is_loopback(bind):
            token = secrets.token_urlsafe(24)
        return cls(bind, token)

    @property
    def loopback(self) -> bool:
        return is_loopback(self.bind)

    def refusal(self, headers: Mapping[str, str], query: Mapping[str, str],
                cookies: Mapping[str, str], *, websocket: bool) -> str | None:
        """Why a request is refused, or None if it may go on."""
        host = headers.get("host", "")
        if self.loopback and not is_loopback(urlsplit(f"//{host}").hostname or ""):
            return f"Host {host!r} is not this computer (the dashboard listens on loopback)"
        origin = headers.get("origin")
        if websocket and origin is not None and urlsplit(origin).netloc != host:
            return f"a page from {origin} may not use this dashboard"
        if self.token is None:
            return None
        given = [query.get("token"), cookies.get(COOKIE)]
        auth = headers.get("authorization", "")
        if auth.lower().startswith("bearer "):
            given.append(auth[7:].strip())
        if any(g is not None and secrets.compare_digest(g.encode(), self.token.encode())
               for g in given):
            return None
        return ("a token is required (this dashboard listens beyond this computer): open "
                "the link it printed at start, or send Authorization: Bearer TOKEN"
                if not any(given) else "wrong token")
