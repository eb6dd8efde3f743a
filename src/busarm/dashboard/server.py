"""The dashboard's web server: the page, the WebSocket, the camera streams, the reports.

``make_app`` builds the FastAPI application around a RobotService; ``serve`` runs it
with uvicorn until Ctrl+C, then stops the robot (holding) and closes it.

- ``GET /``: the page (plain HTML, JS and CSS from ``static/``, no build step, nothing
  from other sites: it works offline).
- ``WS /ws``: the page's requests in, state and log out (busarm.dashboard.protocol).
- ``GET /camera/NAME.mjpg``: a camera as an MJPEG stream (``wrist``; ``overview`` on a
  twin).
- ``GET /api/state``, ``GET /api/robot``: the newest state and the robot, as JSON.
- ``GET /map.png``: a mobile robot's map with what its job did on it
  (busarm.dashboard.map_view); the number of the newest one is each state's ``map``;
  ``GET /api/map``: where its metres fall on the picture (a click names a point).
- ``GET /reports/NAME/FILE``: a pick-and-sort report's files.

Every request passes ``Access`` first (busarm.dashboard.access).
"""

from __future__ import annotations

import asyncio
import itertools
import json
import logging
import socket
import threading
import time
from collections.abc import AsyncIterator, Callable
from importlib import resources
from pathlib import Path

from fastapi import FastAPI, Request, WebSocket, WebSocketDisconnect
from fastapi.responses import FileResponse, JSONResponse, Response, StreamingResponse
from starlette.middleware.base import BaseHTTPMiddleware, RequestResponseEndpoint
from starlette.types import ASGIApp

from busarm.dashboard.access import COOKIE, Access
from busarm.dashboard.feeds import Feed
from busarm.dashboard.protocol import message, parse_request, request_type
from busarm.dashboard.service import RobotService
from busarm.errors import BusArmError, ConfigError
from busarm.netaddr import bind_socket

__all__ = [
    "LIVE",
    "OUTBOX",
    "STATIC",
    "STATIC_TYPES",
    "Delivered",
    "ServerThread",
    "bind_socket",
    "make_app",
    "serve",
]


log = logging.getLogger(__name__)

STATIC = resources.files("busarm.dashboard") / "static"
STATIC_TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css",
                ".svg": "image/svg+xml"}
OUTBOX = 64
"""Messages waiting for a slow page; beyond this its oldest live ones (state, scan) are
dropped."""
LIVE = ('{"type":"state"', '{"type":"scan"')
"""The messages a newer one of replaces: a slow page may miss old ones."""
_ids = itertools.count(1)


class Delivered:
    """What the server has sent: state and scan messages per page, frames per camera
    stream (for the benchmark: ``GET /api/delivered``)."""

    def __init__(self) -> None:
        self.states: dict[str, int] = {}
        self.scans: dict[str, int] = {}
        self.frames: dict[str, int] = {}
        self._streams = itertools.count(1)

    def stream(self, camera: str) -> str:
        key = f"{camera}-{next(self._streams)}"
        self.frames[key] = 0
        return key


class _Guard(BaseHTTPMiddleware):
    """Every HTTP request passes ``Access`` first; the printed link's token is kept as the
    page's cookie."""

    def __init__(self, app: ASGIApp, access: Access) -> None:
        super().__init__(app)
        self.access = access

    async def dispatch(self, request: Request, call_next: RequestResponseEndpoint) -> Response:
        access = self.access
        why = access.refusal(request.headers, request.query_params, request.cookies,
                             websocket=False)
        if why is not None:
            return JSONResponse({"error": why}, status_code=403)
        response = await call_next(request)
        token = request.query_params.get("token")
        if token and access.token is not None:  # the printed link: keep it for the page
            response.set_cookie(COOKIE, token, httponly=True, samesite="strict")
        return response


def make_app(service: RobotService, access: Access, feeds: dict[str, Feed]) -> FastAPI:
    """The application: routes for the page, its WebSocket, cameras and reports."""
    app = FastAPI(title="busarm dashboard", docs_url=None, redoc_url=None, openapi_url=None)
    delivered = Delivered()
    app.add_middleware(_Guard, access=access)
    _page_routes(app, service, delivered)
    _media_routes(app, service, feeds, delivered)

    @app.websocket("/ws")
    async def ws(socket: WebSocket) -> None:
        why = access.refusal(socket.headers, socket.query_params, socket.cookies,
                             websocket=True)
        if why is not None:
            await socket.close(code=1008, reason=why[:120])
            return
        await socket.accept()
        await _session(socket, service, delivered)

    return app


def _page_routes(app: FastAPI, service: RobotService, delivered: Delivered) -> None:
    """The page and its files, and the JSON of the state, the robot and what was sent."""

    @app.get("/")
    async def index() -> Response:
        return _static("index.html")

    @app.get("/static/{name}")
    async def static(name: str) -> Response:
        return _static(name)

    @app.get("/api/state")
    async def state() -> JSONResponse:
        return JSONResponse(json.loads(message("state", **service.last_state)))

    @app.get("/api/delivered")
    async def counts() -> JSONResponse:
        return JSONResponse({"states": delivered.states, "scans": delivered.scans,
                             "frames": delivered.frames})

    @app.get("/api/robot")
    async def robot() -> JSONResponse:
        return JSONResponse(service.describe())


def _media_routes(app: FastAPI, service: RobotService, feeds: dict[str, Feed],
                  delivered: Delivered) -> None:
    """The camera streams, the map picture and the reports' files."""

    @app.get("/camera/{name}.mjpg")
    async def camera(name: str) -> Response:
        feed = feeds.get(name)
        if feed is None:
            return JSONResponse({"error": f"no camera {name!r}; cameras: "
                                          f"{', '.join(feeds) or 'none'}"}, status_code=404)
        return StreamingResponse(_mjpeg(feed, delivered, delivered.stream(name)),
                                 media_type="multipart/x-mixed-replace; boundary=frame")

    @app.get("/map.png")
    async def map_png() -> Response:
        if not service.mobile.available:
            return JSONResponse({"error": "no map: this robot has no base and Lidar"},
                                status_code=404)
        sequence, png = await asyncio.to_thread(service.mobile.view.png)
        return Response(png, media_type="image/png",
                        headers={"Cache-Control": "no-store", "X-Map-Sequence": str(sequence)})

    @app.get("/api/map")
    async def map_info() -> JSONResponse:
        if not service.mobile.available:
            return JSONResponse({"error": "no map: this robot has no base and Lidar"},
                                status_code=404)
        return JSONResponse(service.mobile.view.info())

    @app.get("/reports/{name}/{file:path}")
    async def report(name: str, file: str) -> Response:
        path = (service.reports / name / file).resolve()
        root = service.reports.resolve()
        if root not in path.parents or not path.is_file():
            return JSONResponse({"error": f"no report file {name}/{file}"}, status_code=404)
        return FileResponse(path)


def _static(name: str) -> Response:
    file = STATIC / name
    suffix = Path(name).suffix
    if "/" in name or suffix not in STATIC_TYPES or not file.is_file():
        return JSONResponse({"error": f"no file {name!r}"}, status_code=404)
    return Response(file.read_bytes(), media_type=STATIC_TYPES[suffix],
                    headers={"Cache-Control": "no-cache"})


async def _mjpeg(feed: Feed, delivered: Delivered, key: str) -> AsyncIterator[bytes]:
    sequence = 0
    while True:
        sequence, jpeg = await asyncio.to_thread(feed.next_jpeg, sequence)
        if feed.closed:
            return
        if not jpeg:  # none yet (a first frame can take seconds): wait on
            continue
        delivered.frames[key] += 1
        yield (b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: "
               + str(len(jpeg)).encode() + b"\r\n\r\n" + jpeg + b"\r\n")


async def _session(socket: WebSocket, service: RobotService, delivered: Delivered) -> None:
    """One page: its messages in (each request carried out off the event loop), and
    everything the service says out, through a bounded outbox."""
    client = f"p{next(_ids)}"
    loop = asyncio.get_running_loop()
    outbox: asyncio.Queue[str] = asyncio.Queue()

    def put(text: str) -> None:  # called from the service's threads
        loop.call_soon_threadsafe(_offer, outbox, text)

    welcome = service.subscribe(client, put)
    delivered.states[client] = delivered.scans[client] = 0
    sender = asyncio.create_task(_send_all(socket, outbox, welcome, delivered, client))
    try:
        while True:
            received = await socket.receive()
            if received["type"] == "websocket.disconnect":
                break
            text = received.get("text")
            if text is None:  # a binary frame
                await socket.send_text(message("error", request="?", text="binary messages "
                                               "are not requests: send JSON text"))
                continue
            await _answer(socket, service, client, text)
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        sender.cancel()
        await asyncio.to_thread(service.unsubscribe, client)


def _offer(outbox: asyncio.Queue[str], text: str) -> None:
    if outbox.qsize() >= OUTBOX:  # a page that cannot keep up misses old states, not logs
        kept = [t for t in _drain(outbox) if not t.startswith(LIVE)]
        for t in kept[-OUTBOX // 2:]:
            outbox.put_nowait(t)
    outbox.put_nowait(text)


def _drain(outbox: asyncio.Queue[str]) -> list[str]:
    out = []
    while not outbox.empty():
        out.append(outbox.get_nowait())
    return out


async def _send_all(socket: WebSocket, outbox: asyncio.Queue[str], first: str,
                    delivered: Delivered, client: str) -> None:
    try:
        await socket.send_text(first)
        while True:
            text = await outbox.get()
            await socket.send_text(text)
            if text.startswith(LIVE[0]):
                delivered.states[client] += 1
            elif text.startswith(LIVE[1]):
                delivered.scans[client] += 1
    except (WebSocketDisconnect, RuntimeError):
        pass


async def _answer(socket: WebSocket, service: RobotService, client: str, text: str) -> None:
    """Carry out one request; a refusal goes back to this page alone."""
    kind = request_type(text)
    try:
        request = parse_request(text, service.names)
        kind = request.type
        if kind == "estop":  # first, on this thread: nothing queues in front of a stop
            service.handle(client, request)
        else:
            await asyncio.to_thread(service.handle, client, request)
    except (BusArmError, ValueError) as exc:
        await socket.send_text(message("error", request=kind, text=str(exc)))
    except Exception as exc:  # a bug: say so, keep serving, leave the robot as it is
        log.exception("request %s", text[:200])
        await socket.send_text(message("error", request=kind,
                                       text=f"internal error: {type(exc).__name__}: {exc}"))


def serve(service: RobotService, access: Access, feeds: dict[str, Feed], *,
          sock: socket.socket, announce: Callable[[str], None]) -> None:
    """Serve on ``sock`` until Ctrl+C (or SIGTERM); then the robot is stopped, holding
    (MOVE_STOP), and the feeds and the service end. ``announce`` gets the page's link."""
    import uvicorn

    app = make_app(service, access, feeds)
    # Streams (cameras) never end by themselves: a short grace on shutdown.
    config = uvicorn.Config(app, log_level="warning", ws_max_size=64 * 1024, lifespan="off",
                            timeout_graceful_shutdown=1)
    server = uvicorn.Server(config)
    host, port = sock.getsockname()[:2]
    host = f"[{host}]" if ":" in host else host
    announce(f"http://{host}:{port}/" + (f"?token={access.token}" if access.token else ""))
    try:
        server.run(sockets=[sock])
    except KeyboardInterrupt:
        pass  # uvicorn stopped on the signal, then raised it again: the stop asked for
    finally:
        service.close()
        for feed in feeds.values():
            feed.close()
        sock.close()


class ServerThread:
    """The dashboard served from a thread (tests, benchmarks): ``url`` once started,
    ``stop()`` to end it. The service and feeds stay the caller's to close."""

    def __init__(self, service: RobotService, access: Access, feeds: dict[str, Feed],
                 host: str = "127.0.0.1") -> None:
        import uvicorn

        self.sock = bind_socket(host, 0)
        config = uvicorn.Config(make_app(service, access, feeds), log_level="warning",
                                lifespan="off", timeout_graceful_shutdown=1)
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]},
                                       name="busarm-dashboard-http", daemon=True)
        port = self.sock.getsockname()[1]
        self.url = f"http://{host}:{port}/"

    def start(self, timeout_s: float = 10.0) -> ServerThread:
        self.thread.start()
        deadline = time.monotonic() + timeout_s
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise ConfigError(f"the dashboard did not start on {self.url}")
            time.sleep(0.02)
        return self

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=10)
        self.sock.close()
