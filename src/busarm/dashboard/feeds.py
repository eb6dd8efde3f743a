"""Camera feeds for the page: frames as JPEG, at most ``fps`` a second, while watched.

One thread per camera grabs, draws (the wrist camera gets the blocks it sees boxed and
labelled), encodes, and keeps the newest JPEG; every page watching gets that one (an
MJPEG stream: busarm.dashboard.server). Nobody watching: the thread stops, and the twin
renders nothing for it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import BusArmError
from busarm.robot import Robot
from busarm.vision.annotate import annotate
from busarm.vision.camera import CameraSource
from busarm.vision.color import ColorDetector, Detection
from busarm.vision.color_thresholds import default_thresholds

__all__ = [
    "DEFAULT_FPS",
    "DETECT_EVERY",
    "IDLE_STOP_S",
    "JPEG_QUALITY",
    "OVERVIEW_FPS",
    "Feed",
    "Image",
    "block_boxes",
    "robot_feeds",
]


log = logging.getLogger(__name__)

Image = npt.NDArray[np.uint8]
JPEG_QUALITY = 80
DEFAULT_FPS = 20.0
"""A camera's frames a second on the page, at most (a USB camera gives 30)."""
IDLE_STOP_S = 2.0
"""A feed nobody has asked for a frame for this long stops grabbing."""


DETECT_EVERY = 2
"""The wrist camera's blocks are found in every this many frames (and drawn on each):
a person sees boxes that lag a frame, and the CPU has time for more frames."""


def block_boxes(colors: list[str]) -> Callable[[Image], Image]:
    """Draw the blocks of ``colors`` found in a picture (the wrist camera's overlay)."""
    detector = ColorDetector(default_thresholds(), colors=colors)
    found: list[Detection] = []
    count = 0

    def draw(image: Image) -> Image:
        nonlocal found, count
        if count % DETECT_EVERY == 0:
            found = detector.detect(image)
        count += 1
        return annotate(image, found)
    return draw


class Feed:
    """The newest JPEG of ``source`` (drawn on by ``draw``), ``fps`` at most."""

    def __init__(self, name: str, source: CameraSource, *, fps: float = 15.0,
                 draw: Callable[[Image], Image] | None = None,
                 on_thread_end: Callable[[], None] | None = None) -> None:
        self.name, self.source, self.fps = name, source, fps
        self.draw = draw
        self.on_thread_end = on_thread_end
        self._cond = threading.Condition()
        self._jpeg = b""
        self._sequence = 0
        self._wanted_at = 0.0
        self._waiting = 0  # viewers waiting for a frame now (a slow first one, say)
        self._thread: threading.Thread | None = None
        self._closed = False
        self.error: str | None = None
        self.frames = 0
        """Frames encoded since the feed was made (for the benchmark)."""

    def next_jpeg(self, after: int, timeout_s: float = 2.0) -> tuple[int, bytes]:
        """The first frame newer than sequence ``after``: (sequence, JPEG); waits up to
        ``timeout_s`` (then the newest one, maybe old); starts the thread if idle."""
        with self._cond:
            self._wanted_at = time.monotonic()
            self._waiting += 1
            if not self._closed and (self._thread is None or not self._thread.is_alive()):
                self._thread = threading.Thread(target=self._run, daemon=True,
                                                name=f"busarm-feed-{self.name}")
                self._thread.start()
            try:
                self._cond.wait_for(lambda: self._sequence > after or self._closed, timeout_s)
                return self._sequence, self._jpeg
            finally:
                self._waiting -= 1
                self._wanted_at = time.monotonic()

    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()
            thread = self._thread
        if thread is not None:
            thread.join(timeout=2)

    def _run(self) -> None:
        period = 1.0 / self.fps
        next_at = time.monotonic()
        try:
            while not self._closed and (
                    self._waiting or time.monotonic() - self._wanted_at < IDLE_STOP_S):
                self._publish(self._encode())
                next_at += period
                delay = next_at - time.monotonic()
                if delay < -period:  # far behind (a busy CPU): go on from now, no racing
                    next_at, delay = time.monotonic(), 0.0
                time.sleep(max(0.0, delay))
        finally:
            if self.on_thread_end is not None:
                self.on_thread_end()  # a twin camera frees this thread's renderer

    def _encode(self) -> bytes:
        try:
            image = self.source.read().image
            if self.draw is not None:
                image = self.draw(image)
            self.error = None
        except BusArmError as exc:
            self.error = str(exc)
            log.warning("camera %s: %s", self.name, exc)
            image = _message_image(f"{self.name}: {exc}")
            time.sleep(0.5)
        except Exception as exc:  # a bug must not end the feed in silence: say it, go on
            log.exception("camera %s", self.name)
            self.error = f"{type(exc).__name__}: {exc}"
            image = _message_image(f"{self.name}: {self.error}")
            time.sleep(0.5)
        ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        return bytes(data) if ok else b""

    def _publish(self, jpeg: bytes) -> None:
        with self._cond:
            self._jpeg, self._sequence = jpeg, self._sequence + 1
            self.frames += 1
            self._cond.notify_all()


def _message_image(text: str, width: int = 640, height: int = 480) -> Image:
    """A dark picture that says ``text`` (a camera that gives none says why)."""
    image = np.full((height, width, 3), 40, np.uint8)
    for k in range(0, len(text), 60):
        cv2.putText(image, text[k:k + 60], (12, 40 + 28 * (k // 60)),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.6, (230, 230, 230), 1, cv2.LINE_AA)
    return image


OVERVIEW_FPS = 5.0
"""The twin's overview camera (context, not control) at most this often: CPU for the rest."""


def robot_feeds(robot: Robot, fps: float) -> dict[str, Feed]:
    """A feed for each of the robot's cameras (``wrist`` with the blocks it sees drawn on,
    ``fps`` a second; the twin's ``overview`` at most OVERVIEW_FPS).

    A twin's cameras are rendered for the page without shadows or antialiasing (cheaper on
    a CPU, which is what lets the page have 15 frames a second); the pictures vision and
    jobs work on keep them.
    """
    sim = robot.sim
    sources: dict[str, CameraSource] = dict(robot.cameras)
    if sim is not None:
        sources = {name: sim.live_camera("arm" if name == "wrist" else "overview")
                   for name in sources}
    boxes = block_boxes(["red", "green", "blue", "yellow"])
    return {name: Feed(name, source, fps=fps if name == "wrist" else min(fps, OVERVIEW_FPS),
                       draw=boxes if name == "wrist" else None,
                       on_thread_end=sim.release_renderers if sim is not None else None)
            for name, source in sources.items()}
