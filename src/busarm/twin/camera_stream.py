"""The wrist camera as a stream: frames captured at simulated instants, drawn meanwhile.

A real camera exposes and transfers frames while the robot goes on; on the twin a frame
is a render, which on a CPU costs as much as many milliseconds of physics. ``CameraStream``
captures the simulation's state at each frame's instant (``capture``: a copy, cheap) and
draws it in its own thread while physics goes on (MuJoCo's renderer releases Python's
lock), so the two share the machine's cores. Each frame carries the simulated time it
shows. At most ``backlog`` frames wait to be drawn: a capture beyond that waits for the
drawing (the simulation is held back, never a frame dropped silently).
"""

from __future__ import annotations

import contextlib
import queue
import threading
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.errors import CameraError
from busarm.twin.twin import Twin

__all__ = [
    "BACKLOG",
    "CameraStream",
    "StreamFrame",
]


BACKLOG = 4


@dataclass(frozen=True)
class StreamFrame:
    image: npt.NDArray[np.uint8]
    """BGR, through the lens, as ``Twin.render_camera`` draws it."""
    at_s: float
    """The simulated time it shows."""


class CameraStream:
    """Wrist-camera frames of ``twin`` drawn in a background thread; a context manager."""

    def __init__(self, twin: Twin, *, live: bool = True, backlog: int = BACKLOG,
                 keep: int = 1) -> None:
        self.twin = twin
        self.live = live
        self.drawn = 0
        self._todo: queue.Queue[tuple[Any, float] | None] = queue.Queue(maxsize=backlog)
        self._done: queue.Queue[StreamFrame] = queue.Queue(maxsize=keep)
        self._error: BaseException | None = None
        self._spare: queue.SimpleQueue[Any] = queue.SimpleQueue()
        """Snapshots whose frames are drawn, to be overwritten by the next captures."""
        self._thread = threading.Thread(target=self._draw, name="busarm-camera-stream",
                                        daemon=True)
        self._thread.start()

    def capture(self) -> None:
        """Take a frame now (the simulation's state at this simulated instant)."""
        if self._error is not None:
            raise CameraError(f"the camera stream stopped: {self._error}")
        try:
            spare = self._spare.get_nowait()
        except queue.Empty:
            spare = None
        self._todo.put((self.twin.snapshot(into=spare), self.twin.clock.now()))

    def latest(self) -> StreamFrame | None:
        """The newest frame drawn and not yet taken (older ones are let go)."""
        frame = None
        while True:
            try:
                frame = self._done.get_nowait()
            except queue.Empty:
                return frame

    def drain(self) -> None:
        """Wait until every captured frame is drawn."""
        self._todo.join()
        if self._error is not None:
            raise CameraError(f"the camera stream stopped: {self._error}")

    def close(self) -> None:
        self._todo.put(None)
        self._thread.join(timeout=5.0)

    def __enter__(self) -> CameraStream:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _draw(self) -> None:
        try:
            while (job := self._todo.get()) is not None:
                try:
                    data, at_s = job
                    frame = StreamFrame(self.twin.render_camera(live=self.live, data=data), at_s)
                    self._spare.put(data)
                    with contextlib.suppress(queue.Empty):  # ``latest`` may take it first
                        if self._done.full():
                            self._done.get_nowait()
                    with contextlib.suppress(queue.Full):
                        self._done.put_nowait(frame)
                    self.drawn += 1
                except Exception as exc:  # reported to the capturing thread
                    self._error = exc
                finally:
                    self._todo.task_done()
            self._todo.task_done()
        finally:
            self.twin.release_renderers()
