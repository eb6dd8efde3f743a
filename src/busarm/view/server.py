"""Serving a RobotView over Foxglove's WebSocket protocol (``foxglove.sdk.v1``).

``serve_view(view, host, port, token)`` starts foxglove-sdk's server on the view's
context: Foxglove (the app, or anything speaking the protocol) connects to
``ws://HOST:PORT``, sees every channel advertised with its schema, and gets the messages
of the channels it subscribes to. The URDF is there three ways, as Foxglove's 3D panel
looks for one: the ``/robot_description`` topic, the ``/robot_description`` parameter,
and the asset ``package://busarm/robot.urdf``. The server takes nothing in: no client
publishing, no services; a viewer cannot move the robot.

Who may connect: bound to a loopback address (the default) only this computer, and no
token is needed. Bound to any other address a token is required (given, or made and
printed), as the dashboard's rule is. foxglove-sdk's server checks no token itself, so
then it listens on loopback only, at a port of its own, and a relay (``TokenRelay``)
listens on HOST:PORT: it checks the token of each connection's request (``?token=`` in
the URL, or ``Authorization: Bearer``) and passes the frames of the ones that carry it
both ways, refusing the others (HTTP 401) before any data goes out. That inner server
takes no token: any program on this computer may reach it at its port (a known limit).

A latched topic (the URDF, the map, the path) is sent again when a client subscribes to
it, by one thread, at most once a second, to the live clients only (never into a
recording: busarm.view.live's two contexts).
"""

from __future__ import annotations

import asyncio
import logging
import secrets
import socket
import threading
from collections.abc import Awaitable
from dataclasses import dataclass
from http import HTTPStatus
from typing import Any
from urllib.parse import parse_qs, quote, urlsplit

import foxglove
from foxglove import Parameter
from foxglove.websocket import Capability, ChannelView, Client, ServerListener
from websockets.typing import Subprotocol

from busarm.errors import ConfigError
from busarm.netaddr import check_can_listen, is_loopback
from busarm.view.live import RobotView

__all__ = [
    "DEFAULT_PORT",
    "LATCHED_EVERY_S",
    "MIN_TOKEN_CHARS",
    "SUBPROTOCOL",
    "URDF_ASSET",
    "TokenRelay",
    "ViewServer",
    "is_loopback",
    "serve_view",
    "this_hosts",
]


log = logging.getLogger(__name__)

DEFAULT_PORT = 8765
"""Foxglove's own default for a WebSocket connection."""
SUBPROTOCOL = "foxglove.sdk.v1"
"""The WebSocket subprotocol foxglove-sdk's server speaks."""
URDF_ASSET = "package://busarm/robot.urdf"
MIN_TOKEN_CHARS = 16
LATCHED = ("/robot_description", "/map", "/path")
LATCHED_EVERY_S = 1.0
"""The latched topics are sent again at most this often (however many subscribe)."""
WILDCARDS = ("0.0.0.0", "::", "")


def this_hosts() -> list[str]:
    """The names another computer may reach this one by: its hostname, then each of its
    addresses that is not loopback (as the hostname resolves here)."""
    name = socket.gethostname()
    try:
        infos = socket.getaddrinfo(name, None, type=socket.SOCK_STREAM)
    except OSError:
        infos = []
    addresses = [str(info[4][0]) for info in infos]
    return list(dict.fromkeys([name, *(a for a in addresses if not is_loopback(a))]))


class _Latched:
    """Sends the view's latched topics again to the live clients when one subscribes
    to one: from one thread of its own (not the server's, into which the log goes
    back), at most once every LATCHED_EVERY_S."""

    def __init__(self, view: RobotView) -> None:
        self.view = view
        self._wanted = threading.Event()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name="busarm-view-latched",
                                        daemon=True)

    def want(self) -> None:
        self._wanted.set()

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stopping.set()
        self._wanted.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        while True:
            self._wanted.wait()
            if self._stopping.is_set():
                return
            self._wanted.clear()
            try:
                self.view.publish_latched(record=False)
            except Exception as exc:  # the view only watches: noted, it goes on
                self.view.note(f"latched topics not sent: {type(exc).__name__}: {exc}")
            if self._stopping.wait(LATCHED_EVERY_S):
                return


class _Listener(ServerListener):
    """A new subscriber to a latched topic gets its value at once (foxglove-sdk keeps no
    last message); ``/robot_description`` is also a parameter."""

    def __init__(self, view: RobotView, latched: _Latched) -> None:
        self.view, self.latched = view, latched

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        if channel.topic in LATCHED:
            self.latched.want()

    def on_get_parameters(self, client: Client, param_names: list[str],
                          request_id: str | None = None) -> list[Parameter]:
        if param_names and "/robot_description" not in param_names:
            return []
        return [Parameter("/robot_description", value=self.view.urdf)]


@dataclass
class ViewServer:
    """A running server: its address, the token a client needs (None: none), stop()."""

    server: Any
    host: str
    port: int
    token: str | None
    relay: TokenRelay | None
    latched: _Latched

    @property
    def wildcard(self) -> bool:
        """Bound to every address of this computer (``0.0.0.0``, ``::``)."""
        return self.host in WILDCARDS

    def url_at(self, host: str) -> str:
        """The WebSocket URL a client opens to reach this server as ``host``."""
        host = f"[{host}]" if ":" in host else host
        query = "" if self.token is None else f"/?token={quote(self.token)}"
        return f"ws://{host}:{self.port}{query}"

    @property
    def url(self) -> str:
        """The WebSocket URL a client opens (with the token, when one is needed); bound
        to every address, the one with this computer's name."""
        return self.urls[0]

    @property
    def urls(self) -> list[str]:
        """Every URL that reaches it: bound to every address, one by this computer's
        name and one by each of its addresses not loopback; else the one bound."""
        return [self.url_at(h) for h in (this_hosts() if self.wildcard else [self.host])]

    @property
    def app_url(self) -> str:
        """Foxglove's web app opened on this server, from a browser on this computer
        only (an https page may open a plain ws:// to this computer, not to another)."""
        here = "127.0.0.1" if self.host in ("0.0.0.0", "") else (
            "::1" if self.host == "::" else self.host)
        return ("https://app.foxglove.dev/?ds=foxglove-websocket&ds.url="
                + quote(self.url_at(here), safe=""))

    def stop(self) -> None:
        if self.relay is not None:
            self.relay.stop()
        self.server.stop()
        self.latched.stop()


def serve_view(view: RobotView, host: str = "127.0.0.1", port: int = DEFAULT_PORT,
               token: str | None = None, *, name: str = "busarm",
               option: str = "--ws-port") -> ViewServer:
    """Serve ``view`` on ``host``:``port`` (0: any free port). Off loopback a token is
    needed: ``token``, else a new one (``ViewServer.token``); on loopback ``token`` is
    needed when given. ConfigError when the port (given as ``option``) is taken or the
    token is too short."""
    if token is not None and len(token) < MIN_TOKEN_CHARS:
        raise ConfigError(f"--token of {len(token)} characters: give at least "
                          f"{MIN_TOKEN_CHARS} (or none, and one is made)")
    check_can_listen(host, port, option)
    if token is None and not is_loopback(host):
        token = secrets.token_urlsafe(24)
    inner_host, inner_port = (host, port) if token is None else ("127.0.0.1", 0)
    latched = _Latched(view)
    try:
        server = foxglove.start_server(
            name=name, host=inner_host, port=inner_port, context=view.live_context,
            capabilities=[Capability.Parameters], server_listener=_Listener(view, latched),
            asset_handler=lambda uri: view.urdf.encode() if uri == URDF_ASSET else None)
    except RuntimeError as exc:
        raise ConfigError(f"cannot serve on {inner_host}:{inner_port} ({option}): "
                          f"{exc}") from exc
    latched.start()
    if token is None:
        return ViewServer(server, host, server.port, None, None, latched)
    try:
        relay = TokenRelay(host, port, server.port, token).start()
    except BaseException:
        server.stop()
        latched.stop()
        raise
    return ViewServer(server, host, relay.port, token, relay, latched)


class TokenRelay:
    """Listens on ``host``:``port`` and relays each WebSocket that carries ``token`` to
    the server on 127.0.0.1:``upstream_port``, frame for frame, both ways."""

    def __init__(self, host: str, port: int, upstream_port: int, token: str) -> None:
        self.host, self.port, self.upstream_port = host, port, upstream_port
        self.token = token
        self.refused = 0
        """Connections refused (no token, or a wrong one)."""
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._stop: asyncio.Event | None = None
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="busarm-view-relay",
                                        daemon=True)

    def start(self) -> TokenRelay:
        """Listen (ConfigError when the port is taken); returns self."""
        self._thread.start()
        self._ready.wait(timeout=10.0)
        if self._error is not None:
            self._thread.join(timeout=5.0)
            raise ConfigError(f"cannot serve on {self.host}:{self.port}: {self._error}")
        return self

    def stop(self) -> None:
        if self._stop is not None:
            self._loop.call_soon_threadsafe(self._stop.set)
        self._thread.join(timeout=5.0)

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._serve())
        finally:
            self._loop.close()

    async def _serve(self) -> None:
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        try:
            server = await serve(self._relay, self.host, self.port,
                                 process_request=self._check,
                                 subprotocols=[Subprotocol(SUBPROTOCOL)],
                                 max_size=None, compression=None)
        except OSError as exc:
            self._error = exc
            self._ready.set()
            return
        self.port = next(iter(server.sockets)).getsockname()[1]
        self._ready.set()
        async with server:
            await self._stop.wait()
            server.close()

    def refusal(self, path: str, headers: Any) -> str | None:
        """Why a request is refused, or None if it carries the token."""
        given = parse_qs(urlsplit(path).query).get("token", [])
        auth = str(headers.get("Authorization", ""))
        if auth.lower().startswith("bearer "):
            given.append(auth[7:].strip())
        if any(secrets.compare_digest(g.encode(), self.token.encode()) for g in given):
            return None
        return ("a token is required (this view listens beyond this computer): open the "
                "URL it printed at start (?token=...), or send Authorization: Bearer TOKEN"
                if not given else "wrong token")

    def _check(self, connection: Any, request: Any) -> Any:
        why = self.refusal(request.path, request.headers)
        if why is None:
            return None
        self.refused += 1
        log.warning("refused a view client from %s: %s", connection.remote_address, why)
        return connection.respond(HTTPStatus.UNAUTHORIZED, why + "\n")

    async def _relay(self, client: Any) -> None:
        from websockets.asyncio.client import connect

        async with connect(f"ws://127.0.0.1:{self.upstream_port}",
                           subprotocols=[Subprotocol(SUBPROTOCOL)], max_size=None, compression=None,
                           open_timeout=10) as upstream:
            await _both_ways(_pump(client, upstream), _pump(upstream, client))


async def _pump(source: Any, sink: Any) -> None:
    from websockets.exceptions import ConnectionClosed

    try:
        async for message in source:
            await sink.send(message)
    except ConnectionClosed:
        pass
    finally:
        await sink.close()


async def _both_ways(a: Awaitable[None], b: Awaitable[None]) -> None:
    """Until one way ends (a side closed); then the other is ended too."""
    tasks = [asyncio.ensure_future(a), asyncio.ensure_future(b)]
    _, pending = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
    for task in pending:
        task.cancel()
    await asyncio.gather(*pending, return_exceptions=True)


