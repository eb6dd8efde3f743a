"""The dashboard on the twin in real time, through the real server: the e-stop halts a
running pick-and-sort (MOVE_STOP at the servos, the arm still, the job reporting what the
gripper holds and where the report is) and nothing moves again until re-armed."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from websockets.sync.client import connect

from busarm.dashboard.access import Access
from busarm.dashboard.feeds import robot_feeds
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.protocol import Command
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.spec import TwinSpec


@pytest.mark.slow
@pytest.mark.wallclock("a live dashboard server on a real-time twin sorting its table")
def test_estop_halts_a_running_pick_sort(twin_calibration: tuple[Path, Path],
                                         tmp_path: Path) -> None:
    intrinsics, hand_eye = twin_calibration
    with Robot.open(RobotConfig(TwinSpec(realtime=True, seed=3, blocks=3),
                                camera=CameraSpec(intrinsics=intrinsics,
                                                  hand_eye=hand_eye))) as robot:
        twin = robot.twin
        assert twin is not None
        stops: list[float] = []
        twin.bus.taps.append(lambda r: stops.append(time.monotonic())
                             if r.command is Command.MOVE_STOP else None)
        service = RobotService(robot, folder=tmp_path / "robot",
                               reports=tmp_path / "reports").start()
        feeds = robot_feeds(robot, fps=5)
        http = ServerThread(service, Access.for_bind("127.0.0.1"), feeds).start()
        try:
            with connect(http.url.replace("http", "ws") + "ws", open_timeout=5) as ws:
                ws.send(json.dumps({"type": "pick_sort", "colors": ["red", "green", "blue"]}))
                deadline = time.monotonic() + 60
                start = twin.joints_deg()
                while max(abs(a - b) for a, b in zip(start, twin.joints_deg(), strict=True)
                          ) < 5 and time.monotonic() < deadline:
                    time.sleep(0.05)  # until the arm is on its way to a block
                sent = time.monotonic()
                ws.send('{"type": "estop"}')
                end = None
                while end is None and time.monotonic() < deadline:
                    message = json.loads(ws.recv(timeout=10))
                    if message["type"] == "job" and message["state"] != "running":
                        end = message
                assert end is not None and end["state"] == "stopped", end
                assert "the gripper: " in end["text"] and "the report so far: " in end["text"]
                assert stops and 0 <= min(t for t in stops if t >= sent) - sent < 1.0
                held = twin.joints_deg()
                time.sleep(0.5)
                assert max(abs(a - b) for a, b in zip(held, twin.joints_deg(), strict=True)
                           ) < 0.5
                ws.send(json.dumps({"type": "move_pose", "name": "home"}))
                while True:
                    message = json.loads(ws.recv(timeout=5))
                    if message["type"] == "error":
                        assert "re-arm it first" in message["text"]
                        break
                assert (tmp_path / "reports").is_dir()
                assert list((tmp_path / "reports").glob("*/report.json"))
        finally:
            http.stop()
            service.close()
            for feed in feeds.values():
                feed.close()
