"""The dashboard's mobile side through the real server (uvicorn on 127.0.0.1, HTTP and
WebSocket clients), on simulated robots: a robot without a base refuses the mobile jobs
and has no map; on a controller board the e-stop latches the wheels as well as the
servos (the simulated board's wheel targets are the truth), until the re-arm. The
command: a twin behind a board runs in real time, and bad mobile options are one error
before the robot is opened."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from websockets.sync.client import ClientConnection, connect

from busarm.cli.robot_options import with_realtime
from busarm.dashboard.access import Access
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.errors import HaltedError
from busarm.robot import BaseSpec, Robot, RobotConfig
from busarm.robot.port_url import parse_port
from busarm.sim.board import SimBoard
from busarm.sim.spec import BoardSettings, SimSpec
from busarm.sim.transport import SimTransport

LIVE = pytest.mark.wallclock(
    "a live dashboard server: a real-time robot, its page's heartbeats and watchdogs")


@pytest.fixture
def board_robot() -> Iterator[Robot]:
    # Live, as `busarm dashboard` opens it: on a simulated clock the page's watchdogs and
    # the base's would race through time the moment anything waits.
    with Robot.open(RobotConfig(SimSpec(realtime=True, controller=BoardSettings()),
                                base=BaseSpec("jetauto"))) as robot:
        yield robot


@pytest.fixture
def plain_robot() -> Iterator[Robot]:
    # Live, as `busarm dashboard` opens it.
    with Robot.open(RobotConfig(SimSpec(realtime=True))) as robot:
        yield robot


def serve(robot: Robot, tmp_path: Path) -> tuple[RobotService, ServerThread]:
    service = RobotService(robot, folder=tmp_path / "robot",
                           reports=tmp_path / "reports").start()
    return service, ServerThread(service, Access.for_bind("127.0.0.1"), {}).start()


def ws_of(http: ServerThread) -> ClientConnection:
    return connect(http.url.replace("http", "ws") + "ws", open_timeout=5, max_queue=None)


def receive(ws: ClientConnection, kind: str, timeout_s: float = 5.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout_s
    while True:
        message: dict[str, Any] = json.loads(ws.recv(timeout=deadline - time.monotonic()))
        if message["type"] == kind:
            return message


def wheel_targets(robot: Robot) -> list[float]:
    """What the simulated board's wheel motors were last told (rev/s)."""
    transport = robot.arm.bus.transport
    assert isinstance(transport, SimTransport) and isinstance(transport.bus, SimBoard)
    return [w.target_rev_s for w in transport.bus.wheels]


@LIVE
def test_a_robot_without_a_base_refuses_the_mobile_jobs(plain_robot: Robot,
                                                         tmp_path: Path) -> None:
    service, http = serve(plain_robot, tmp_path)
    try:
        with ws_of(http) as ws:
            assert receive(ws, "welcome")["robot"]["mobile"] is None
            assert receive(ws, "state")["map"] is None
            for request in ({"type": "transport"}, {"type": "line_follow", "laps": 2}):
                ws.send(json.dumps(request))
                refused = receive(ws, "error")
                assert refused["request"] == request["type"]
                assert refused["text"].startswith(
                    f"{request['type']}: this robot has no base and Lidar; open the "
                    "dashboard on one (--port board://twin?family=arena&seed=N")
            ws.send(json.dumps({"type": "transport", "pick": "a", "place": "a"}))
            assert receive(ws, "error")["text"] == (
                "transport: pick and place are both 'a'; give two different points")
        with pytest.raises(urllib.error.HTTPError) as missing:
            urllib.request.urlopen(http.url + "map.png", timeout=5)
        assert missing.value.code == 404
        assert json.load(missing.value) == {"error": "no map: this robot has no base and Lidar"}
        assert service.last_state["job"] is None
    finally:
        http.stop()
        service.close()


@LIVE
def test_the_estop_latches_the_wheels_until_rearmed(board_robot: Robot,
                                                     tmp_path: Path) -> None:
    base = board_robot.base
    assert base is not None
    service, http = serve(board_robot, tmp_path)
    try:
        with ws_of(http) as ws:
            receive(ws, "welcome")
            base.drive(0.1, 0.0, 0.0)  # as a job's thread drives it
            assert any(wheel_targets(board_robot))
            ws.send('{"type": "estop"}')
            receive(ws, "log")
            assert wheel_targets(board_robot) == [0.0] * 4
            with pytest.raises(HaltedError, match=r"wheel speeds refused: the robot is halted "
                                                  r"\(e-stop from page p\d+\); re-arm it first"):
                base.drive(0.1, 0.0, 0.0)
            assert wheel_targets(board_robot) == [0.0] * 4
            base.stop()  # a stop still goes out
            ws.send('{"type": "rearm"}')
            deadline = time.monotonic() + 5
            while board_robot.arm.bus.halted is not None and time.monotonic() < deadline:
                time.sleep(0.01)
            base.drive(0.1, 0.0, 0.0)
            assert any(wheel_targets(board_robot))
            base.stop()
    finally:
        http.stop()
        service.close()


@LIVE
def test_base_drive_is_checked_held_and_stopped_through_the_server(
        board_robot: Robot, plain_robot: Robot, tmp_path: Path) -> None:
    """The base's requests from a page: refused (named value, range) with nothing sent to
    the wheels; a drive reaches the wheels and base_stop stops them; heartbeats alone do
    not keep it going; refused while a job runs and while halted; a point named without a
    map refused."""
    service, http = serve(board_robot, tmp_path)
    try:
        with ws_of(http) as ws:
            robot = receive(ws, "welcome")["robot"]
            assert robot["base"]["max_speed_m_s"] == 0.4 and robot["bins"] == []
            for request, said in (
                    ({"vx_m_s": 0.9}, "base_drive: vx = 0.9 m/s is beyond the chassis's "
                                      "limit; allowed: -0.4..0.4 m/s"),
                    ({"wz_rad_s": -3}, "base_drive: wz = -171.887 deg/s is beyond the "
                                       "chassis's limit; allowed: -120..120 deg/s"),
                    ({"vx_m_s": 0.4, "vy_m_s": 0.4}, "base_drive: vx 0.4 m/s, vy 0.4 m/s and "
                     "wz 0 deg/s together need a wheel at 2.64 rev/s; the wheels turn at most "
                     "1.5 rev/s (in this direction at most 57% as fast)"),
                    ({"vy_m_s": "fast"}, 'base_drive: vy_m_s = "fast"; allowed: a number '
                                         "-1000..1000"),
                    ({"spin": 1}, "base_drive: unknown field(s) spin; allowed: vx_m_s, "
                                  "vy_m_s, wz_rad_s")):
                ws.send(json.dumps({"type": "base_drive", **request}))
                assert receive(ws, "error")["text"] == said
                assert wheel_targets(board_robot) == [0.0] * 4
            ws.send('{"type": "base_drive", "vx_m_s": 0.2}')
            deadline = time.monotonic() + 5
            while not any(wheel_targets(board_robot)) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert any(wheel_targets(board_robot))
            deadline = time.monotonic() + 5
            while (driving := receive(ws, "state")["base"]["driving"]) is None:
                assert time.monotonic() < deadline, "no state says the base drives"
            assert driving["vx_m_s"] == 0.2  # (states sent before the drive came first)
            ws.send('{"type": "base_stop"}')
            while "base stopped (released)" not in receive(ws, "log")["text"]:
                pass  # "base: driving at ..." first
            assert wheel_targets(board_robot) == [0.0] * 4
            # Heartbeats alone (a key-up lost, a page whose script failed): the wheels stop.
            ws.send('{"type": "base_drive", "vx_m_s": -0.2}')
            deadline = time.monotonic() + 5
            while not any(wheel_targets(board_robot)) and time.monotonic() < deadline:
                time.sleep(0.01)
            assert any(wheel_targets(board_robot))
            for _ in range(10):
                ws.send('{"type": "heartbeat"}')
                time.sleep(0.1)
            assert wheel_targets(board_robot) == [0.0] * 4
            assert any(e["text"] == "base stopped (no drive from the driver for 250 ms)"
                       for e in service.log_lines)
            ws.send('{"type": "play", "group": "wave"}')
            receive(ws, "job")
            ws.send('{"type": "base_drive", "vx_m_s": 0.2}')
            assert receive(ws, "error")["text"] == (
                "base_drive: play sample wave is running: stop it first")
            assert wheel_targets(board_robot) == [0.0] * 4
            ws.send('{"type": "stop"}')
            ws.send('{"type": "estop"}')
            ws.send('{"type": "base_drive", "vx_m_s": 0.2}')
            assert receive(ws, "error")["text"].startswith("base_drive: the robot is stopped")
            assert wheel_targets(board_robot) == [0.0] * 4
            ws.send('{"type": "name_point", "name": "shelf", "x_m": 1, "y_m": 2}')
            assert receive(ws, "error")["text"].startswith("name_point: no map yet")
    finally:
        http.stop()
        service.close()
    service, http = serve(plain_robot, tmp_path / "plain")
    try:
        with ws_of(http) as ws:
            assert receive(ws, "welcome")["robot"]["base"] is None
            ws.send('{"type": "base_drive", "vx_m_s": 0.1}')
            assert receive(ws, "error")["text"].startswith("base_drive: this robot has no base")
    finally:
        http.stop()
        service.close()


ARENA = "board://twin?family=arena&seed=3"


@pytest.mark.parametrize(("port", "realtime"), [
    ("board://twin", "board://twin?realtime=1"),
    (ARENA, ARENA + "&realtime=1"),
    (ARENA + "&realtime=1", ARENA + "&realtime=1"),
    ("twin", "twin://?realtime=1"),
    ("sim", "sim://?realtime=1"),
    ("board://sim?encoders=0", "board://sim?encoders=0&realtime=1"),
    ("sim://?realtime=1", "sim://?realtime=1"),
    ("/dev/ttyUSB0", "/dev/ttyUSB0"),
    ("board:///dev/ttyACM0", "board:///dev/ttyACM0"),
])
def test_the_dashboard_runs_a_twin_behind_a_board_in_real_time(port: str,
                                                               realtime: str) -> None:
    assert with_realtime(parse_port(port)) == parse_port(realtime)


@pytest.mark.parametrize(("args", "said"), [
    (["--seed", "2"], f"error: --port {ARENA}: a twin behind the board stands in an arena "
                      "(family=arena&seed=N), not at a table: leave out "
                      "--scene/--seed/--blocks/--colors"),
    (["--points", "{bad}"], "error: points file {bad}: not valid TOML: "),
    (["--map", "{map}"], "error: --map without --points: the named points on that map are "
                         "needed"),
])
def test_bad_mobile_options_are_one_error_before_the_robot_opens(
        tmp_path: Path, args: list[str], said: str) -> None:
    bad, map_file = tmp_path / "points.toml", tmp_path / "map.yaml"
    bad.write_text("not toml\n")
    map_file.write_text("image: map.pgm\n")
    fill = {"bad": str(bad), "map": str(map_file)}
    done = subprocess.run(
        [sys.executable, "-m", "busarm", "--port", ARENA, "dashboard", "--http-port", "0",
         *(a.format(**fill) for a in args)],
        capture_output=True, text=True, timeout=60,
        env={**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "config")})
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith(said.format(**fill)), done.stderr
    assert len(done.stderr.splitlines()) == 1, done.stderr  # no twin, no calibration
    assert done.stdout == ""
