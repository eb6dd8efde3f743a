"""The Lidar's scans for the page, live, from the moment a page watches: ``scan`` messages.

Every revolution anyone reads reaches the page: a job's (the robot's Lidar is a
``ScanTap``: its listeners hear each scan its reader takes), or, when no job reads,
the dashboard's own, read here (``read_when_idle``: never a revolution a job wanted).
Each goes out as a ``scan`` message (the returns in the base's frame, mm), at most
``SCAN_HZ`` a second, only while a page is connected; between jobs the map view (when
there is a map) shows the base and the scan on it (``MobileJobs.show_idle``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from busarm.base.config import Mount
from busarm.errors import BusArmError
from busarm.lidar.scan import LaserScan, to_points
from busarm.lidar.tap import ScanTap

__all__ = [
    "IDLE_S",
    "SCAN_HZ",
    "LiveScans",
    "scan_message",
]


log = logging.getLogger(__name__)

SCAN_HZ = 10.0
"""The most scans a second the page gets (the A1 turns about 10 times a second)."""
IDLE_S = 0.3
"""No job has read a scan for this long: the dashboard reads them itself."""
RETRY_S = 1.0
"""After a Lidar that did not answer, the next try this much later."""


def scan_message(scan: LaserScan, mount: Mount) -> dict[str, Any]:
    """A scan for the page: its valid returns as [x, y] mm in the base's frame."""
    points = np.rint(to_points(scan, mount) * 1000.0).astype(int)
    return {"t": round(scan.stamp_s, 3), "count": len(scan), "rate_hz": round(scan.rate_hz, 1),
            "points_mm": points.tolist()}


class LiveScans:
    """Scans from ``lidar`` (mounted at ``mount``) to ``publish(fields)``, while
    ``watched()``; ``busy()``: a job runs (it reads the scans); ``idle(scan)``: called
    with each scan between jobs."""

    def __init__(self, lidar: ScanTap, mount: Mount, *, publish: Callable[[dict[str, Any]],
                 None], watched: Callable[[], bool], busy: Callable[[], bool],
                 idle: Callable[[LaserScan], None]) -> None:
        self.lidar, self.mount = lidar, mount
        self.publish, self.watched, self.busy, self.idle = publish, watched, busy, idle
        self.error: str | None = None
        """Why the Lidar gives no scans (None while it does)."""
        self._new = threading.Condition()
        self._newest: LaserScan | None = None
        self._closed = threading.Event()
        self._unlisten = lidar.listen(self._offer)
        self._thread = threading.Thread(target=self._run, name="busarm-dashboard-scans",
                                        daemon=True)

    def start(self) -> LiveScans:
        self._thread.start()
        return self

    def close(self) -> None:
        self._closed.set()
        self._unlisten()
        with self._new:
            self._new.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout=2)

    def _offer(self, scan: LaserScan) -> None:  # in the reader's thread: quick
        with self._new:
            self._newest = scan
            self._new.notify_all()

    def _run(self) -> None:
        sent_at = -float("inf")
        while not self._closed.is_set():
            if not self.watched():
                self._closed.wait(0.1)
                continue
            scan = self._next_scan()
            if scan is None or time.monotonic() - sent_at < 1.0 / SCAN_HZ * 0.8:
                continue
            sent_at = time.monotonic()
            try:
                self.publish(scan_message(scan, self.mount))
                if not self.busy():
                    self.idle(scan)
            except Exception:  # a bug must not end the live view in silence
                log.exception("scan for the page")

    def _next_scan(self) -> LaserScan | None:
        """The next scan: a job's (waited for), or one read here when none reads."""
        if not self.busy():
            try:
                self.lidar.read_when_idle(IDLE_S, timeout_s=1.0)
                self.error = None
            except BusArmError as exc:
                if self.error is None:
                    log.warning("Lidar: %s", exc)
                self.error = str(exc)
                self._closed.wait(RETRY_S)
                return None
        with self._new:
            self._new.wait_for(lambda: self._newest is not None or self._closed.is_set(),
                               timeout=0.5)
            scan, self._newest = self._newest, None
        return scan
