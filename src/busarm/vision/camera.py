"""Camera sources behind one interface: USB cameras, video files, image folders, plugins.

Every source gives :class:`CameraFrame` objects (a BGR ``uint8`` image, the time of
capture on the robot's clock, a per-source sequence number) from ``read()``, which
raises :class:`~busarm.errors.CameraError` when no frame comes (end of a video, a read
timeout, an unreadable file) and never waits without bound. ``open_camera`` picks a
source from one string:

- ``/dev/video0`` (anything under ``/dev/``) or a plain integer ``0``: a USB camera
  (V4L2 on Linux);
- an existing folder: its images in (natural) sorted order;
- an existing file: a video;
- ``twin`` or ``twin://...``: a scheme from :data:`CAMERA_SCHEMES`, a
  ``"module:callable"`` imported only when used, so this layer never imports the twin
  (installed packages add schemes under the entry-point group ``busarm.cameras``);
- ``rtsp://``, ``http://``, ``https://`` URLs: a network stream (``busarm.vision.stream``),
  with timeouts on opening and on every read.

A scheme name wins over a file or folder of the same name (write ``./twin`` for those).
"""

from __future__ import annotations

import importlib
import inspect
import math
import os
import re
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import CameraError, ConfigError
from busarm.lazy import backend_table
from busarm.units import check_int_range, check_range

UInt8Image = npt.NDArray[np.uint8]

_URL_SCHEMES = ("rtsp", "rtsps", "http", "https")
"""Network streams (busarm.vision.stream): IP cameras, MJPEG over HTTP. Messages do not
list them among the "known" schemes: a URL needs no introduction."""
# Scheme -> "module:callable(spec, **options) -> CameraSource", imported only when used.
CAMERA_SCHEMES: dict[str, str] = {
    "twin": "busarm.twin.camera:open_twin_camera",
    **dict.fromkeys(_URL_SCHEMES, "busarm.vision.stream:NetworkStream"),
}
CAMERA_ENTRY_POINT_GROUP = "busarm.cameras"
"""Installed packages' camera schemes: ``[project.entry-points."busarm.cameras"]``
``myscheme = "mypkg.cam:open_my_camera"`` (a built-in scheme is never replaced)."""

DEFAULT_WIDTH_PX = 640
DEFAULT_HEIGHT_PX = 480
DEFAULT_FPS = 30.0
DEFAULT_READ_TIMEOUT_S = 2.0
FOURCCS = ("YUYV", "MJPG")
IMAGE_PATTERN = "*.png|*.jpg|*.jpeg|*.bmp"
V4L_TIMEOUT_ENV = "OPENCV_VIDEOIO_V4L_SELECT_TIMEOUT"
FPS_TOLERANCE = 0.05
"""A camera running more than 5 % away from the asked rate is reported (a warning)."""


def check_bgr_image(image: object, what: str = "image") -> UInt8Image:
    """Return ``image`` if it is an H x W x 3 ``uint8`` array (BGR), else raise ConfigError.

    Non-contiguous views are copied (OpenCV needs contiguous rows).
    """
    if not isinstance(image, np.ndarray):
        raise ConfigError(
            f"{what} must be an H x W x 3 uint8 numpy array, got {type(image).__name__}"
        )
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise ConfigError(
            f"{what} must be an H x W x 3 uint8 array (BGR), got shape {image.shape} "
            f"dtype {image.dtype}"
        )
    if image.shape[0] < 1 or image.shape[1] < 1:
        raise ConfigError(f"{what} is empty: shape {image.shape}")
    if not image.flags.c_contiguous:
        image = np.ascontiguousarray(image)
    return image


def _as_bgr(image: npt.NDArray[Any]) -> UInt8Image:
    """What a decoder gave (grey, BGRA, 16-bit) as H x W x 3 uint8 BGR."""
    if image.dtype == np.uint16:
        image = (image >> 8).astype(np.uint8)
    if image.ndim == 2:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    elif image.ndim == 3 and image.shape[2] == 4:
        image = cv2.cvtColor(image, cv2.COLOR_BGRA2BGR)
    elif image.ndim == 3 and image.shape[2] == 1:
        image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    return check_bgr_image(image, "decoded frame")


@dataclass(frozen=True)
class CameraFrame:
    """One image from a source.

    ``image`` is H x W x 3 ``uint8`` BGR (read-only), ``timestamp_s`` when it was
    captured on the robot's clock: ``time.monotonic()`` for a real camera (a USB camera:
    when the driver handed it over), the simulated seconds of a twin in this process
    (``robot.clock``), so a frame lines up with the robot's other readings. ``sequence``
    counts from 0 per source, ``source`` is the source's name.
    """

    image: UInt8Image = field(compare=False, repr=False)
    timestamp_s: float
    sequence: int
    source: str

    @property
    def width_px(self) -> int:
        return int(self.image.shape[1])

    @property
    def height_px(self) -> int:
        return int(self.image.shape[0])


@runtime_checkable
class CameraSource(Protocol):
    """What every camera source provides (USB, video file, image folder, the twin)."""

    @property
    def name(self) -> str: ...

    @property
    def width_px(self) -> int: ...

    @property
    def height_px(self) -> int: ...

    def read(self) -> CameraFrame:
        """The next frame; CameraError if none comes (end, timeout, unreadable)."""
        ...

    def close(self) -> None: ...

    def __enter__(self) -> CameraSource: ...

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


class EndOfFrames(CameraError):
    """A finite source (a video, an image folder) has no more frames."""


class CameraBase:
    """Shared plumbing: sequence numbers, timestamps, closing, ``with`` and iteration.

    Subclasses implement ``_grab() -> image`` (raise CameraError when none comes) and
    ``_release()``.
    """

    def __init__(self, name: str, width_px: int, height_px: int) -> None:
        self._name = name
        self._width_px = width_px
        self._height_px = height_px
        self._sequence = 0
        self._closed = False
        # Several threads may read one camera (a job and the dashboard's stream): one
        # grab at a time, each frame to one of them.
        self._read_lock = threading.Lock()

    @property
    def name(self) -> str:
        return self._name

    @property
    def width_px(self) -> int:
        return self._width_px

    @property
    def height_px(self) -> int:
        return self._height_px

    @property
    def closed(self) -> bool:
        return self._closed

    def read(self) -> CameraFrame:
        """The next frame, stamped when it arrived (``_timestamp``: the robot's clock)."""
        with self._read_lock:
            return self._read()

    def _read(self) -> CameraFrame:
        if self._closed:
            raise CameraError(f"camera {self._name} is closed")
        image = self._grab()
        timestamp_s = self._timestamp()
        if image.shape[1] != self._width_px or image.shape[0] != self._height_px:
            raise CameraError(
                f"camera {self._name}: frame {self._sequence} is {image.shape[1]}x"
                f"{image.shape[0]} px, the source is {self._width_px}x{self._height_px} px"
            )
        image.flags.writeable = False  # frames are shared; annotate() draws on a copy
        frame = CameraFrame(image, timestamp_s, self._sequence, self._name)
        self._sequence += 1
        return frame

    def _timestamp(self) -> float:
        """When a frame is taken: the machine's monotonic clock (a simulated camera: its
        simulation's)."""
        return time.monotonic()

    def frames(self, count: int | None = None) -> Iterator[CameraFrame]:
        """Up to ``count`` frames (all, for None); a finite source's end stops it quietly."""
        n = 0
        while count is None or n < count:
            try:
                yield self.read()
            except EndOfFrames:
                return
            n += 1

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._release()

    def __enter__(self) -> CameraBase:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return (f"{type(self).__name__}({self._name!r}, {self._width_px}x{self._height_px} px, "
                f"{state})")

    def _grab(self) -> UInt8Image:  # pragma: no cover - abstract
        raise NotImplementedError

    def _release(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError


# ---------------------------------------------------------------------- USB cameras


def _usb_backend() -> int:
    # V4L2 directly on Linux: the generic backend may pick GStreamer and ignore the format.
    return cv2.CAP_V4L2 if sys.platform.startswith("linux") else cv2.CAP_ANY


def _usb_device_name(device: str | int, width_px: int, height_px: int, fps: float,
                     fourcc: str, read_timeout_s: float) -> str:
    """The device path of a USB camera, after checking what it is asked for."""
    check_int_range("width_px", width_px, 16, 8192)
    check_int_range("height_px", height_px, 16, 8192)
    check_range("fps", fps, 1.0, 1000.0)
    check_range("read_timeout_s", read_timeout_s, 0.05, 60.0)
    if fourcc not in FOURCCS:
        raise ConfigError(f"fourcc {fourcc!r} is not one of {', '.join(FOURCCS)}")
    if isinstance(device, bool) or not isinstance(device, int | str):
        raise ConfigError(f"camera device must be a path or an index, got {device!r}")
    if isinstance(device, int) and not 0 <= device <= 255:
        raise ConfigError(f"camera index {device} is out of range 0..255")
    name = device if isinstance(device, str) else f"/dev/video{device}"
    if sys.platform.startswith("linux") and not os.path.exists(name):
        # Checked first: OpenCV would print its own warnings and just fail to open.
        raise CameraError(f"no camera at {name}")
    return name


class UsbCamera(CameraBase):
    """A USB (UVC) camera through ``cv2.VideoCapture`` (V4L2 on Linux).

    The camera must deliver the asked size, or CameraError says what it gave; a frame
    rate more than 5 % off is reported as a RuntimeWarning (``actual_fps`` has it).
    ``read_timeout_s`` bounds every read (on Linux in whole seconds, and the first
    camera opened in a process sets it for all: OpenCV's V4L2 reads it once).
    ``fourcc`` is ``"YUYV"`` (uncompressed; USB 2 carries 640x480 at 30 fps) or
    ``"MJPG"`` (needed for larger sizes at full rate).
    """

    def __init__(
        self, device: str | int, width_px: int = DEFAULT_WIDTH_PX,
        height_px: int = DEFAULT_HEIGHT_PX, fps: float = DEFAULT_FPS, fourcc: str = "YUYV",
        *, read_timeout_s: float = DEFAULT_READ_TIMEOUT_S,
    ) -> None:
        name = _usb_device_name(device, width_px, height_px, fps, fourcc, read_timeout_s)
        # OpenCV's V4L2 backend ignores CAP_PROP_READ_TIMEOUT_MSEC and waits 10 s for a
        # stalled camera, or what this variable says (whole seconds, read once per
        # process at the first wait): the first camera opened sets it.
        os.environ.setdefault(V4L_TIMEOUT_ENV, str(max(1, math.ceil(read_timeout_s))))
        capture = cv2.VideoCapture(device, _usb_backend())
        if not capture.isOpened():
            capture.release()
            raise CameraError(f"no camera at {name} (it exists but cannot be opened as a camera)")
        self._capture = capture
        self.read_timeout_s = read_timeout_s
        try:
            capture.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter.fourcc(*fourcc))
            capture.set(cv2.CAP_PROP_FRAME_WIDTH, width_px)
            capture.set(cv2.CAP_PROP_FRAME_HEIGHT, height_px)
            capture.set(cv2.CAP_PROP_FPS, fps)
            capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)  # the newest frame, not a stale queue
            capture.set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, read_timeout_s * 1000.0)
            got_w = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH))
            got_h = int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))
            self.actual_fps = float(capture.get(cv2.CAP_PROP_FPS))
            self.fourcc = fourcc
            asked = f"{width_px}x{height_px} {fourcc} at {fps:g} fps"
            if (got_w, got_h) != (width_px, height_px):
                raise CameraError(
                    f"camera {name} gave {got_w}x{got_h} px, asked {asked}; "
                    "`v4l2-ctl --list-formats-ext` lists what it offers"
                )
            super().__init__(name, width_px, height_px)
            # The first frame proves the stream runs (a busy camera opens, then gives nothing).
            self._first: UInt8Image | None = None
            self._first = self._grab()
            if self._first.shape[:2] != (height_px, width_px):
                raise CameraError(
                    f"camera {name} delivered {self._first.shape[1]}x{self._first.shape[0]} "
                    f"px frames, asked {asked}"
                )
        except BaseException:
            capture.release()
            raise
        if self.actual_fps > 0 and abs(self.actual_fps - fps) > FPS_TOLERANCE * fps:
            warnings.warn(
                f"camera {name} runs at {self.actual_fps:g} fps, asked {fps:g} "
                f"({width_px}x{height_px} {fourcc})", RuntimeWarning, stacklevel=2,
            )

    def _grab(self) -> UInt8Image:
        if self._first is not None:
            first, self._first = self._first, None
            return first
        ok, image = self._capture.read()
        if not ok or image is None:
            raise CameraError(
                f"camera {self._name}: no frame within {self.read_timeout_s:g} s "
                "(unplugged, or used by another program?)"
            )
        return _as_bgr(image)

    def _release(self) -> None:
        self._capture.release()


# ---------------------------------------------------------------------- files


class VideoFileSource(CameraBase):
    """Frames of a video file (anything OpenCV's FFmpeg can decode); ``loop`` restarts it.

    Its end raises :class:`EndOfFrames` (a CameraError) naming the file and the count.
    """

    def __init__(self, path: str | Path, loop: bool = False) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise CameraError(f"no video file {self.path}")
        capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            capture.release()
            raise CameraError(f"cannot open video {self.path}: not a video OpenCV can decode")
        self._capture = capture
        self.loop = loop
        self._count = 0
        ok, image = capture.read()
        if not ok or image is None:
            capture.release()
            raise CameraError(f"video {self.path} has no frame OpenCV can decode")
        first = _as_bgr(image)
        self._first: UInt8Image | None = first
        self.fps = float(capture.get(cv2.CAP_PROP_FPS))
        super().__init__(str(self.path), int(first.shape[1]), int(first.shape[0]))

    def _grab(self) -> UInt8Image:
        if self._first is not None:
            first, self._first = self._first, None
            self._count += 1
            return first
        ok, image = self._capture.read()
        if (not ok or image is None) and self.loop and self._count > 0:
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, image = self._capture.read()
        if not ok or image is None:
            raise EndOfFrames(f"end of video {self.path} after {self._count} frame(s)")
        self._count += 1
        return _as_bgr(image)

    def _release(self) -> None:
        self._capture.release()


def _natural_key(path: Path) -> list[Any]:
    # frame2.png before frame10.png
    return [int(p) if p.isdigit() else p.lower() for p in re.split(r"(\d+)", path.name)]


class ImageFolderSource(CameraBase):
    """The images of a folder matching ``pattern`` (globs joined by ``|``), in natural
    sorted order (``frame2`` before ``frame10``); ``loop`` starts over at the end.

    Every image must have the first one's size; an unreadable one raises CameraError
    naming the file; the end raises :class:`EndOfFrames`.
    """

    def __init__(self, path: str | Path, pattern: str = IMAGE_PATTERN, loop: bool = False) -> None:
        self.path = Path(path)
        if not self.path.is_dir():
            raise CameraError(f"no image folder {self.path}")
        globs = [g.strip() for g in pattern.split("|") if g.strip()]
        if not globs:
            raise ConfigError(f"image pattern {pattern!r} has no glob (e.g. '*.png|*.jpg')")
        found = {p for g in globs for p in self.path.glob(g) if p.is_file()}
        self.files = sorted(found, key=_natural_key)
        if not self.files:
            raise CameraError(f"no images matching {pattern!r} in folder {self.path}")
        self.loop = loop
        self._index = 0
        first = self._load(self.files[0])
        super().__init__(str(self.path), int(first.shape[1]), int(first.shape[0]))
        self._first: UInt8Image | None = first

    @staticmethod
    def _load(file: Path) -> UInt8Image:
        try:
            data = np.fromfile(file, dtype=np.uint8)  # imread cannot say why it failed
        except OSError as exc:
            raise CameraError(f"cannot read image {file}: {exc}") from exc
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
        if image is None:
            raise CameraError(f"cannot read image {file}: not an image OpenCV can decode")
        return _as_bgr(image)

    def _grab(self) -> UInt8Image:
        if self._first is not None:
            first, self._first = self._first, None
            self._index = 1
            return first
        if self._index >= len(self.files):
            if not self.loop:
                raise EndOfFrames(f"end of folder {self.path} after {len(self.files)} image(s)")
            self._index = 0
        file = self.files[self._index]
        self._index += 1
        return self._load(file)

    def _release(self) -> None:
        pass


# ---------------------------------------------------------------------- open_camera


def open_camera(spec: str | int, **options: Any) -> CameraSource:
    """Open a camera source from one string (see the module docstring).

    ``options`` go to the source (``UsbCamera(width_px=..., fourcc=...)``,
    ``VideoFileSource(loop=...)``, ``ImageFolderSource(pattern=..., loop=...)`` or the
    scheme's factory); an option the source does not take is a ConfigError.
    """
    if isinstance(spec, int) and not isinstance(spec, bool):
        return _construct(UsbCamera, str(spec), spec, options)
    if not isinstance(spec, str) or not spec.strip():
        raise ConfigError(f"camera must be a device, file, folder or scheme, got {spec!r}")
    spec = spec.strip()
    if spec.isdigit():
        return _construct(UsbCamera, spec, int(spec), options)
    if spec.startswith("/dev/"):
        return _construct(UsbCamera, spec, spec, options)
    scheme = spec.split("://", 1)[0] if "://" in spec else spec
    schemes = camera_schemes()
    target = schemes.get(scheme)
    if target is not None:
        factory = _import_factory(scheme, target)
        return _construct(factory, spec, spec, options)
    path = Path(spec)
    if path.is_dir():
        return _construct(ImageFolderSource, spec, path, options)
    if path.is_file():
        return _construct(VideoFileSource, spec, path, options)
    known = ", ".join(sorted(set(schemes) - set(_URL_SCHEMES))) or "none"
    raise CameraError(
        f"no camera at {spec}: not a device, file, folder or known scheme (known: {known})"
    )


def camera_schemes() -> dict[str, str]:
    """Every camera scheme: ``CAMERA_SCHEMES`` and those of the ``busarm.cameras``
    entry-point group."""
    return backend_table(CAMERA_SCHEMES, CAMERA_ENTRY_POINT_GROUP)


def _import_factory(scheme: str, target: str) -> Callable[..., CameraSource]:
    module_name, _, func_name = target.partition(":")
    try:
        factory = getattr(importlib.import_module(module_name), func_name)
    except (ImportError, AttributeError) as exc:
        raise CameraError(f"camera scheme {scheme!r}: cannot load {target}: {exc}") from exc
    if not callable(factory):
        raise CameraError(f"camera scheme {scheme!r}: {target} is not callable")
    return factory  # type: ignore[no-any-return]


def _construct(
    factory: Callable[..., Any], spec: str, first: object, options: dict[str, Any]
) -> CameraSource:
    try:
        inspect.signature(factory).bind(first, **options)
    except TypeError:
        params = [
            p.name for p in list(inspect.signature(factory).parameters.values())[1:]
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
        ]
        raise ConfigError(
            f"camera {spec}: option(s) {', '.join(sorted(options)) or '(none)'} not accepted; "
            f"it takes: {', '.join(params) or 'no options'}"
        ) from None
    except ValueError:  # a builtin without a signature: let the call decide
        pass
    source = factory(first, **options)
    if not isinstance(source, CameraSource):
        raise CameraError(f"camera {spec}: the factory returned {type(source).__name__}, "
                          "not a camera source")
    return source



__all__ = [
    "CAMERA_ENTRY_POINT_GROUP",
    "CAMERA_SCHEMES",
    "CameraBase",
    "CameraFrame",
    "CameraSource",
    "EndOfFrames",
    "ImageFolderSource",
    "UsbCamera",
    "VideoFileSource",
    "camera_schemes",
    "check_bgr_image",
    "open_camera",
]
