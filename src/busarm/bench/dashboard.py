"""``busarm bench dashboard``: the dashboard's rates and stopping times, on the twin in real
time, through the real server on 127.0.0.1.

- Rates: two pages' WebSocket clients count state messages while two MJPEG readers take
  the wrist camera (640x480), all at once, for ``seconds``.
- E-stop: a driver jogs, then sends ``estop``; the time from sending it to the first
  MOVE_STOP the servos receive (a probe on the twin's simulated bus, which the server
  never reads), ``tries`` times.
- Deadman: a driver jogs with heartbeats, then falls silent; the time from its last
  message to the MOVE_STOP that stops the jog.
"""

from __future__ import annotations

import json
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any

from websockets.sync.client import ClientConnection, connect
from websockets.sync.connection import Connection

from busarm.bench.common import latency_percentiles_ms, machine_info
from busarm.dashboard.access import Access
from busarm.dashboard.feeds import robot_feeds
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.progress import Progress, quiet
from busarm.protocol import Command, Request
from busarm.robot import Robot
from busarm.robot.calibration_store import CalibrationStore


@dataclass
class DashboardBenchReport:
    machine: dict[str, str]
    seconds: float
    state_hz: list[float] = field(default_factory=list)
    camera_fps: list[float] = field(default_factory=list)
    camera_size: str = ""
    estop_ms: dict[str, float] = field(default_factory=dict)
    deadman_ms: dict[str, float] = field(default_factory=dict)
    tries: int = 0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _ws(url: str) -> ClientConnection:
    # The stop measurements read no messages: let them queue (a few thousand), no pings.
    return connect(url.replace("http", "ws") + "ws", open_timeout=10, ping_interval=None,
                   max_queue=None)


def _count_states(url: str, seconds: float, out: list[float]) -> None:
    with _ws(url) as ws:
        n, end = 0, time.monotonic() + seconds
        start = time.monotonic()
        while time.monotonic() < end:
            if json.loads(ws.recv(timeout=5))["type"] == "state":
                n += 1
        out.append(n / (time.monotonic() - start))


def _count_frames(url: str, seconds: float, out: list[float], size: list[str]) -> None:
    import urllib.request

    import cv2
    import numpy as np

    with urllib.request.urlopen(url + "camera/wrist.mjpg", timeout=10) as stream:
        n, buf, start = 0, b"", time.monotonic()
        while time.monotonic() - start < seconds:
            buf += stream.read1(65536)
            while (end := buf.find(b"\r\n--frame", 1)) > 0:
                part, buf = buf[:end], buf[end + 2:]
                jpeg = part[part.find(b"\r\n\r\n") + 4:]
                if n == 0:
                    image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
                    size.append("not a JPEG" if image is None else
                                f"{image.shape[1]}x{image.shape[0]}")
                n += 1
        out.append(n / (time.monotonic() - start))


def _rates(url: str, seconds: float, report: DashboardBenchReport) -> None:
    size: list[str] = []
    workers = [threading.Thread(target=_count_states, args=(url, seconds, report.state_hz))
               for _ in range(2)]
    workers += [threading.Thread(target=_count_frames,
                                 args=(url, seconds, report.camera_fps, size))
                for _ in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    report.camera_size = size[0] if size else "no frame"


def _stops_after(seen: list[tuple[float, Request]], t0: float, timeout_s: float = 2.0) -> float:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for t, r in list(seen):
            if t >= t0 and r.command is Command.MOVE_STOP:
                return t - t0
        time.sleep(0.001)
    raise RuntimeError("no MOVE_STOP reached the servos")


def _jog(ws: Connection, direction: int, seconds: float) -> None:
    ws.send(json.dumps({"type": "jog", "joint": "base_yaw", "direction": direction,
                        "speed": 0.5}))
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        time.sleep(0.1)
        ws.send('{"type": "heartbeat"}')


def _stops(url: str, seen: list[tuple[float, Request]], tries: int,
           report: DashboardBenchReport, progress: Progress) -> None:
    estop, deadman = [], []
    with _ws(url) as ws:
        for k in range(tries):
            progress(f"stop {k + 1}/{tries}")
            _jog(ws, 1 if k % 2 else -1, 0.3)
            t0 = time.monotonic()
            ws.send('{"type": "estop"}')
            estop.append(_stops_after(seen, t0))
            ws.send('{"type": "rearm"}')
            _jog(ws, -1 if k % 2 else 1, 0.3)
            t0 = time.monotonic()  # the last heartbeat went out at most a moment ago
            deadman.append(_stops_after(seen, t0))
            time.sleep(0.05)
    report.estop_ms = latency_percentiles_ms(estop)
    report.deadman_ms = latency_percentiles_ms(deadman)


def run_dashboard_bench(*, seconds: float = 10.0, tries: int = 50,
                        progress: Progress = quiet) -> DashboardBenchReport:
    """The benchmark (see the module docstring) on a real-time twin."""
    report = DashboardBenchReport(machine_info(), seconds, tries=tries)
    progress("opening the twin (real time)...")
    with Robot.open("twin://?realtime=1", calibration_store=CalibrationStore.for_port("twin"),
                    progress=progress) as robot:
        assert robot.twin is not None
        seen: list[tuple[float, Request]] = []
        robot.twin.bus.taps.append(  # the stops only: the list is scanned while it grows
            lambda r: seen.append((time.monotonic(), r)) if r.command is Command.MOVE_STOP
            else None)
        service = RobotService(robot).start()
        feeds = robot_feeds(robot, fps=15)
        http = ServerThread(service, Access.for_bind("127.0.0.1"), feeds).start()
        try:
            progress(f"two pages and two camera streams for {seconds:g} s...")
            _rates(http.url, seconds, report)
            _stops(http.url, seen, tries, report, progress)
        finally:
            http.stop()
            service.close()
            for feed in feeds.values():
                feed.close()
    return report
