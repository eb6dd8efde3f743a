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
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from browser.conftest import Dashboard

DOCS_PICTURE = Path(__file__).resolve().parents[2] / "docs" / "dashboard.png"
JOINT = "base_yaw"
STILL_DEG = 0.5


def open_page(page: Page, dashboard: Dashboard, query: str = "cameras=off") -> None:
    """Open the page (cameras off unless asked: they cost the twin renders), wait for the
    live state, take the driver's seat and make sure the robot is not stopped."""
    page.goto(f"{dashboard.url}?{query}")
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


def still_deg(dashboard: Dashboard, name: str = JOINT) -> float:
    """The joint once it has stopped: two reads 0.5 s apart within 0.5 deg (after a short
    settling); fails if it keeps moving."""
    time.sleep(0.3)
    a = joint_deg(dashboard, name)
    time.sleep(0.5)
    b = joint_deg(dashboard, name)
    assert abs(b - a) <= STILL_DEG, f"{name} still moving after the release: {a:.2f} -> {b:.2f}"
    return b


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
    page.wait_for_timeout(300)
    assert int(page.locator("#state-count").inner_text()) > count + 3  # ~25 a second
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
    page: Page, dashboard: Dashboard
) -> None:
    open_page(page, dashboard)
    watcher = page.context.new_page()
    try:
        watcher.goto(f"{dashboard.url}?cameras=off")
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
        new_id = dashboard.api("state")["driver"]
        assert new_id != driver_id
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


def test_escape_key_is_the_estop(page: Page, dashboard: Dashboard) -> None:
    open_page(page, dashboard)
    page.locator("#pose-name").click()  # even while typing in a field
    page.keyboard.press("Escape")
    wait_for(lambda: dashboard.api("state")["halted"] is not None, "/api/state halted")
    expect(page.locator("#halted-banner")).to_be_visible()
    page.locator("#rearm").click()
    wait_for(lambda: dashboard.api("state")["halted"] is None, "/api/state not halted")
    expect(page.locator("#halted-banner")).to_be_hidden()


def test_page_with_cameras_at_1280x800(
    page: Page, dashboard: Dashboard, tmp_path: Path
) -> None:
    page.set_viewport_size({"width": 1280, "height": 800})
    open_page(page, dashboard, query="")
    for camera in dashboard.api("robot")["cameras"]:
        img = page.locator(f"#cam-{camera}")
        expect(img).to_be_visible()
        page.wait_for_function(
            "sel => document.querySelector(sel).naturalWidth > 0", arg=f"#cam-{camera}",
            timeout=20_000)
    page.wait_for_timeout(500)
    picture = page.screenshot()
    assert picture.startswith(b"\x89PNG")
    (tmp_path / "dashboard.png").write_bytes(picture)
    if os.environ.get("BUSARM_DASHBOARD_SCREENSHOT"):
        DOCS_PICTURE.write_bytes(picture)
