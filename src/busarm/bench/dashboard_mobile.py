"""``busarm bench dashboard --mobile``: the mobile page's rates and the base's stopping
times, on the mobile robot's twin in an arena in real time, through the real server on
127.0.0.1.

- Rates: two headless Chromium pages show the dashboard (the wrist camera streaming, the
  Lidar's scan drawn) for ``seconds``; the server counts the state and scan messages it
  delivered to each (``/api/delivered``).
- Key release: the first page drives the base with a held key (I, then K: forth and
  back), then lets go; the time from the key's release to every wheel motor told 0 (the
  twin's board, which the server never reads), ``tries`` times.
- Deadman: a driver drives over its WebSocket, repeating its twist every 100 ms as the
  page does, then falls silent: from its last message to the wheels told 0.
- E-stop: from ``estop`` sent while driving to the wheels told 0.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import asdict, dataclass, field
from typing import Any

from websockets.sync.connection import Connection

from busarm.bench.common import latency_percentiles_ms, machine_info
from busarm.bench.dashboard import CHROMIUM_FLAGS, WARM_UP_S, browser_driver, get_json, open_ws
from busarm.dashboard.access import Access
from busarm.dashboard.feeds import DEFAULT_FPS, robot_feeds
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.robot.description import RobotConfig
from busarm.robot.sim_handle import SimHandle
from busarm.sim.spec import BoardSettings
from busarm.twin.spec import TwinSpec

__all__ = [
    "ARENA",
    "DRIVE_S",
    "MobilePageReport",
    "run_mobile_page_bench",
]


ARENA = RobotConfig(TwinSpec(family="arena", seed=3, controller=BoardSettings(),
                             realtime=True))
"""The mobile robot in arena 3, behind its controller board, on the wall clock."""
DRIVE_S = 0.4
"""How long each drive lasts before its stop is measured."""
STOP_TIMEOUT_S = 3.0


@dataclass
class MobilePageReport:
    machine: dict[str, str]
    seconds: float
    state_hz: list[float] = field(default_factory=list)
    scan_hz: list[float] = field(default_factory=list)
    camera_fps: list[float] = field(default_factory=list)
    key_release_ms: dict[str, float] = field(default_factory=dict)
    deadman_ms: dict[str, float] = field(default_factory=dict)
    estop_ms: dict[str, float] = field(default_factory=dict)
    tries: int = 0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def _wheels_stopped_after(sim: SimHandle, t0: float) -> float:
    """Seconds from ``t0`` until every wheel motor is told 0 (polled every millisecond)."""
    deadline = time.monotonic() + STOP_TIMEOUT_S
    while time.monotonic() < deadline:
        targets = sim.wheel_targets_rev_s()
        if targets is not None and not any(targets):
            return time.monotonic() - t0
        time.sleep(0.001)
    raise RuntimeError(f"the wheels were not stopped within {STOP_TIMEOUT_S:g} s")


def _wheels_turning(sim: SimHandle, timeout_s: float = STOP_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while not any(sim.wheel_targets_rev_s() or ()):
        if time.monotonic() > deadline:
            raise RuntimeError("the wheels did not start: the drive was refused?")
        time.sleep(0.005)


def _pages(url: str, seconds: float, tries: int, sim: SimHandle, report: MobilePageReport,
           progress: Progress) -> None:
    chromium, sync_playwright = browser_driver()
    with sync_playwright() as playwright, tempfile.TemporaryDirectory() as tmp:
        contexts = [playwright.chromium.launch_persistent_context(
            f"{tmp}/{k}", executable_path=chromium, headless=True, args=CHROMIUM_FLAGS,
            viewport={"width": 1280, "height": 900}) for k in range(2)]
        try:
            for context in contexts:  # the first page drives
                context.pages[0].goto(url)
                context.pages[0].wait_for_selector("#base-panel:not([hidden])")
            time.sleep(WARM_UP_S)
            progress(f"two browsers on the mobile page for {seconds:g} s...")
            before, start = get_json(url + "api/delivered"), time.monotonic()
            time.sleep(seconds)
            after, took = get_json(url + "api/delivered"), time.monotonic() - start
            released = []
            page = contexts[0].pages[0]
            for k in range(tries):
                progress(f"key release {k + 1}/{tries}")
                key = "i" if k % 2 == 0 else "k"
                page.keyboard.down(key)
                _wheels_turning(sim)
                time.sleep(DRIVE_S)
                t0 = time.monotonic()
                page.keyboard.up(key)
                released.append(_wheels_stopped_after(sim, t0))
                time.sleep(0.1)
        finally:
            for context in contexts:
                context.close()
    report.key_release_ms = latency_percentiles_ms(released)
    for name, key in (("state_hz", "states"), ("scan_hz", "scans")):
        setattr(report, name, [round((n - before[key].get(c, 0)) / took, 1)
                               for c, n in after[key].items() if c in before[key]])
    report.camera_fps = [round((n - before["frames"].get(k, 0)) / took, 1)
                         for k, n in after["frames"].items()
                         if k.startswith("wrist") and k in before["frames"]]


def _drive(ws: Connection, forward: bool, seconds: float) -> float:
    """Drive as a page does, the twist again every 100 ms, for ``seconds``; when the last
    message went out."""
    text = json.dumps({"type": "base_drive", "vx_m_s": 0.2 if forward else -0.2,
                       "vy_m_s": 0.0, "wz_rad_s": 0.0})
    end = time.monotonic() + seconds
    while True:
        ws.send(text)
        sent = time.monotonic()
        if sent + 0.1 > end:
            return sent
        time.sleep(0.1)


def _stops(url: str, tries: int, sim: SimHandle, report: MobilePageReport,
           progress: Progress) -> None:
    deadman, estop = [], []
    with open_ws(url) as ws:
        if json.loads(ws.recv(timeout=10))["role"] != "driver":  # its welcome
            ws.send('{"type": "drive", "take_over": true}')
        for k in range(tries):
            progress(f"deadman and e-stop {k + 1}/{tries}")
            last = _drive(ws, k % 2 == 0, DRIVE_S)
            deadman.append(_wheels_stopped_after(sim, last))
            _drive(ws, k % 2 == 1, DRIVE_S)
            t0 = time.monotonic()
            ws.send('{"type": "estop"}')
            estop.append(_wheels_stopped_after(sim, t0))
            ws.send('{"type": "rearm"}')
            time.sleep(0.1)
    report.deadman_ms = latency_percentiles_ms(deadman)
    report.estop_ms = latency_percentiles_ms(estop)


def run_mobile_page_bench(*, seconds: float = 10.0, tries: int = 50,
                          progress: Progress = quiet) -> MobilePageReport:
    """The benchmark (see the module docstring) on a real-time arena twin."""
    report = MobilePageReport(machine_info(), seconds, tries=tries)
    progress("opening the arena twin (real time)...")
    with Robot.open(ARENA, progress=progress) as robot:
        assert robot.sim is not None
        service = RobotService(robot).start()
        feeds = robot_feeds(robot, fps=DEFAULT_FPS)  # as `busarm dashboard` streams
        http = ServerThread(service, Access.for_bind("127.0.0.1"), feeds).start()
        try:
            _pages(http.url, seconds, tries, robot.sim, report, progress)
            _stops(http.url, tries, robot.sim, report, progress)
        finally:
            http.stop()
            service.close()
            for feed in feeds.values():
                feed.close()
    return report
