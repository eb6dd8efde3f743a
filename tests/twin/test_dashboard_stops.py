"""A person's stop of a dashboard job (pick-sort, transport, line following, play) is
reported as a stop, not as a failure (issue 30): at the service
(busarm.dashboard.service), its job thread, the job's end message and its report, on
twins (and a simulated arm) of their own, on the simulated clock; the service's control
thread is not started: nothing here needs the page's state.

The stop reaches a job as the dashboard's Stop does: the bus halted (``stop`` halts it,
then sets the job's cancel event). Here the halt comes at the moment the job says what it
starts on (in its own thread, before any cancel): the job must end "stopped" from the
halt alone, with its report so far, which says so in the halt's words.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from busarm.base.odometry import Pose2D
from busarm.dashboard.mobile import MobileSetup
from busarm.dashboard.protocol import parse_request
from busarm.dashboard.service import RobotService
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.map_files import save_map
from busarm.nav.points import NamedPoint, NamedPoints, save_points
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.sim.spec import BoardSettings, SimSpec
from busarm.twin.spec import TwinSpec

WHY = "stop from page p1"


def stopped_at(service: RobotService, request: str, when: Callable[[str], bool]
               ) -> dict[str, Any]:
    """Run ``request`` from page p1, halting the bus at its first progress ``when`` says;
    the job's last message."""
    ended: list[dict[str, Any]] = []
    done = threading.Event()

    def page(text: str) -> None:
        msg = json.loads(text)
        if msg["type"] != "job":
            return
        if msg["state"] == "running" and when(msg["text"]) and service.arm.bus.halted is None:
            service.arm.bus.halt(WHY)  # (the job's thread: its next write meets it)
        elif msg["state"] != "running":
            ended.append(msg)
            done.set()

    service.subscribe("p1", page)
    service.handle("p1", parse_request(request, service.names))
    assert done.wait(120), "the job did not end"
    for thread in threading.enumerate():  # its thread frees its renderers after its end
        if thread.name.startswith("busarm-job-"):
            thread.join(timeout=10)
    return ended[0]


def calibrated(world: TwinSpec, calibration: tuple[Path, Path]) -> RobotConfig:
    return RobotConfig(world, camera=CameraSpec(intrinsics=calibration[0],
                                                hand_eye=calibration[1]))


def report_of(text: str) -> dict[str, Any]:
    """The report.json the end message names (``the report so far: PATH``)."""
    path = Path(text.split("the report so far: ")[1].split(";")[0])
    data: dict[str, Any] = json.loads(path.read_text())
    return data


def test_a_stopped_pick_sort_is_stopped_and_its_report_says_by_what(
        tmp_path: Path, twin_calibration: tuple[Path, Path]) -> None:
    with Robot.open(calibrated(TwinSpec(seed=3, blocks=3), twin_calibration)) as robot:
        service = RobotService(robot, folder=tmp_path / "robot", reports=tmp_path / "reports")
        try:
            end = stopped_at(service, '{"type": "pick_sort"}', lambda t: "into its bin" in t)
        finally:
            service.close()
    assert end["state"] == "stopped", end
    assert end["text"].startswith(f"pick-sort: stopped ({WHY}); the gripper: "), end
    data = report_of(end["text"])
    assert f"the robot is halted ({WHY})" in data["stopped"], data["stopped"]
    assert not data["stopped"].startswith("HaltedError")  # a stop, not an error
    assert data["totals"]["sorted"] >= 1


def test_a_stopped_transport_is_stopped_even_before_its_cancel(
        tmp_path: Path, twin_calibration: tuple[Path, Path]) -> None:
    """The halt before the cancel (as ``stop`` sends them): the job once took it for a
    failure ("not delivered") when it noticed the halt first."""
    free = np.full((120, 120), -3.0)  # (the job is stopped before it looks at the room)
    save_map(tmp_path / "room.yaml", OccupancyGrid(GridSpec(-3.0, -3.0, 0.05, 120, 120), free))
    points = NamedPoints("room", {"pick": NamedPoint("pick", Pose2D(1.0, 0.0, 0.0)),
                                  "place": NamedPoint("place", Pose2D(0.0, 1.0, 0.0))})
    save_points(tmp_path / "points.toml", points, "room.yaml")
    world = TwinSpec(family="arena", seed=1, controller=BoardSettings())
    with Robot.open(calibrated(world, twin_calibration)) as robot:
        service = RobotService(robot, folder=tmp_path / "robot", reports=tmp_path / "reports",
                               mobile=MobileSetup(tmp_path / "points.toml"))
        try:
            end = stopped_at(service, '{"type": "transport"}', lambda t: t == "stow the arm...")
            assert robot.base is not None and robot.base.command.is_zero
        finally:
            service.close()
    assert end["state"] == "stopped", end
    assert end["text"].startswith(f"transport: stopped ({WHY}); the report so far: "), end
    data = report_of(end["text"])
    assert not data["delivered"] and f"the robot is halted ({WHY})" in data["why"], data
    assert [(p["name"], p["ok"]) for p in data["phases"]] == [("stow the arm", False)]


def test_a_stopped_line_follow_is_stopped_and_its_report_says_by_what(
        tmp_path: Path, twin_calibration: tuple[Path, Path]) -> None:
    world = TwinSpec(family="arena", seed=1, controller=BoardSettings())
    with Robot.open(calibrated(world, twin_calibration)) as robot:
        service = RobotService(robot, folder=tmp_path / "robot", reports=tmp_path / "reports")
        try:
            end = stopped_at(service, '{"type": "line_follow"}',
                             lambda t: t.endswith("following the line"))
            assert robot.base is not None and robot.base.command.is_zero
        finally:
            service.close()
    assert end["state"] == "stopped", end
    assert end["text"].startswith(f"line follow: stopped ({WHY}); the report so far: "), end
    data = report_of(end["text"])
    assert not data["finished"] and f"the robot is halted ({WHY})" in data["why"], data


def test_a_stopped_play_is_stopped(tmp_path: Path) -> None:
    with Robot.open(RobotConfig(SimSpec())) as robot:
        service = RobotService(robot, folder=tmp_path / "robot", reports=tmp_path / "reports")
        try:
            end = stopped_at(service, '{"type": "play", "group": "nod"}',
                             lambda t: t.startswith("frame 2 of"))
        finally:
            service.close()
    assert end["state"] == "stopped" and end["text"] == f"play sample nod: stopped ({WHY})", end
