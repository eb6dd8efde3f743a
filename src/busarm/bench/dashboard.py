"""``busarm bench dashboard``: the dashboard's rates and stopping times, on the twin in real
time, through the real server on 127.0.0.1.

- Rates: two headless Chromium pages show the dashboard (state, the wrist camera at
  640x480 with the blocks drawn, the overview camera) for ``seconds`` while the arm
  waves (an action group, again and again: every frame differs); the server counts what
  it delivered to each (``/api/delivered``).
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
from busarm.dashboard.feeds import DEFAULT_FPS, robot_feeds
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.errors import ConfigError
from busarm.progress import Progress, quiet
from busarm.protocol import Command, Request
from busarm.robot import Robot
from busarm.robot.calibration_store import CalibrationStore
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.twin.spec import TwinSpec

__all__ = [
    "CHROMIUM_FLAGS",
    "WARM_UP_S",
    "DashboardBenchReport",
    "browser_driver",
    "get_json",
    "open_ws",
    "run_dashboard_bench",
]


WARM_UP_S = 3.0
"""The pages load, open their streams and the feeds start, before the count begins."""


@dataclass
class DashboardBenchReport:
    machine: dict[str, str]
    seconds: float
    state_hz: list[float] = field(default_factory=list)
    camera_fps: list[float] = field(default_factory=list)
    overview_fps: list[float] = field(default_factory=list)
    camera_size: str = ""
    estop_ms: dict[str, float] = field(default_factory=dict)
    deadman_ms: dict[str, float] = field(default_factory=dict)
    tries: int = 0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def open_ws(url: str) -> ClientConnection:
    """A page's WebSocket to the dashboard at ``url``, for measuring."""
    # The stop measurements read no messages: let them queue (a few thousand), no pings.
    return connect(url.replace("http", "ws") + "ws", open_timeout=10, ping_interval=None,
                   max_queue=None)


CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu",
                  "--disable-background-networking", "--disable-component-update",
                  "--no-first-run"]


def get_json(url: str) -> dict[str, Any]:
    import urllib.request

    with urllib.request.urlopen(url, timeout=10) as reply:
        return dict(json.loads(reply.read()))


def _rates(url: str, seconds: float, report: DashboardBenchReport,
           progress: Progress) -> None:
    """Two headless Chromium pages on the dashboard (each showing the cameras); what the
    server delivered to them over ``seconds``, after a warm-up."""
    chromium, sync_playwright = browser_driver()
    moving, mover_id = threading.Event(), list[str]()
    mover = threading.Thread(target=_keep_moving, args=(url, moving, mover_id),
                             name="busarm-bench-mover")
    mover.start()  # drives first: the browsers watch
    moving.wait(10)
    try:
        _browsers(url, seconds, report, progress, chromium, sync_playwright, mover_id)
    finally:
        moving.clear()
        mover.join()


def browser_driver() -> tuple[str, Any]:
    """(Chromium's path, Playwright's ``sync_playwright``); ConfigError naming what is
    missing."""
    import shutil

    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        raise ConfigError("bench dashboard drives two browsers: it needs Playwright "
                          "(pip install -e '.[dev]')") from None
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise ConfigError("bench dashboard drives two browsers: it needs Chromium "
                          "(make browser, or apt-get install chromium)")
    return chromium, sync_playwright


def _keep_moving(url: str, moving: threading.Event, mover: list[str]) -> None:
    """The arm waves (the sample action group, again and again) while the rates are
    measured: every camera frame differs, as when a person watches a job."""
    with open_ws(url) as ws:
        mover.append(json.loads(ws.recv(timeout=10))["client"])  # its welcome
        moving.set()
        playing = False
        while moving.is_set():
            if not playing:
                ws.send('{"type": "play", "group": "wave"}')
                playing = True
            message = json.loads(ws.recv(timeout=30))
            if message["type"] == "job" and message["state"] != "running":
                playing = False
            if message["type"] == "error":
                raise RuntimeError(message["text"])
        ws.send('{"type": "stop"}')
        while playing:  # until the stopped job has ended: only then may the arm move again
            message = json.loads(ws.recv(timeout=30))
            playing = not (message["type"] == "job" and message["state"] != "running")


def _browsers(url: str, seconds: float, report: DashboardBenchReport, progress: Progress,
              chromium: str, sync_playwright: Any, not_browsers: list[str]) -> None:
    import tempfile

    with sync_playwright() as playwright, tempfile.TemporaryDirectory() as tmp:
        contexts = [playwright.chromium.launch_persistent_context(
            f"{tmp}/{k}", executable_path=chromium, headless=True, args=CHROMIUM_FLAGS,
            viewport={"width": 1280, "height": 800}) for k in range(2)]
        try:
            for context in contexts:
                context.pages[0].goto(url)
            time.sleep(WARM_UP_S)
            progress(f"two browsers on the page for {seconds:g} s...")
            before, start = get_json(url + "api/delivered"), time.monotonic()
            time.sleep(seconds)
            after, took = get_json(url + "api/delivered"), time.monotonic() - start
        finally:
            for context in contexts:
                context.close()
    report.state_hz = [round((n - before["states"].get(c, 0)) / took, 1)
                       for c, n in after["states"].items()
                       if c in before["states"] and c not in not_browsers]
    report.camera_fps = [round((n - before["frames"].get(k, 0)) / took, 1)
                         for k, n in after["frames"].items()
                         if k.startswith("wrist") and k in before["frames"]]
    report.overview_fps = [round((n - before["frames"].get(k, 0)) / took, 1)
                           for k, n in after["frames"].items()
                           if k.startswith("overview") and k in before["frames"]]


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
    with open_ws(url) as ws:
        # The waving page may not have left the seat yet (the server frees it after its
        # close): then this page watches, and takes the seat over.
        if json.loads(ws.recv(timeout=10))["role"] != "driver":  # its welcome
            ws.send('{"type": "drive", "take_over": true}')
        ws.send('{"type": "move_pose", "name": "home"}')  # the jogs stay clear of the limits
        while True:
            message = json.loads(ws.recv(timeout=30))
            if message["type"] == "error":  # refused: no job will end
                raise RuntimeError(message["text"])
            if message["type"] == "job" and message["state"] != "running":
                break
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
    with Robot.open(RobotConfig(TwinSpec(realtime=True), camera=CameraSpec(
            store=CalibrationStore.for_port(TwinSpec()))), progress=progress) as robot:
        assert robot.twin is not None
        seen: list[tuple[float, Request]] = []
        robot.twin.bus.taps.append(  # the stops only: the list is scanned while it grows
            lambda r: seen.append((time.monotonic(), r)) if r.command is Command.MOVE_STOP
            else None)
        service = RobotService(robot).start()
        feeds = robot_feeds(robot, fps=DEFAULT_FPS)  # as `busarm dashboard` streams
        report.camera_size = f"{robot.camera.width_px}x{robot.camera.height_px}"
        http = ServerThread(service, Access.for_bind("127.0.0.1"), feeds).start()
        try:
            _rates(http.url, seconds, report, progress)
            _stops(http.url, seen, tries, report, progress)
        finally:
            http.stop()
            service.close()
            for feed in feeds.values():
                feed.close()
    return report
