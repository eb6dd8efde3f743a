"""Driving the mobile base from the dashboard's page, in a real browser, against a real
server on the mobile robot's twin in an arena (real time, in this process: the twin's
truth is read here, never through the page or the server).

The page draws the Lidar's scan before any map exists; a held key drives the base (the
twin's true pose moves), letting go stops the wheels, a frozen page stops them through
the server's deadman, the e-stop stops them and stays stopped until re-armed; with a
map, a click on it names a point that lands in the points file and in transport's lists.

BUSARM_DASHBOARD_SCREENSHOT=1 also writes the base panel's picture to
docs/dashboard-base.png.
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from busarm.base.odometry import Pose2D, wrap_rad
from busarm.dashboard.access import Access
from busarm.dashboard.mobile import MobileSetup
from busarm.dashboard.server import ServerThread
from busarm.dashboard.service import RobotService
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.map_files import load_map, save_map
from busarm.nav.map_picture import picture_frame
from busarm.nav.points import NamedPoint, NamedPoints, load_points, save_points
from busarm.robot import Robot, RobotConfig

ARENA = "board://twin?family=arena&seed=3&realtime=1"
DOCS_PICTURE = Path(__file__).resolve().parents[2] / "docs" / "dashboard-base.png"
MOVED_M = 0.05
MOVED_RAD = 0.15


@pytest.fixture(scope="module")
def arena_robot() -> Iterator[Robot]:
    with Robot.open(RobotConfig.from_port(ARENA)) as robot:
        yield robot


def serve(robot: Robot, folder: Path, mobile: MobileSetup | None = None
          ) -> tuple[RobotService, ServerThread]:
    service = RobotService(robot, folder=folder / "robot", reports=folder / "reports",
                           mobile=mobile).start()
    try:
        return service, ServerThread(service, Access.for_bind("127.0.0.1"), {}).start()
    except BaseException:
        service.close()
        raise


def open_driving(page: Page, url: str) -> None:
    page.set_viewport_size({"width": 1280, "height": 900})
    page.goto(url + "?cameras=off")
    expect(page.locator("#role")).to_have_text("you drive")
    expect(page.locator("#base-panel")).to_be_visible()


def wait_for(page: Page, check: Callable[[], bool], what: str, timeout_s: float = 5.0) -> None:
    """Wait for ``check()`` (the twin's truth) while the page runs: waiting through
    Playwright, whose socket routes (the conftest's guard) carry the page's messages
    only while its client is being waited on."""
    end = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > end:
            pytest.fail(f"{what}: not within {timeout_s} s")
        page.wait_for_timeout(20)


def stopped(robot: Robot) -> bool:
    """The wheels told to stop, and the chassis (truth) still."""
    assert robot.sim is not None
    targets, speed = robot.sim.wheel_targets_rev_s(), robot.sim.base_velocity()
    assert targets is not None and speed is not None
    return not any(targets) and math.hypot(speed[0], speed[1]) < 0.01 and abs(speed[2]) < 0.02


def moved(robot: Robot, start: Pose2D) -> bool:
    """Whether the base has truly gone MOVED_M or turned MOVED_RAD from ``start``."""
    assert robot.sim is not None
    now = robot.sim.base_pose()
    assert now is not None
    return (math.dist((now.x_m, now.y_m), (start.x_m, start.y_m)) > MOVED_M
            or abs(wrap_rad(now.yaw_rad - start.yaw_rad)) > MOVED_RAD)


def drive_with_key(page: Page, robot: Robot, key: str) -> None:
    """Hold ``key`` until the twin's base has truly moved (keeps it held)."""
    assert robot.sim is not None
    start = robot.sim.base_pose()
    assert start is not None
    page.keyboard.down(key)
    wait_for(page, lambda: moved(robot, start), f"the base moving on key {key}")


def test_the_page_drives_the_base_and_every_stop_stops_it(
        arena_robot: Robot, page: Page, tmp_path: Path) -> None:
    service, http = serve(arena_robot, tmp_path)
    try:
        open_driving(page, http.url)
        # The scan, live, with no map and no job.
        page.wait_for_function(
            "() => Number(document.querySelector('#scan-view').dataset.scans) >= 5")
        assert int(page.locator("#scan-view").get_attribute("data-points") or 0) > 50
        assert service.describe()["mobile"]["map"] is False
        expect(page.locator("#base-limits")).to_contain_text("0.40 m/s, 120 deg/s")
        expect(page.locator("#pick-panel")).to_be_hidden()  # no bins in an arena
        expect(page.locator("#pick-none")).to_contain_text("no bins")

        # A held key drives; the odometry on the page follows; letting go stops.
        assert arena_robot.sim is not None
        page.keyboard.down("Shift")  # a modifier: the page still drives on I
        page.keyboard.up("Shift")
        drive_with_key(page, arena_robot, "i")
        expect(page.locator("#odom-x")).not_to_have_text("0.000")
        page.keyboard.up("i")
        wait_for(page, lambda: stopped(arena_robot), "the wheels stopped on release")
        if os.environ.get("BUSARM_DASHBOARD_SCREENSHOT"):
            DOCS_PICTURE.write_bytes(page.locator("#base-panel").screenshot())

        # A page that falls silent (its script paused: no heartbeat, no repeat): the
        # server's deadman stops the wheels; the key is still down.
        turn_start = arena_robot.sim.base_pose()
        assert turn_start is not None
        drive_with_key(page, arena_robot, "j")
        cdp = page.context.new_cdp_session(page)
        cdp.send("Debugger.enable")
        cdp.send("Debugger.pause")
        wait_for(page, lambda: stopped(arena_robot), "the wheels stopped by the deadman")
        assert any("no drive from the driver for 250 ms" in e["text"]
                   for e in service.log_lines)
        cdp.send("Debugger.resume")
        page.keyboard.up("j")

        # E-stop while driving: the wheels stop and stay stopped until the re-arm.
        drive_with_key(page, arena_robot, "u")
        page.locator("#estop").click()
        expect(page.locator("#halted-banner")).to_be_visible()
        wait_for(page, lambda: stopped(arena_robot), "the wheels stopped by the e-stop")
        page.keyboard.up("u")
        page.keyboard.down("i")
        page.wait_for_timeout(500)
        assert stopped(arena_robot), "a halted base drove"
        expect(page.locator("[data-testid=error-toast]").first).to_contain_text("re-arm")
        page.keyboard.up("i")
        page.locator("#rearm").click()
        expect(page.locator("#halted-banner")).to_be_hidden()
    finally:
        http.stop()
        service.close()
    assert stopped(arena_robot)


def arena_map(robot: Robot, folder: Path) -> MobileSetup:
    """The arena's map drawn from its truth (its walls and boxes; the tables, which the
    Lidar sees as legs, left out), in the arena's frame, and two points on it, as `busarm
    map build` and `busarm map point` leave them."""
    assert robot.sim is not None and robot.sim.arena is not None
    arena, res = robot.sim.arena, 0.05
    room = arena.room
    spec = GridSpec.covering(room.x_min_m - 0.3, room.x_max_m + 0.3, room.y_min_m - 0.3,
                             room.y_max_m + 0.3, res)
    x, y = np.meshgrid(spec.origin_x_m + (np.arange(spec.width) + 0.5) * res,
                       spec.origin_y_m + (np.arange(spec.height) + 0.5) * res)
    occupied = ~((x > room.x_min_m) & (x < room.x_max_m) & (y > room.y_min_m)
                 & (y < room.y_max_m))
    for box in arena.boxes:
        c, s = math.cos(math.radians(box.yaw_deg)), math.sin(math.radians(box.yaw_deg))
        u, v = (x - box.x_m) * c + (y - box.y_m) * s, -(x - box.x_m) * s + (y - box.y_m) * c
        occupied |= (abs(u) < box.size_x_m / 2) & (abs(v) < box.size_y_m / 2)
    save_map(folder / "room.yaml", OccupancyGrid(spec, np.where(occupied, 3.0, -3.0)))
    points = NamedPoints("room", {n: NamedPoint(n, Pose2D(x_m, 0.0, 0.0)) for n, x_m in
                                  (("pick", 0.5), ("place", 2.0))})
    save_points(folder / "points.toml", points, "room.yaml")
    return MobileSetup(folder / "points.toml")


def click_map(page: Page, map_file: Path, x_m: float, y_m: float) -> None:
    """Click the page's map where (x_m, y_m) is drawn (the picture fitted, centred)."""
    box = page.locator("#map-view").bounding_box()
    assert box is not None
    frame = picture_frame(load_map(map_file))
    u, v = frame.pixel(x_m, y_m)
    k = min(box["width"] / frame.width_px, box["height"] / frame.height_px)
    page.locator("#map-view").click(position={
        "x": (box["width"] - k * frame.width_px) / 2 + k * u,
        "y": (box["height"] - k * frame.height_px) / 2 + k * v})


def test_a_click_on_the_map_names_a_point_and_finds_the_base(
        arena_robot: Robot, page: Page, tmp_path: Path) -> None:
    service, http = serve(arena_robot, tmp_path, arena_map(arena_robot, tmp_path))
    try:
        open_driving(page, http.url)
        expect(page.locator("#map-view")).to_have_class("clickable", timeout=15_000)
        click_map(page, tmp_path / "room.yaml", 0.5, 1.0)
        page.locator("#point-name").fill("shelf")
        page.locator("#point-yaw").fill("90")
        page.locator("#point-save").click()
        expect(page.locator("#tr-place option[value=shelf]")).to_have_count(1)
        saved = load_points(tmp_path / "points.toml")
        shelf = saved.points["shelf"].pose
        assert abs(shelf.x_m - 0.5) < 0.03 and abs(shelf.y_m - 1.0) < 0.03, shelf
        assert abs(shelf.yaw_deg - 90.0) < 0.01
        assert set(saved.points) == {"pick", "place", "shelf"}
        assert saved.map_path is not None and saved.map_path.name == "room.yaml"
        click_map(page, tmp_path / "room.yaml", 1.0, 0.5)
        page.locator("#point-name").fill("no good!")
        page.locator("#point-save").click()
        expect(page.locator("[data-testid=error-toast]").first).to_contain_text("no good!")
        room = arena_robot.sim.arena.room if arena_robot.sim and arena_robot.sim.arena else None
        assert room is not None
        click_map(page, tmp_path / "room.yaml", room.x_min_m - 0.15, 0.0)  # in the wall
        page.locator("#point-name").fill("wall")
        page.locator("#point-save").click()
        expect(page.locator("[data-testid=error-toast]").last).to_contain_text(
            "is occupied on the map")
        assert set(load_points(tmp_path / "points.toml").points) == {"pick", "place", "shelf"}

        # Where the base is, from a person's rough guess (0.2 m, 15 deg off): the map
        # then shows the base; checked against the twin's truth.
        page.locator("#localise").click()  # no guess and no job before: refused
        expect(page.locator("[data-testid=error-toast]").last).to_contain_text(
            "click the map where it stands")
        assert arena_robot.sim is not None
        truth = arena_robot.sim.base_pose()
        assert truth is not None
        click_map(page, tmp_path / "room.yaml", truth.x_m + 0.15, truth.y_m - 0.1)
        page.locator("#point-yaw").fill(str(round(truth.yaw_deg + 15)))
        guess = page.locator("#point-at").text_content()  # what the page took the click for
        page.locator("#base-here").click()
        expect(page.locator("#job-last")).to_contain_text("localise done", timeout=20_000)
        said = re.search(r"x ([-+.\d]+) m, y ([-+.\d]+) m, ([-+\d]+) deg",
                         page.locator("#job-last").text_content() or "")
        assert said is not None
        found = Pose2D(float(said[1]), float(said[2]), math.radians(float(said[3])))
        now = arena_robot.sim.base_pose()
        assert math.dist((found.x_m, found.y_m), (truth.x_m, truth.y_m)) < 0.1, (
            found, truth, now, guess)
        assert abs(math.degrees(wrap_rad(found.yaw_rad - truth.yaw_rad))) < 5, (
            found, truth, now, guess)
        expect(page.locator("#map-caption")).to_contain_text("click a spot")
    finally:
        http.stop()
        service.close()
