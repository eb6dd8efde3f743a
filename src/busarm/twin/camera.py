"""The twin's arm camera as a vision camera source, in this process or over loopback.

- ``twin``: a new twin of its own (the default table); the camera of a twin the program
  already has is ``TwinCamera(twin)`` (a ``busarm.robot.Robot`` on a twin hands out its
  own as ``robot.camera``);
- ``twin://127.0.0.1:PORT``: the camera of a ``busarm twin serve`` in another process.

The wire format of the loopback camera is one request byte ``F`` per frame, answered by
a header (magic ``BATF``, width, height as uint32, capture time as float64
``time.monotonic()``, which all processes on one Linux machine share) and the BGR bytes.
A request byte ``L`` asks for the camera's optics (what its calibration depends on): a
header (magic ``BATL``, length as uint32) and that many bytes of JSON, ``{"lens":
{LensSpec's fields}, "cam2link": 4x4 mm}``. The server binds 127.0.0.1 only.
"""

from __future__ import annotations

import contextlib
import json
import socket
import socketserver
import struct
import threading
from dataclasses import dataclass, fields
from urllib.parse import urlsplit

import numpy as np
import numpy.typing as npt

from busarm.arm.camera_mount import CameraMount
from busarm.errors import CameraError, ConfigError
from busarm.twin.lens import LensSpec
from busarm.twin.twin import Twin
from busarm.units import listing
from busarm.vision.camera import CameraBase

__all__ = [
    "LOOPBACK",
    "SOCKET_TIMEOUT_S",
    "CameraServer",
    "RemoteTwinCamera",
    "TwinCamera",
    "TwinOptics",
    "open_twin_camera",
]


_HEADER = struct.Struct("<4sIId")
_MAGIC = b"BATF"
_OPTICS_HEADER = struct.Struct("<4sI")
_OPTICS_MAGIC = b"BATL"
LOOPBACK = "127.0.0.1"
SOCKET_TIMEOUT_S = 5.0


@dataclass(frozen=True)
class TwinOptics:
    """A twin camera's lens and where it sits on the arm: what its calibration is for
    (``busarm.robot.calibration_store``); a ``Twin`` has the same two attributes."""

    lens: LensSpec
    mount: CameraMount

    def to_json(self) -> bytes:
        lens = {f.name: getattr(self.lens, f.name) for f in fields(LensSpec)}
        return json.dumps({"lens": lens, "cam2link": self.mount.cam2link.tolist()}).encode()

    @classmethod
    def from_json(cls, data: bytes) -> TwinOptics:
        """Optics as ``to_json`` wrote them; CameraError if they are not."""
        try:
            raw = json.loads(data.decode("utf-8"))
            lens = dict(raw["lens"])
            lens["distortion"] = tuple(lens["distortion"])
            cam2link = np.asarray(raw["cam2link"], dtype=float)
            if cam2link.shape != (4, 4):
                raise ValueError(f"cam2link has shape {cam2link.shape}")
            return cls(LensSpec(**lens), CameraMount(cam2link))
        except (ValueError, TypeError, KeyError, ConfigError) as exc:
            raise CameraError(f"twin camera: the server's optics are not readable ({exc})"
                              ) from None


class TwinCamera(CameraBase):
    """Frames from a twin in this process (its arm camera, or the overview camera)."""

    def __init__(self, twin: Twin, *, view: str = "arm", owns_twin: bool = False,
                 live: bool = False) -> None:
        """``live``: a view for a person, drawn without shadows or antialiasing, several
        times cheaper on a CPU (busarm.dashboard); vision gets the full pictures."""
        if view not in ("arm", "overview"):
            raise ConfigError(f"twin camera view {view!r}; allowed: arm, overview")
        arm = view == "arm"
        super().__init__("twin" if arm else "twin overview",
                         twin.lens.width_px if arm else 640, twin.lens.height_px if arm else 480)
        self.twin = twin
        self.view = view
        self._owns = owns_twin
        self.live = live
        self._taken_s = twin.clock.now()

    def _grab(self) -> npt.NDArray[np.uint8]:
        if self.twin.is_closed:
            raise CameraError(f"{self.name}: the twin was closed")
        # The moment the picture shows: the render that follows takes time on the wall
        # clock (a real-time twin moves on meanwhile), none on a simulated one.
        self._taken_s = self.twin.clock.now()
        if self.view == "arm":
            return self.twin.render_camera(live=self.live)
        return self.twin.render_overview(live=self.live)

    def _timestamp(self) -> float:
        return self._taken_s

    def _release(self) -> None:
        if self._owns:
            self.twin.close()


class RemoteTwinCamera(CameraBase):
    """Frames from ``busarm twin serve``'s camera server on this machine."""

    def __init__(self, host: str, port: int) -> None:
        if host not in (LOOPBACK, "localhost"):
            raise ConfigError(f"twin camera host {host!r}: only this machine "
                              f"({LOOPBACK}) serves twin frames")
        name = f"twin://{host}:{port}"
        self._sock = self._connect(name, port)
        try:
            self.optics: TwinOptics | None = self._fetch_optics()
            """The served twin's lens and camera mount (None from a server too old to
            tell): the twin's kept calibration is for them."""
        except CameraError:  # such a server closes the connection on a request it lacks
            self._sock.close()
            self._sock, self.optics = self._connect(name, port), None
        try:
            first = self._fetch()
        except BaseException:
            self._sock.close()
            raise
        height, width = first.shape[:2]
        super().__init__(name, width, height)

    @staticmethod
    def _connect(name: str, port: int) -> socket.socket:
        try:
            return socket.create_connection((LOOPBACK, port), timeout=SOCKET_TIMEOUT_S)
        except OSError as exc:
            raise CameraError(f"no camera at {name}: {exc} (is `busarm twin serve` "
                              "running?)") from exc

    def _fetch_optics(self) -> TwinOptics:
        try:
            self._sock.sendall(b"L")
        except OSError as exc:
            raise CameraError(f"twin camera: {exc}") from exc
        magic, size = _OPTICS_HEADER.unpack(self._recv(_OPTICS_HEADER.size))
        if magic != _OPTICS_MAGIC or size > 1 << 16:
            raise CameraError("twin camera: not a twin camera server (bad optics header)")
        return TwinOptics.from_json(self._recv(size))

    def _recv(self, n: int) -> bytes:
        buf = bytearray()
        while len(buf) < n:
            try:
                chunk = self._sock.recv(n - len(buf))
            except OSError as exc:
                raise CameraError(f"twin camera: {exc}") from exc
            if not chunk:
                raise CameraError("twin camera: the twin server closed the connection")
            buf += chunk
        return bytes(buf)

    def _fetch(self) -> npt.NDArray[np.uint8]:
        try:
            self._sock.sendall(b"F")
        except OSError as exc:
            raise CameraError(f"twin camera: {exc}") from exc
        magic, width, height, _stamp = _HEADER.unpack(self._recv(_HEADER.size))
        if magic != _MAGIC or not (0 < width <= 4096 and 0 < height <= 4096):
            raise CameraError("twin camera: not a twin camera server (bad header)")
        data = self._recv(width * height * 3)
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3).copy()

    def _grab(self) -> npt.NDArray[np.uint8]:
        return self._fetch()

    def _release(self) -> None:
        with contextlib.suppress(OSError):
            self._sock.close()


def open_twin_camera(spec: str, **options: object) -> TwinCamera | RemoteTwinCamera:
    """Entry point of the ``twin`` camera scheme (see the module docstring)."""
    view = str(options.pop("view", "arm"))
    if options:
        raise ConfigError(f"twin camera: unknown option(s) {listing(sorted(options))}; known: view")
    parts = urlsplit(spec) if "://" in spec else None
    if parts is not None and parts.netloc:
        try:
            port = parts.port
        except ValueError:
            port = None
        if port is None or parts.hostname is None or not 1 <= port <= 65535:
            raise ConfigError(f"twin camera {spec!r}: expected twin://127.0.0.1:PORT with "
                              "PORT 1..65535 (the address `busarm twin serve` prints)")
        return RemoteTwinCamera(parts.hostname, port)
    if spec != "twin":
        raise ConfigError(f"twin camera {spec!r}: give twin (a twin of its own) or "
                          "twin://127.0.0.1:PORT (the address `busarm twin serve` prints); "
                          "for another table, open the robot on that twin (--port "
                          "twin://?...) and use its camera")
    from busarm.twin.spec import TwinSpec

    return TwinCamera(TwinSpec().build(), view=view, owns_twin=True)


class CameraServer:
    """Serves a twin's arm camera on 127.0.0.1 (port 0: any free port)."""

    def __init__(self, twin: Twin, port: int = 0) -> None:
        camera = TwinCamera(twin)
        optics = TwinOptics(twin.lens, twin.mount).to_json()

        class Handler(socketserver.BaseRequestHandler):
            def handle(self) -> None:
                sock: socket.socket = self.request
                try:
                    while (request := sock.recv(1)) in (b"F", b"L"):
                        if request == b"L":
                            sock.sendall(_OPTICS_HEADER.pack(_OPTICS_MAGIC, len(optics))
                                         + optics)
                            continue
                        frame = camera.read()
                        h, w = frame.image.shape[:2]
                        sock.sendall(_HEADER.pack(_MAGIC, w, h, frame.timestamp_s)
                                     + frame.image.tobytes())
                except (OSError, CameraError):
                    pass  # the client went away, or the twin closed: end this connection
                finally:
                    twin.release_renderers()

        class Server(socketserver.ThreadingTCPServer):
            daemon_threads = True
            allow_reuse_address = True

        try:
            self._server = Server((LOOPBACK, port), Handler)
        except OSError as exc:
            raise ConfigError(f"cannot serve the twin camera on {LOOPBACK}:{port}: {exc}") from exc
        self.port: int = self._server.server_address[1]
        self.url = f"twin://{LOOPBACK}:{self.port}"
        self._thread = threading.Thread(target=self._server.serve_forever,
                                        name="busarm-twin-camera", daemon=True)

    def start(self) -> str:
        self._thread.start()
        return self.url

    def stop(self) -> None:
        self._server.shutdown()
        self._server.server_close()
