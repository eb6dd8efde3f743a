"""The dashboard's server through the real path: uvicorn on 127.0.0.1, HTTP and WebSocket
clients, the simulated arm behind it (its servos' own positions are the truth).

Bad input, a second driver, a missing or wrong token, a page of another site: each is
refused with a clear message, the arm does not move, and the server keeps serving.
The deadman (a lost heartbeat), a jog, stop and e-stop are checked on the arm itself.
"""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from busarm.dashboard.access import Access
from busarm.dashboard.feeds import Feed
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import JOG_HOLD_S, RobotService
from busarm.protocol import Command, Request
from busarm.protocol.lx_units import DEG_PER_PULSE
from busarm.robot import Robot, RobotConfig
from busarm.sim.spec import SimSpec
from busarm.sim.transport import SimTransport
from busarm.vision.camera import CameraBase

pytestmark = pytest.mark.wallclock(
    "a live dashboard server: a real-time robot, its page's heartbeats and watchdogs")

TOKEN = "a-token-of-thirty-two-characters"
LIVE_SIM = RobotConfig(SimSpec(realtime=True))
"""The simulated arm, live (on the wall clock), as `busarm dashboard` opens it."""


@dataclass
class Server:
    url: str
    service: RobotService
    robot: Robot
    requests: list[tuple[float, Request]]

    def ws(self, query: str = "", **kwargs: Any) -> ClientConnection:
        # Every message is taken in, as a page does (max_queue None): with the client's
        # default bound, a test that reads nothing for a second stops reading the socket,
        # and its close then waits 10 s for the server's close frame it cannot see.
        return connect(self.url.replace("http", "ws") + "ws" + query, open_timeout=5,
                       max_queue=None, **kwargs)

    def servo_deg(self, servo_id: int) -> float:
        """Where the simulated servo is (the truth, not what the page was told)."""
        transport = self.robot.arm.bus.transport
        assert isinstance(transport, SimTransport)
        transport.bus.advance()
        return transport.bus.servo(servo_id).position_pulses * DEG_PER_PULSE


def _serve(tmp_path: Path, access: Access) -> Iterator[Server]:
    robot = Robot.open(LIVE_SIM)
    service = RobotService(robot, folder=tmp_path / "robot", reports=tmp_path / "reports")
    transport = robot.arm.bus.transport
    assert isinstance(transport, SimTransport)
    seen: list[tuple[float, Request]] = []
    transport.bus.taps.append(lambda r: seen.append((time.monotonic(), r)))
    service.start()
    http = ServerThread(service, access, {}).start()
    try:
        yield Server(http.url, service, robot, seen)
    finally:
        http.stop()
        service.close()
        robot.close()


@pytest.fixture
def server(tmp_path: Path) -> Iterator[Server]:
    yield from _serve(tmp_path, Access.for_bind("127.0.0.1"))


@pytest.fixture
def guarded(tmp_path: Path) -> Iterator[Server]:
    """Rules of a dashboard bound off loopback (the token required), served on loopback:
    the tests reach nothing but 127.0.0.1."""
    yield from _serve(tmp_path, Access("192.0.2.10", TOKEN))


def receive(ws: ClientConnection, kind: str, timeout_s: float = 3.0,
            saying: str = "") -> dict[str, Any]:
    """The next message of ``kind`` (whose text has ``saying``; others skipped)."""
    deadline = time.monotonic() + timeout_s
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            raise AssertionError(f"no {kind} message in {timeout_s} s")
        message = json.loads(ws.recv(timeout=left))
        if message["type"] == kind and saying in message.get("text", ""):
            return dict(message)


def fresh_state(ws: ClientConnection) -> dict[str, Any]:
    """A state read after now (the ones queued before are skipped)."""
    after = time.time()
    while True:
        state = receive(ws, "state")
        if state["t"] > after:
            return state


def moves(server: Server) -> list[str]:
    """The motion commands that reached the servos."""
    motion = {Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE, Command.MOVE_START,
              Command.LOAD_OR_UNLOAD_WRITE}
    return [r.command.name for _, r in server.requests if r.command in motion]


def test_state_streams_and_the_first_page_drives(server: Server) -> None:
    with server.ws() as ws:
        welcome = receive(ws, "welcome")
        assert welcome["role"] == "driver"
        assert [j["name"] for j in welcome["robot"]["joints"]][:2] == [
            "base_yaw", "shoulder_pitch"]
        first = fresh_state(ws)
        start, n = time.monotonic(), 0
        while n < 30:
            last = receive(ws, "state")
            n += 1
        rate = n / (time.monotonic() - start)
        assert rate > 10, rate  # 25 Hz nominal; the benchmark measures it properly
        assert set(first["tool"]) == {"x_mm", "y_mm", "z_mm", "pitch_deg"}
        assert first["gripper"]["state"] in ("open", "closed", "holding", "moving")
        # The slow values take turns (one a period): all read within about a second.
        assert [s["id"] for s in last["servos"]] == [1, 2, 3, 4, 5, 10]
        assert all(s["vin_v"] == pytest.approx(11.1, abs=1) and s["temp_c"] is not None
                   and s["torque"] in (True, False) for s in last["servos"]), last["servos"]
        assert first["halted"] is None and first["driver"] == welcome["client"]
    with urllib.request.urlopen(server.url + "api/state", timeout=5) as reply:
        assert json.loads(reply.read())["type"] == "state"


@pytest.mark.parametrize(("text", "says"), [
    ("not json", "not JSON"),
    ("[1, 2]", "expected a JSON object"),
    ('{"type": "fly"}', 'type "fly": unknown; allowed: heartbeat'),
    ('{"type": "jog", "joint": "elbow_pitch", "direction": 2}', "direction = 2; allowed: 1, -1"),
    ('{"type": "jog", "joint": "knee", "direction": 1}', 'joint = "knee"; allowed: base_yaw'),
    ('{"type": "jog", "axis": "x", "direction": 1, "speed": 7}',
     "speed = 7; allowed: a number 0.05..1"),
    ('{"type": "move_pose", "name": "nowhere"}', "no pose named 'nowhere'"),
    ('{"type": "torque", "servo": 99, "on": false}', "servo 99 is not one of this arm's"),
    ('{"type": "play", "group": "../../etc/passwd"}', "expected 1..64 letters"),
    ('{"type": "gripper", "action": "crush"}', 'action = "crush"; allowed: open, close'),
    ('{"type": "rearm"}', "the robot is not stopped"),
    ('{"type": "pick_sort", "by": "weight"}', 'by = "weight"; allowed: color, size, tag'),
    ("x" * 5000, "at most 4096"),
])
def test_bad_requests_are_refused_and_nothing_moves(server: Server, text: str,
                                                    says: str) -> None:
    with server.ws() as ws:
        receive(ws, "welcome")
        before = len(moves(server))
        ws.send(text)
        error = receive(ws, "error")
        assert says in error["text"], error
        ws.send('{"type": "heartbeat"}')  # still serving this page
        assert fresh_state(ws)["halted"] is None
    assert len(moves(server)) == before


def test_binary_and_flooded_messages_are_refused_and_the_server_goes_on(server: Server) -> None:
    with server.ws() as ws:
        receive(ws, "welcome")
        ws.send(b"\x55\x55\x01\x03\x0c\xef")  # bytes, not a request
        assert "binary messages are not requests" in receive(ws, "error")["text"]
        for _ in range(200):  # a page gone wrong: every one answered, none moves the arm
            ws.send('{"type": "jog", "joint": "base_yaw", "direction": 0}')
        for _ in range(200):
            assert "direction = 0" in receive(ws, "error")["text"]
    assert moves(server) == []
    with server.ws() as ws:
        assert receive(ws, "welcome")["role"] == "driver"


def test_a_second_page_watches_and_takes_over_only_explicitly(server: Server) -> None:
    with server.ws() as driver, server.ws() as watcher:
        first, second = receive(driver, "welcome"), receive(watcher, "welcome")
        assert (first["role"], second["role"]) == ("driver", "watcher")
        before = len(moves(server))
        watcher.send(json.dumps({"type": "jog", "joint": "base_yaw", "direction": 1}))
        assert f"page {first['client']} drives (take over to drive)" in receive(
            watcher, "error")["text"]
        watcher.send('{"type": "drive"}')
        assert "take over explicitly" in receive(watcher, "error")["text"]
        assert len(moves(server)) == before
        watcher.send('{"type": "drive", "take_over": true}')
        assert receive(driver, "role")["driver"] == second["client"]
        driver.send('{"type": "gripper", "action": "open"}')
        assert "this page watches" in receive(driver, "error")["text"]


def test_a_held_jog_moves_the_joint_and_a_lost_heartbeat_stops_it(server: Server) -> None:
    with server.ws() as ws:
        receive(ws, "welcome")
        start = server.servo_deg(1)
        ws.send(json.dumps({"type": "jog", "joint": "base_yaw", "direction": 1, "speed": 1}))
        for _ in range(8):  # held for 0.8 s, heartbeats every 100 ms
            time.sleep(0.1)
            ws.send('{"type": "heartbeat"}')
        assert abs(server.servo_deg(1) - start) > 10  # 30 deg/s for 0.8 s
        sent_last = time.monotonic()  # the page freezes: no heartbeat
        receive(ws, "log", timeout_s=2, saying="no heartbeat from the driver for 300 ms")
        stopped_after = time.monotonic() - sent_last
        # Not before the hold ran out; how soon after is the benchmark's (bench dashboard).
        assert stopped_after >= JOG_HOLD_S, stopped_after
        stop = [t for t, r in server.requests if r.command is Command.MOVE_STOP]
        assert stop and JOG_HOLD_S <= stop[-1] - sent_last <= 2.0
        time.sleep(0.2)
        held = server.servo_deg(1)
        time.sleep(0.5)
        assert abs(server.servo_deg(1) - held) < 0.5  # stopped, holding


def test_released_jog_stops_at_once(server: Server) -> None:
    with server.ws() as ws:
        receive(ws, "welcome")
        ws.send(json.dumps({"type": "jog", "joint": "base_yaw", "direction": -1}))
        for _ in range(3):
            time.sleep(0.1)
            ws.send('{"type": "heartbeat"}')
        released = time.monotonic()  # before the send: the stop may reach the servos first
        ws.send('{"type": "jog_stop"}')
        receive(ws, "log", saying="(released)")
        stops = [t for t, r in server.requests if r.command is Command.MOVE_STOP]
        assert stops and 0 <= stops[-1] - released < 1.0  # the figure: bench dashboard


def test_estop_halts_until_rearmed(server: Server) -> None:
    with server.ws() as ws, server.ws() as watcher:
        receive(ws, "welcome")
        receive(watcher, "welcome")
        ws.send(json.dumps({"type": "move_pose", "name": "home"}))
        time.sleep(0.3)
        sent = time.monotonic()
        watcher.send('{"type": "estop"}')  # anyone may stop the robot
        job = receive(ws, "job")
        while job["state"] == "running":
            job = receive(ws, "job")
        assert job["state"] == "stopped", job
        stops = [t for t, r in server.requests if r.command is Command.MOVE_STOP and t >= sent]
        assert stops and stops[0] - sent < 1.0  # the figure: bench dashboard
        held = [server.servo_deg(s) for s in (2, 3)]
        assert fresh_state(ws)["halted"].startswith("e-stop from page")
        ws.send(json.dumps({"type": "jog", "joint": "base_yaw", "direction": 1}))
        assert "re-arm it first" in receive(ws, "error")["text"]
        time.sleep(0.3)
        assert [server.servo_deg(s) for s in (2, 3)] == pytest.approx(held, abs=0.5)
        watcher.send('{"type": "rearm"}')  # re-arming is the driver's
        assert "this page watches" in receive(watcher, "error")["text"]
        ws.send('{"type": "rearm"}')
        receive(ws, "log", saying="re-armed")
        assert fresh_state(ws)["halted"] is None


def test_the_driver_leaving_stops_a_job(server: Server) -> None:
    with server.ws() as watcher:
        receive(watcher, "welcome")
        with server.ws() as ws:
            client = receive(ws, "welcome")["client"]
            watcher.send('{"type": "release"}')
            assert receive(watcher, "role")["driver"] is None
            ws.send('{"type": "drive"}')
            assert receive(watcher, "role")["driver"] == client
            ws.send(json.dumps({"type": "move_pose", "name": "home"}))
            time.sleep(0.2)
        job = receive(watcher, "job")
        while job["state"] == "running":
            job = receive(watcher, "job")
        assert job["state"] == "stopped", job
        assert fresh_state(watcher)["halted"] is None  # a stop, not an e-stop


def test_token_required_off_loopback(guarded: Server) -> None:
    for url in (guarded.url, guarded.url + "api/state", guarded.url + "?token=wrong-token"):
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(url, timeout=5)
        assert refused.value.code == 403
        assert b"token" in refused.value.read()
    with pytest.raises(InvalidStatus):
        guarded.ws().close()
    with urllib.request.urlopen(guarded.url + f"?token={TOKEN}", timeout=5) as reply:
        assert reply.status == 200
        assert f"busarm_token={TOKEN}" in reply.headers["set-cookie"]
        assert "samesite=strict" in reply.headers["set-cookie"].lower()
    request = urllib.request.Request(guarded.url + "api/robot",
                                     headers={"Authorization": f"Bearer {TOKEN}"})
    with urllib.request.urlopen(request, timeout=5) as reply:
        assert json.loads(reply.read())["name"]
    with guarded.ws(f"?token={TOKEN}") as ws:
        assert receive(ws, "welcome")["role"] == "driver"


def test_pages_of_other_sites_and_rebound_hosts_are_refused(server: Server) -> None:
    with pytest.raises(InvalidStatus):
        server.ws(origin="http://evil.example").close()  # type: ignore[arg-type]
    request = urllib.request.Request(server.url, headers={"Host": "evil.example:8000"})
    with pytest.raises(urllib.error.HTTPError) as refused:
        urllib.request.urlopen(request, timeout=5)
    assert refused.value.code == 403
    with server.ws(origin=server.url.rstrip("/")) as ws:  # type: ignore[arg-type]
        assert receive(ws, "welcome")["role"] == "driver"


class SlowCamera(CameraBase):
    """A camera whose first frame takes longer than a viewer's wait (a twin's first render
    under load), then 20 frames a second."""

    def __init__(self) -> None:
        super().__init__("slow", 64, 48)
        self.first = True

    def _grab(self) -> npt.NDArray[np.uint8]:
        time.sleep(2.5 if self.first else 0.05)
        self.first = False
        return np.full((48, 64, 3), 90, np.uint8)

    def _release(self) -> None:
        pass


def test_a_camera_streams_as_mjpeg_even_when_its_first_frame_is_slow(tmp_path: Path) -> None:
    robot = Robot.open(LIVE_SIM)
    service = RobotService(robot, folder=tmp_path / "robot").start()
    feed = Feed("wrist", SlowCamera(), fps=20)
    http = ServerThread(service, Access.for_bind("127.0.0.1"), {"wrist": feed}).start()
    try:
        with urllib.request.urlopen(http.url + "camera/wrist.mjpg", timeout=10) as stream:
            assert stream.headers["content-type"].startswith("multipart/x-mixed-replace")
            data = b""
            while data.count(b"Content-Type: image/jpeg") < 4:
                chunk = stream.read1(65536)
                assert chunk, f"the stream ended after {data.count(b'image/jpeg')} frames"
                data += chunk
        jpeg = data[data.index(b"\r\n\r\n") + 4:]
        image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
        assert image is not None and image.shape == (48, 64, 3)
        with pytest.raises(urllib.error.HTTPError) as missing:
            urllib.request.urlopen(http.url + "camera/overview.mjpg", timeout=5)
        assert missing.value.code == 404 and b"cameras: wrist" in missing.value.read()
    finally:
        http.stop()
        feed.close()
        service.close()
        robot.close()
