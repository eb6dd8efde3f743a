"""Network camera streams: ``rtsp://``, ``http://`` and ``https://`` URLs (an IP camera, an
MJPEG stream from a phone or a Raspberry Pi), through OpenCV's FFmpeg backend.

``open_camera("rtsp://...")`` routes here (:data:`busarm.vision.camera.CAMERA_SCHEMES`),
so every ``--camera`` takes a URL. Opening and every read are bounded: a camera that
refuses, does not answer or stalls gives :class:`~busarm.errors.CameraError` within
``open_timeout_s`` / ``read_timeout_s``, never a hang. A password in the URL is never
shown in a message or a frame's source name.
"""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from urllib.parse import urlsplit, urlunsplit

import cv2

from busarm.errors import CameraError, ConfigError
from busarm.units import check_range
from busarm.vision.camera import CameraBase, UInt8Image, _as_bgr

STREAM_SCHEMES = ("rtsp", "rtsps", "http", "https")
DEFAULT_OPEN_TIMEOUT_S = 5.0
DEFAULT_READ_TIMEOUT_S = 5.0
FFMPEG_LOGLEVEL_ENV = "OPENCV_FFMPEG_LOGLEVEL"
"""FFmpeg's own log level for OpenCV (read once, at the backend's first use): quiet, so
that a refused connection is our one error line, not FFmpeg's too."""


def shown_url(url: str) -> str:
    """``url`` with any password replaced by ``***`` (for messages and names)."""
    parts = urlsplit(url)
    if parts.password is None:
        return url
    host = parts.hostname or ""
    netloc = f"{parts.username}:***@{host}" + (f":{parts.port}" if parts.port else "")
    return urlunsplit(parts._replace(netloc=netloc))


@contextmanager
def _quiet_opencv() -> Iterator[None]:
    """OpenCV's warnings off while a stream opens: the CameraError says what failed."""
    os.environ.setdefault(FFMPEG_LOGLEVEL_ENV, "-8")
    previous = cv2.getLogLevel()
    cv2.setLogLevel(0)
    try:
        yield
    finally:
        cv2.setLogLevel(previous)


_DEFAULT_PORTS = {"rtsp": 554, "rtsps": 322, "http": 80, "https": 443}


def _why_not_opened(url: str, waited_s: float, timeout_s: float) -> str:
    """Why FFmpeg opened no stream (it does not say): a timeout if it waited that long;
    else what a plain connection to the host finds (refused, unknown host), or a server
    that answers with something that is not a video stream."""
    if waited_s >= 0.9 * timeout_s:
        return f"no video stream within {timeout_s:g} s (unreachable, or not answering)"
    parts = urlsplit(url)
    host = parts.hostname or ""
    try:
        port = parts.port or _DEFAULT_PORTS.get(parts.scheme.lower(), 80)
        with socket.create_connection((host, port), timeout=min(timeout_s, 2.0)):
            pass
    except ConnectionRefusedError:
        return f"the connection was refused (nothing listens on {host}:{port})"
    except socket.gaierror:
        return f"the host {host!r} is not known"
    except (OSError, ValueError) as exc:  # unreachable network, a bad port number
        return f"no connection to {host} ({getattr(exc, 'strerror', None) or exc})"
    return f"{host}:{port} answered, but not with a video stream FFmpeg can decode"


class NetworkStream(CameraBase):
    """Frames of a network stream; its size is the first frame's.

    CameraError if nothing opens within ``open_timeout_s`` (refused, unreachable, not a
    stream FFmpeg can decode) or a read gives no frame within ``read_timeout_s``.
    """

    def __init__(self, url: str, *, open_timeout_s: float = DEFAULT_OPEN_TIMEOUT_S,
                 read_timeout_s: float = DEFAULT_READ_TIMEOUT_S) -> None:
        check_range("open_timeout_s", open_timeout_s, 0.1, 120.0, "s")
        check_range("read_timeout_s", read_timeout_s, 0.1, 120.0, "s")
        scheme = url.split("://", 1)[0].lower() if "://" in url else ""
        if scheme not in STREAM_SCHEMES:
            raise ConfigError(f"camera stream {url!r}: the URL must start with "
                              f"{', '.join(s + '://' for s in STREAM_SCHEMES)}")
        name = shown_url(url)
        self.read_timeout_s = read_timeout_s
        params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, round(open_timeout_s * 1000),
                  cv2.CAP_PROP_READ_TIMEOUT_MSEC, round(read_timeout_s * 1000)]
        started = time.monotonic()
        with _quiet_opencv():
            capture = cv2.VideoCapture(url, cv2.CAP_FFMPEG, params)
            opened = capture.isOpened()
            ok, image = capture.read() if opened else (False, None)
        if not opened or not ok or image is None:
            capture.release()
            raise CameraError(
                f"cannot open camera stream {name}: "
                + _why_not_opened(url, time.monotonic() - started, open_timeout_s)
                if not opened else
                f"camera stream {name} opened but gave no frame within {read_timeout_s:g} s"
            )
        self._capture = capture
        self._first: UInt8Image | None = _as_bgr(image)
        super().__init__(name, int(self._first.shape[1]), int(self._first.shape[0]))

    def _grab(self) -> UInt8Image:
        if self._first is not None:
            first, self._first = self._first, None
            return first
        ok, image = self._capture.read()
        if not ok or image is None:
            raise CameraError(f"camera stream {self._name}: no frame within "
                              f"{self.read_timeout_s:g} s (the stream ended or stalled)")
        return _as_bgr(image)

    def _release(self) -> None:
        self._capture.release()


__all__ = ["DEFAULT_OPEN_TIMEOUT_S", "DEFAULT_READ_TIMEOUT_S", "STREAM_SCHEMES",
           "NetworkStream", "shown_url"]
