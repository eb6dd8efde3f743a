"""One Lidar, many watchers: every scan a reader takes is also handed to the listeners.

A Lidar's revolutions are consumed by whoever reads them: a job that navigates reads
every one, and a second reader would take revolutions from it. ``ScanTap`` wraps the
robot's ``LidarSource`` so that the one reader there is (a job) feeds the others too (a
dashboard's scan view, a live 3D view, a recorder) through ``listen``; when nobody reads
(no job runs), a watcher reads for itself with ``read_when_idle``, which takes a scan only
when no other reader has for ``idle_s``. Reads are one at a time (a lock), so two readers
never interleave a revolution's bytes.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from busarm.lidar.scan import LaserScan, LidarSource

__all__ = [
    "ScanListener",
    "ScanTap",
]


log = logging.getLogger(__name__)

ScanListener = Callable[[LaserScan], None]


class ScanTap:
    """``source`` (a LidarSource) whose scans also reach every ``listen``-er. A
    LidarSource itself: ``robot.lidar`` is one."""

    def __init__(self, source: LidarSource) -> None:
        self.source = source
        self.last_scan: LaserScan | None = None
        """The newest scan anyone read (None before the first)."""
        self._listeners: list[ScanListener] = []
        self._lock = threading.Lock()
        self._reading = threading.Lock()
        self._read_at = -float("inf")  # time.monotonic() of the last read by a job

    def __repr__(self) -> str:
        return repr(self.source)

    def read_scan(self, timeout_s: float = 1.0) -> LaserScan:
        """The next complete revolution (the source's), handed to every listener too."""
        self._read_at = time.monotonic()
        with self._reading:
            scan = self.source.read_scan(timeout_s)
        self._read_at = time.monotonic()
        self._hand_out(scan)
        return scan

    def read_when_idle(self, idle_s: float, timeout_s: float = 1.0) -> LaserScan | None:
        """A scan for a watcher, only when no other reader has read for ``idle_s`` (else
        None: the listeners have that reader's scans)."""
        if time.monotonic() - self._read_at < idle_s:
            return None
        with self._reading:
            if time.monotonic() - self._read_at < idle_s:
                return None
            scan = self.source.read_scan(timeout_s)
        self._hand_out(scan)
        return scan

    def listen(self, listener: ScanListener) -> Callable[[], None]:
        """Call ``listener(scan)`` with every scan read from now on (in the reader's
        thread: keep it short); returns the function that stops it."""
        with self._lock:
            self._listeners.append(listener)

        def stop() -> None:
            with self._lock:
                if listener in self._listeners:
                    self._listeners.remove(listener)
        return stop

    def close(self) -> None:
        self.source.close()

    def _hand_out(self, scan: LaserScan) -> None:
        self.last_scan = scan
        with self._lock:
            listeners = list(self._listeners)
        for listener in listeners:
            try:
                listener(scan)
            except Exception:  # a watcher's bug must not cost the job its scan
                log.exception("scan listener %r", listener)
