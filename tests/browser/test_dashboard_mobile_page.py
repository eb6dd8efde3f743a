"""The dashboard's Mobile panel in a real browser, against a real `busarm dashboard` on the
mobile robot's twin in an arena (``--port board://twin?family=arena&seed=3``).

Transport is started from the panel; the map picture arrives (the wrist camera streams),
the job's progress lines under them; the panel's Stop ends the job and the page says so.

BUSARM_DASHBOARD_SCREENSHOT=1 also writes the panel's picture to
docs/dashboard-mobile.png, once the job drives to the pick point (a longer run).
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from browser.conftest import Dashboard, running_dashboard
from browser.test_dashboard_page import open_page, wait_for

DOCS_PICTURE = Path(__file__).resolve().parents[2] / "docs" / "dashboard-mobile.png"
ARENA_PORT = "board://twin?family=arena&seed=3"
DOCS_WAIT_S = 150.0
"""For the docs' picture: how long the exploring may take before the drive to the pick."""


@pytest.fixture
def mobile_dashboard(dashboard_config_home: Path, tmp_path: Path) -> Iterator[Dashboard]:
    with running_dashboard(dashboard_config_home, tmp_path, "--port", ARENA_PORT) as d:
        yield d


def test_mobile_panel_runs_transport_shows_the_map_and_stops(
    mobile_dashboard: Dashboard, page: Page, tmp_path: Path
) -> None:
    # The dashboard first: the browser (its camera streams) ends before the server does.
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.set_viewport_size({"width": 1280, "height": 800})
    open_page(page, mobile_dashboard, cameras=True)
    panel = page.locator("#mobile")
    expect(panel).to_be_visible()
    expect(page.locator("#tr-pick")).to_have_value("pick")
    expect(page.locator("#tr-place")).to_have_value("place")

    page.locator("#tr-run").click()
    progress = page.locator("#mobile-progress")
    expect(progress).to_contain_text("exploring to map the arena", timeout=20_000)
    page.wait_for_function(  # a map drawn by the job (the first one is the placeholder)
        """() => { const img = document.querySelector('#map-view');
                   return Number(img.dataset.map) >= 2 && img.naturalWidth > 300; }""",
        timeout=20_000)
    assert mobile_dashboard.api("state")["job"]["name"] == "transport"
    if os.environ.get("BUSARM_DASHBOARD_SCREENSHOT"):
        expect(progress).to_contain_text("drive to pick", timeout=DOCS_WAIT_S * 1000)
        page.wait_for_timeout(3000)  # the plan and the drive under way on the map
    page.wait_for_function(
        "() => document.querySelector('#cam-wrist').naturalWidth > 0", timeout=30_000)
    picture = panel.screenshot()
    assert picture.startswith(b"\x89PNG")
    (tmp_path / "dashboard-mobile.png").write_bytes(picture)
    if os.environ.get("BUSARM_DASHBOARD_SCREENSHOT"):
        DOCS_PICTURE.write_bytes(picture)

    page.locator("#cameras-toggle").uncheck()  # no renders for the rest of the test
    page.locator("#mobile-stop").click()
    expect(page.locator("#job-last")).to_contain_text("transport stopped: transport: stopped",
                                                      timeout=15_000)
    expect(progress.locator("li.stopped")).to_contain_text("stopped (stop from page")
    wait_for(lambda: mobile_dashboard.api("state")["job"] is None, "no job running")
    assert mobile_dashboard.api("state")["halted"] is None  # a stop is not latched
    shown = page.locator("#map-view").get_attribute("data-map")
    time.sleep(2.5)  # no job: no new map pictures
    assert page.locator("#map-view").get_attribute("data-map") == shown
    assert not errors, errors
