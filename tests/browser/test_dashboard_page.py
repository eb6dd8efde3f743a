"""The dashboard's page in a real browser, against a real `busarm dashboard` on the twin.

One server for the module (the `dashboard` fixture); each test opens a fresh browser and
takes the driver's seat. The arm's joints are read through GET /api/state, not the page,
so a page that shows the wrong thing cannot pass for one that moves the arm. The jogs
turn the base back and forth, which keeps it far from its limits and off the table.

BUSARM_DASHBOARD_SCREENSHOT=1 also writes the page's picture to docs/dashboard.png.
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlencode, urlsplit

import pytest
from playwright.sync_api import Page, WebSocketRoute, expect

from browser.conftest import Dashboard, running_dashboard

DOCS_PICTURE = Path(__file__).resolve().parents[2] / "docs" / "dashboard.png"
JOINT = "base_yaw"
STILL_DEG = 0.5


@pytest.fixture(autouse=True)
def no_script_errors(page: Page) -> Iterator[list[str]]:
    """Every test fails on an uncaught error in the page's script (pages a test opens
    itself add theirs to this list)."""
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    yield errors
    assert not errors, errors


def page_url(dashboard: Dashboard, cameras: bool = False) -> str:
    """The page's link, with the dashboard's token if it has one; cameras off unless
    asked (each costs the twin a render 15 times a second)."""
    query = {"token": dashboard.token} if dashboard.token else {}
    return f"{dashboard.base}?{urlencode({**query, **({} if cameras else {'cameras': 'off'})})}"


def open_page(page: Page, dashboard: Dashboard, cameras: bool = False) -> None:
    """Open the page, wait for the live state, take the driver's seat and make sure the
    robot is not stopped."""
    page.goto(page_url(dashboard, cameras))
    expect(page.locator("#conn")).to_have_attribute("data-state", "connected")
    expect(page.locator("#state-count")).not_to_have_text("0")
    role = page.locator("#role")
    if role.get_attribute("data-role") != "driver":  # a previous test's page not gone yet
        seat = page.locator("#drive") if page.locator("#drive").is_visible() else (
            page.locator("#take-over"))
        seat.click()
    expect(role).to_have_text("you drive")
    if dashboard.api("state")["halted"] is not None:
        page.locator("#rearm").click()
        wait_for(lambda: dashboard.api("state")["halted"] is None, "the robot re-armed")


def wait_for(check: object, what: str, timeout_s: float = 5.0) -> None:
    assert callable(check)
    end = time.monotonic() + timeout_s
    while not check():
        if time.monotonic() > end:
            pytest.fail(f"{what}: not within {timeout_s} s")
        time.sleep(0.05)


def joint_deg(dashboard: Dashboard, name: str = JOINT) -> float:
    names = [j["name"] for j in dashboard.api("robot")["joints"]]
    return float(dashboard.api("state")["joints_deg"][names.index(name)])


def still_deg(dashboard: Dashboard, name: str = JOINT, timeout_s: float = 5.0) -> float:
    """The joint once it has stopped: two reads 0.5 s apart within 0.5 deg; fails if it
    keeps moving for ``timeout_s`` (a busy computer slows the twin, so a stop's last
    fraction of a degree may come late in wall time)."""
    end = time.monotonic() + timeout_s
    a = joint_deg(dashboard, name)
    while True:
        time.sleep(0.5)
        b = joint_deg(dashboard, name)
        if abs(b - a) <= STILL_DEG:
            return b
        assert time.monotonic() < end, (
            f"{name} still moving after {timeout_s} s: {a:.2f} -> {b:.2f}")
        a = b


def hold(page: Page, selector: str, seconds: float) -> None:
    """Press the mouse on ``selector``, hold it ``seconds``, release it there."""
    page.locator(selector).hover()
    page.mouse.down()
    page.wait_for_timeout(seconds * 1000)
    page.mouse.up()


def jog_button(joint: str, direction: int) -> str:
    return f'[data-jog="joint:{joint}:{direction:+d}"]'


def test_page_shows_live_values(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    robot = dashboard.api("robot")
    expect(page.locator("#robot-name")).to_have_text(robot["name"])
    cells = page.locator("[data-joint]")
    expect(cells).to_have_count(len(robot["joints"]))
    count = int(page.locator("#state-count").inner_text())
    page.wait_for_function(  # live: ~25 a second (the rate itself is the benchmark's)
        f"() => Number(document.querySelector('#state-count').textContent) > {count + 3}",
        timeout=5000)
    for j in robot["joints"]:
        value = float(page.locator(f'[data-joint="{j["name"]}"]').inner_text())
        assert j["min_deg"] <= value <= j["max_deg"]
    for axis in ("x", "y", "z", "pitch"):
        float(page.locator(f'[data-axis="{axis}"]').inner_text())
    float(page.locator("#gripper-gap").inner_text())
    expect(page.locator("#gripper-state")).to_have_text(re.compile("open|closed|holding|moving"))
    expect(page.locator("#servos tbody tr")).to_have_count(len(robot["servo_ids"]))
    expect(page.locator("[data-torque]").first).to_have_text("on")
    for pose in robot["poses"]:
        expect(page.locator(f'[data-pose="{pose}"]')).to_be_visible()
    expect(page.locator("#group-select option")).to_have_count(len(robot["groups"]))
    expect(page.locator("#log")).to_contain_text("drives")
    for view in ("#arm-top", "#arm-side"):  # the arm is drawn from links_mm
        drawn = page.evaluate(
            """sel => { const c = document.querySelector(sel);
                 const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
                 let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i]) n++; return n; }""",
            view)
        assert drawn > 500, f"{view}: {drawn} pixels drawn"
    expect(page.locator("#halted-banner")).to_be_hidden()


def test_holding_a_jog_button_moves_the_joint_and_releasing_stops_it(
    page: Page, dashboard: Dashboard
) -> None:
    open_page(page, dashboard)
    before = still_deg(dashboard)
    hold(page, jog_button(JOINT, +1), 1.0)
    after = still_deg(dashboard)
    assert after - before >= 5, f"{JOINT} {before:.1f} -> {after:.1f} deg for 1 s held"
    shown = page.locator(f'[data-joint="{JOINT}"]')
    expect(shown).to_have_text(f"{after:.1f}")


def test_leaving_the_button_while_held_stops_the_jog(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    before = still_deg(dashboard)
    page.locator(jog_button(JOINT, -1)).hover()
    page.mouse.down()
    page.wait_for_timeout(600)
    page.mouse.move(640, 10)  # off the button, still pressed
    try:
        moved = still_deg(dashboard)
    finally:
        page.mouse.up()
    assert before - moved >= 3, f"{JOINT} {before:.1f} -> {moved:.1f} deg"


def test_holding_a_key_jogs_and_releasing_it_stops(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    expect(page.locator("#keys-help")).to_contain_text(JOINT)
    before = still_deg(dashboard)
    page.keyboard.down("a")  # base_yaw -
    page.wait_for_timeout(1000)
    page.keyboard.up("a")
    after = still_deg(dashboard)
    assert before - after >= 5, f"{JOINT} {before:.1f} -> {after:.1f} deg for 1 s held"


def test_losing_focus_stops_a_held_key(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    before = still_deg(dashboard)
    page.keyboard.down("q")  # base_yaw +
    try:
        page.wait_for_timeout(600)
        page.evaluate("window.dispatchEvent(new Event('blur'))")  # another window's turn
        moved = still_deg(dashboard)  # stopped, the key still down
    finally:
        page.keyboard.up("q")
    assert moved - before >= 3, f"{JOINT} {before:.1f} -> {moved:.1f} deg"


def test_estop_button_halts_and_jogs_are_refused_until_rearmed(
    page: Page, dashboard: Dashboard
) -> None:
    open_page(page, dashboard)
    page.locator("#estop").click()
    wait_for(lambda: dashboard.api("state")["halted"] is not None, "/api/state halted")
    banner = page.locator("#halted-banner")
    expect(banner).to_be_visible()
    expect(banner).to_contain_text("STOPPED: e-stop from page")
    before = still_deg(dashboard)
    hold(page, jog_button(JOINT, +1), 0.6)
    toast = page.locator('[data-testid="error-toast"][data-request="jog"]')
    expect(toast.first).to_contain_text("re-arm it first")
    assert abs(still_deg(dashboard) - before) <= STILL_DEG
    page.locator("#rearm").click()
    wait_for(lambda: dashboard.api("state")["halted"] is None, "/api/state not halted")
    expect(banner).to_be_hidden()
    hold(page, jog_button(JOINT, +1), 0.6)
    assert still_deg(dashboard) - before >= 3


def test_a_second_page_watches_and_takes_over_explicitly(
    page: Page, dashboard: Dashboard, no_script_errors: list[str]
) -> None:
    open_page(page, dashboard)
    watcher = page.context.new_page()
    watcher.on("pageerror", lambda exc: no_script_errors.append(str(exc)))
    try:
        watcher.goto(page_url(dashboard))
        expect(watcher.locator("#conn")).to_have_attribute("data-state", "connected")
        driver_id = dashboard.api("state")["driver"]
        expect(watcher.locator("#role")).to_have_text(f"watching (page {driver_id} drives)")
        expect(watcher.locator("#take-over")).to_be_visible()
        before = still_deg(dashboard)
        hold(watcher, jog_button(JOINT, -1), 0.6)
        toast = watcher.locator('[data-testid="error-toast"][data-request="jog"]')
        expect(toast.first).to_contain_text("this page watches")
        assert abs(still_deg(dashboard) - before) <= STILL_DEG

        watcher.locator("#take-over").click()
        expect(watcher.locator("#role")).to_have_text("you drive")
        # /api/state is the newest tick's: the take-over is in it a tick later.
        wait_for(lambda: dashboard.api("state")["driver"] != driver_id, "the new driver")
        new_id = dashboard.api("state")["driver"]
        expect(page.locator("#role")).to_have_text(f"watching (page {new_id} drives)")
        hold(watcher, jog_button(JOINT, -1), 0.6)
        assert before - still_deg(dashboard) >= 3

        # The page that now watches may still stop the robot; the driver re-arms it.
        page.locator("#estop").click()
        wait_for(lambda: dashboard.api("state")["halted"] is not None, "halted by a watcher")
        expect(watcher.locator("#halted-banner")).to_be_visible()
        watcher.locator("#rearm").click()
        wait_for(lambda: dashboard.api("state")["halted"] is None, "re-armed by the driver")
    finally:
        watcher.close()


def test_poses_groups_gripper_and_torque_controls(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    # A pose saved from the page comes back as a button (the server's `robot` message).
    page.locator("#pose-name").fill("browser_pose")
    page.locator("#save-pose").click()
    expect(page.locator('[data-pose="browser_pose"]')).to_be_visible()
    # An action group recorded from the page: start, one frame, save; it can be chosen.
    page.locator("#rec-start").click()
    expect(page.locator("#rec-frames")).to_have_text("recording: 0 frames")
    page.locator("#rec-duration").fill("500")
    page.locator("#rec-frame").click()
    expect(page.locator("#rec-frames")).to_have_text("recording: 1 frame")
    page.locator("#rec-name").fill("browser_group")
    page.locator("#rec-save").click()
    expect(page.locator("#rec-frames")).to_have_text("not recording")
    expect(page.locator('#group-select option[value="browser_group"]')).to_have_count(1)
    # A bad name is refused by the server, and the page says so.
    page.locator("#rec-start").click()
    page.locator("#rec-name").fill("no spaces")
    page.locator("#rec-save").click()
    expect(page.locator('[data-testid="error-toast"][data-request="record"]').first
           ).to_contain_text("expected 1..64 letters")
    page.locator("#rec-cancel").click()
    # The gripper: a job, shown while it runs and when it is done.
    page.locator("#grip-close").click()
    expect(page.locator("#job-last")).to_contain_text("gripper close done", timeout=15_000)
    expect(page.locator("#gripper-state")).to_have_text(re.compile("closed|holding"))
    page.locator("#grip-open").click()
    expect(page.locator("#job-last")).to_contain_text("gripper open done", timeout=15_000)
    expect(page.locator("#gripper-state")).to_have_text("open")
    # Torque of the gripper's servo: off (limp), then on again, as read back.
    gripper = dashboard.api("robot")["gripper_id"]
    torque = page.locator(f'[data-torque="{gripper}"]')
    expect(torque).to_have_text("on")
    torque.click()
    expect(torque).to_have_text("off")
    torque.click()
    expect(torque).to_have_text("on")


def test_escape_key_is_the_estop(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    page.locator("#pose-name").click()  # even while typing in a field
    page.keyboard.press("Escape")
    wait_for(lambda: dashboard.api("state")["halted"] is not None, "/api/state halted")
    expect(page.locator("#halted-banner")).to_be_visible()
    page.locator("#rearm").click()
    wait_for(lambda: dashboard.api("state")["halted"] is None, "/api/state not halted")
    expect(page.locator("#halted-banner")).to_be_hidden()


def test_pick_sort_runs_stops_and_links_its_report(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    page.locator('#pick-colors input[data-color="blue"]').uncheck()
    page.locator("#pick-run").click()
    expect(page.locator("#job")).to_contain_text("pick-sort: ", timeout=20_000)
    page.locator("#job-stop").click()
    expect(page.locator("#job-last")).to_contain_text("pick-sort stopped", timeout=15_000)
    link = page.locator("#report-link")
    expect(link).to_be_visible()
    href = link.get_attribute("href")
    assert href is not None and href.endswith("/report.json")
    name = href.split("/")[2]
    assert (dashboard.reports / name / "report.json").is_file()
    report = page.request.get(f"{dashboard.base.rstrip('/')}{href}")
    assert report.ok and report.json()["stopped"], report.text()
    page.locator('[data-pose="look"]').click()  # where it started, the blocks in view
    expect(page.locator("#job-last")).to_contain_text("move to look done", timeout=15_000)


def test_sorting_by_size_without_bins_for_the_classes_is_refused_and_nothing_stops(
        page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    page.locator("#pick-by").select_option("size")
    page.locator("#pick-run").click()  # the twin's trays are named for colours
    expect(page.locator("#toasts")).to_contain_text(
        "sorting by size needs a bin named as a size class (small, medium, large)")
    assert dashboard.api("state")["halted"] is None and dashboard.api("state")["job"] is None


def test_page_reconnects_after_a_lost_connection(page: Page, dashboard: Dashboard) -> None:
    sockets: list[tuple[WebSocketRoute, WebSocketRoute]] = []

    def through(ws: WebSocketRoute) -> None:  # the page's socket, passed on to the server
        sockets.append((ws, ws.connect_to_server()))

    page.route_web_socket(lambda url: urlsplit(url).path == "/ws", through)
    open_page(page, dashboard)
    to_page, to_server = sockets[-1]
    to_server.close(code=1000)  # the connection is lost, at both ends
    to_page.close(code=1011, reason="cut by the test")
    conn = page.locator("#conn")
    expect(conn).to_contain_text("connection lost (cut by the test): retrying")
    expect(page.locator("#role")).to_have_text("not connected")
    expect(conn).to_have_attribute("data-state", "connected")
    assert len(sockets) == 2
    expect(page.locator("#role")).to_have_text("you drive")  # the seat was free again
    count = int(page.locator("#state-count").inner_text())
    expect(page.locator("#state-count")).not_to_have_text(str(count))


def test_the_token_goes_on_to_the_socket_and_the_cameras(
    page: Page, dashboard_config_home: Path, tmp_path: Path
) -> None:
    token = "a-token-for-the-browser-test"
    with running_dashboard(dashboard_config_home, tmp_path, "--token", token) as dashboard:
        assert dashboard.token == token
        sockets: list[str] = []
        page.on("websocket", lambda ws: sockets.append(ws.url))
        with page.expect_response(
                lambda r: urlsplit(r.url).path == "/camera/wrist.mjpg") as camera:
            open_page(page, dashboard, cameras=True)
        page.locator("#cameras-toggle").uncheck()  # no renders for the rest of the test
        assert sockets and all(f"token={token}" in url for url in sockets), sockets
        assert f"token={token}" in camera.value.url
        assert camera.value.status == 200  # the stream began: the token was accepted


def test_page_with_cameras_at_1280x800(
    page: Page, dashboard: Dashboard, tmp_path: Path
) -> None:
    page.set_viewport_size({"width": 1280, "height": 800})
    open_page(page, dashboard, cameras=True)
    for camera in dashboard.api("robot")["cameras"]:
        img = page.locator(f"#cam-{camera}")
        expect(img).to_be_visible()
        page.wait_for_function(
            "sel => document.querySelector(sel).naturalWidth > 0", arg=f"#cam-{camera}",
            timeout=30_000)  # a first frame can take seconds
    page.wait_for_timeout(500)
    picture = page.screenshot()
    assert picture.startswith(b"\x89PNG")
    (tmp_path / "dashboard.png").write_bytes(picture)
    if os.environ.get("BUSARM_DASHBOARD_SCREENSHOT"):
        DOCS_PICTURE.write_bytes(picture)
