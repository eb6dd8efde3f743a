"""The dashboard's mobile jobs through the real server (uvicorn on 127.0.0.1, HTTP and
WebSocket clients) on the mobile robot's twin in an arena, in real time.

Transport is started from a page: its progress arrives as ``job`` messages, the map as
``GET /map.png`` (its number in the state); a stop ends it, the job says it stopped, and
the chassis (the twin's truth) stands still and stays so; the robot may move again."""

from __future__ import annotations

import json
import math
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from websockets.sync.client import ClientConnection, connect

from busarm.dashboard.access import Access
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.sim.spec import BoardSettings
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

pytestmark = [pytest.mark.slow, pytest.mark.wallclock(
    "a live dashboard server on a real-time twin in an arena")]

SEED = 3
STILL_M_S = 0.005
STILL_RAD_S = 0.01


def chassis_speed(twin: Twin) -> tuple[float, float]:
    """The chassis's true speed: (m/s, |rad/s|)."""
    assert twin.mobile is not None
    with twin.lock:
        vx, vy, wz = twin.mobile.speed(twin.data)
    return math.hypot(vx, vy), abs(wz)


def next_message(ws: ClientConnection, kind: str, deadline: float, **fields: Any
                 ) -> dict[str, Any]:
    """The next message of ``kind`` with ``fields`` (others skipped) before ``deadline``."""
    while True:
        left = deadline - time.monotonic()
        try:
            if left <= 0:
                raise TimeoutError
            message: dict[str, Any] = json.loads(ws.recv(timeout=left))
        except TimeoutError:
            raise AssertionError(f"no {kind} message with {fields} in time") from None
        if message["type"] == kind and all(message.get(k) == v for k, v in fields.items()):
            return message


def map_picture(url: str) -> np.ndarray:
    """The dashboard's current map picture (a PNG of at least 300 px, numbered >= 2)."""
    with urllib.request.urlopen(url + "map.png", timeout=5) as reply:
        assert reply.headers["Content-Type"] == "image/png"
        assert int(reply.headers["X-Map-Sequence"]) >= 2
        picture = cv2.imdecode(np.frombuffer(reply.read(), np.uint8), cv2.IMREAD_COLOR)
    assert picture is not None and min(picture.shape[:2]) >= 300
    return picture


@pytest.fixture
def served(twin_calibration: tuple[Path, Path], tmp_path: Path
           ) -> Iterator[tuple[str, Robot, Twin]]:
    intrinsics, hand_eye = twin_calibration
    world = TwinSpec(family="arena", seed=SEED, realtime=True, controller=BoardSettings())
    with Robot.open(RobotConfig(world, camera=CameraSpec(intrinsics=intrinsics,
                                                         hand_eye=hand_eye))) as robot:
        assert robot.twin is not None and robot.base is not None
        service = RobotService(robot, folder=tmp_path / "robot",
                               reports=tmp_path / "reports").start()
        http = ServerThread(service, Access.for_bind("127.0.0.1"), {}).start()
        try:
            yield http.url, robot, robot.twin
        finally:
            http.stop()
            service.close()


def test_transport_runs_shows_its_map_and_stops_with_the_wheels(
        served: tuple[str, Robot, Twin]) -> None:
    url, robot, twin = served
    with connect(url.replace("http", "ws") + "ws", open_timeout=5, max_queue=None) as ws:
        welcome = next_message(ws, "welcome", time.monotonic() + 5)
        assert welcome["robot"]["mobile"]["points"] == ["pick", "place"]
        # Refused before anything moves: each names the bad value and what is allowed.
        ws.send(json.dumps({"type": "transport", "pick": "shelf"}))
        refused = next_message(ws, "error", time.monotonic() + 5)
        assert refused["text"] == "transport: pick = 'shelf': no such point; points: pick, place"
        ws.send(json.dumps({"type": "line_follow", "laps": 500}))
        refused = next_message(ws, "error", time.monotonic() + 5)
        assert refused["text"] == "line_follow: laps = 500; allowed: a number 0.05..100"

        ws.send(json.dumps({"type": "transport"}))
        deadline = time.monotonic() + 40
        progress = next_message(ws, "job", deadline, name="transport", state="running")
        assert progress["text"] == "no map yet: exploring the arena to map it"
        next_message(ws, "job", deadline, name="transport", state="running")  # exploring...
        while True:  # two pictures in: the base has been driving a second at least
            state = next_message(ws, "state", deadline)
            if state["map"] >= 2 and chassis_speed(twin)[0] > 0.05:
                break
        # The path driven is drawn on the map (a loaded machine's real-time twin may
        # have driven only a few cm by now: the next pictures must show more of it).
        path_blue = 0
        while path_blue <= 20 and time.monotonic() < deadline:
            picture = map_picture(url)
            path_blue = np.all(picture == (200, 120, 0), axis=2).sum()  # PATH_BGR
            time.sleep(0.2)
        assert path_blue > 20, "no path driven drawn on the map"

        ws.send(json.dumps({"type": "stop"}))
        end = next_message(ws, "job", time.monotonic() + 10, name="transport",
                           state="stopped")
        assert end["text"].startswith("transport: stopped (stop from page ")
        time.sleep(0.5)  # the wheels' own deceleration (the firmware's ramp) is over
        for _ in range(10):  # and they stay stopped: nothing drives them again
            speed_m_s, turn_rad_s = chassis_speed(twin)
            assert speed_m_s < STILL_M_S and turn_rad_s < STILL_RAD_S, (speed_m_s, turn_rad_s)
            time.sleep(0.1)
        assert robot.arm.bus.halted is None  # a stop is not latched: it may move again
        # A state sent just before the job ended may still be on its way (a loaded
        # machine): the next ones say no job runs.
        state = next_message(ws, "state", time.monotonic() + 5, job=None)
        assert "job" in state and state["job"] is None
