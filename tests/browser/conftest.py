"""Real-browser fixtures: Debian's headless chromium driven by Playwright's sync API.

`make browser` installs chromium (`make test` depends on it); never `playwright install`,
whose browser download is not reachable from our machines or CI. A missing chromium fails
the test, never skips it.

The browser may reach 127.0.0.1 only: every other request is aborted before it is sent
(the context's route guard), and a request the guard cannot see (the browser's own
traffic) goes to a dead proxy on 127.0.0.1 instead of the network. A page that asks for
another address (a CDN's script, a web font) fails its test at teardown, naming the URLs.

    def test_title(page: Page, served: str) -> None:   # `served`: a URL on 127.0.0.1
        page.goto(served)
        expect(page.locator("h1")).to_have_text("busarm")

While Playwright runs (from this folder's first test to its last, see `playwright`), its
event loop counts as running in the main thread: asyncio.run() there fails, so run servers
under test (uvicorn) in their own thread.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import pytest
from playwright.sync_api import (
    BrowserContext,
    Page,
    Playwright,
    Route,
    WebSocketRoute,
    sync_playwright,
)

from conftest import keep_twin_calibration

CHROMIUM = "/usr/bin/chromium"
ALLOWED_HOST = "127.0.0.1"
# Our standard flags. Playwright passes --headless, --no-sandbox (needed as root),
# --disable-background-networking, --disable-component-update and --no-first-run itself
# (playwright 1.65); passing them again is harmless and keeps them if it ever stops.
# --proxy-server: whatever the browser would send past the route guard goes to a closed
# port on 127.0.0.1; chromium never proxies loopback addresses, so 127.0.0.1 is reached
# directly.
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    f"--proxy-server=http://{ALLOWED_HOST}:9",
]
PAGE_TIMEOUT_MS = 10_000


def is_allowed(url: str) -> bool:
    """Whether the browser may fetch `url`: only from 127.0.0.1 (or a URL with no host,
    like data:)."""
    host = urlsplit(url).hostname
    return host is None or host == ALLOWED_HOST


@pytest.fixture(scope="session")
def chromium_path() -> str:
    """The chromium that Playwright drives: Debian's, installed by `make browser`."""
    path = CHROMIUM if Path(CHROMIUM).is_file() else shutil.which("chromium")
    if path is None:
        pytest.fail(
            f"chromium is not installed ({CHROMIUM} is missing): run `make browser` "
            "(as root it installs Debian's chromium; else `sudo apt-get install chromium`)",
            pytrace=False,
        )
    return path


@pytest.fixture(scope="package")
def playwright() -> Iterator[Playwright]:
    """One Playwright driver (a node process, about a second to start) for this folder's
    tests. Not for the session: while it runs, asyncio.run() fails in the main thread, so
    it must stop with this folder's last test (package scope: this folder is a package)."""
    with sync_playwright() as p:
        yield p


@pytest.fixture
def blocked_requests() -> list[str]:
    """The URLs that the route guard aborted during the test. A test that provokes a
    blocked request on purpose clears this list, or its teardown fails."""
    return []


@pytest.fixture
def browser_context(
    playwright: Playwright, chromium_path: str, tmp_path: Path, blocked_requests: list[str]
) -> Iterator[BrowserContext]:
    """A fresh headless chromium (its own user-data folder) that reaches 127.0.0.1 only."""
    context = playwright.chromium.launch_persistent_context(
        user_data_dir=tmp_path / "chromium-profile",
        executable_path=chromium_path,
        headless=True,
        args=CHROMIUM_ARGS,
    )
    try:
        context.set_default_timeout(PAGE_TIMEOUT_MS)

        def guard(route: Route) -> None:
            blocked_requests.append(route.request.url)
            route.abort("blockedbyclient")

        context.route(lambda url: not is_allowed(url), guard)

        # WebSockets are not requests to context.route: refuse other hosts' sockets too.
        # A socket route that never calls connect_to_server() reaches no server; closing
        # it tells the page at once.
        def guard_socket(ws: WebSocketRoute) -> None:
            blocked_requests.append(ws.url)
            ws.close(code=1008, reason=f"the tests reach {ALLOWED_HOST} only")

        context.route_web_socket(lambda url: not is_allowed(url), guard_socket)
        yield context
    finally:
        context.close()
    assert not blocked_requests, (
        f"the page asked for addresses other than {ALLOWED_HOST} (the tests reach no "
        f"other; serve it from 127.0.0.1): {blocked_requests}"
    )


@pytest.fixture
def page(browser_context: BrowserContext) -> Page:
    """The context's tab (a persistent context opens with one), 10 s default timeout."""
    page = browser_context.pages[0] if browser_context.pages else browser_context.new_page()
    page.set_default_timeout(PAGE_TIMEOUT_MS)
    return page


# ---------------------------------------------------------------- a real `busarm dashboard`

DASHBOARD_START_S = 90.0
"""How long `busarm dashboard` may take to print its link (one that calibrates the twin's
camera first takes about 8 s on a free machine)."""


@dataclass(frozen=True)
class Dashboard:
    """A `busarm dashboard` subprocess on the twin: its page's link (as printed: with
    ``?token=`` when it has one) and reports folder."""

    url: str
    reports: Path
    process: subprocess.Popen[bytes]

    @property
    def base(self) -> str:
        """The link without its query: ``http://127.0.0.1:PORT/``."""
        return self.url.split("?")[0]

    @property
    def token(self) -> str | None:
        return parse_qs(urlsplit(self.url).query).get("token", [None])[0]

    def api(self, what: str) -> dict[str, Any]:
        """GET /api/WHAT (state, robot) as JSON (with the token, if any)."""
        headers = {"Authorization": f"Bearer {self.token}"} if self.token else {}
        request = urllib.request.Request(f"{self.base}api/{what}", headers=headers)
        with urllib.request.urlopen(request, timeout=5) as reply:
            data: dict[str, Any] = json.load(reply)
        return data


@contextmanager
def running_dashboard(config_home: Path, folder: Path, *args: str) -> Iterator[Dashboard]:
    """`busarm dashboard --http-port 0 ARGS` on the twin (real time), config in
    ``config_home``, reports and stderr in ``folder``. Stopped with SIGINT (a Ctrl+C) at
    the end: it must exit 0 or 130 and print no traceback."""
    reports = folder / "reports"
    env = {**os.environ, "XDG_CONFIG_HOME": str(config_home)}
    stderr_path = folder / "stderr.txt"
    with stderr_path.open("wb") as stderr:
        process = subprocess.Popen(
            [sys.executable, "-m", "busarm", "dashboard", "--http-port", "0",
             "--reports", str(reports), *args],
            stdout=subprocess.PIPE, stderr=stderr, env=env,
        )
    lines: queue.Queue[bytes] = queue.Queue()

    def read_stdout() -> None:  # the first line is the link; keep the pipe drained after
        assert process.stdout is not None
        for line in process.stdout:
            lines.put(line)
        lines.put(b"")

    reader = threading.Thread(target=read_stdout, name="busarm-dashboard-stdout", daemon=True)
    reader.start()
    try:
        try:
            first = lines.get(timeout=DASHBOARD_START_S).decode().strip()
        except queue.Empty:
            first = ""
        if not first.startswith("http://127.0.0.1:"):
            process.kill()
            process.wait(timeout=10)
            pytest.fail(f"busarm dashboard printed no link in {DASHBOARD_START_S:.0f} s "
                        f"(first line {first!r}); stderr:\n{stderr_path.read_text()}")
        yield Dashboard(first, reports, process)
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=10)
                pytest.fail("busarm dashboard did not end within 20 s of a SIGINT")
        reader.join(timeout=5)
    err = stderr_path.read_text()
    assert process.returncode in (0, 130), f"exit code {process.returncode}; stderr:\n{err}"
    assert "Traceback" not in err, err


@pytest.fixture(scope="session")
def dashboard_config_home(tmp_path_factory: pytest.TempPathFactory,
                          twin_calibration: tuple[Path, Path]) -> Path:
    """One XDG config folder for every dashboard of the session, the twin's camera
    calibration kept in it (the session's: no dashboard makes it again)."""
    home = tmp_path_factory.mktemp("dashboard-config")
    keep_twin_calibration(home, twin_calibration)
    return home


@pytest.fixture(scope="module")
def dashboard(
    dashboard_config_home: Path, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[Dashboard]:
    """`busarm dashboard --http-port 0` on the twin (real time), one per test module."""
    with running_dashboard(dashboard_config_home, tmp_path_factory.mktemp("dashboard")) as d:
        yield d


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """A real browser's tests are slow ones (`make test-fast` leaves them out), on the wall
    clock: a page drives a live dashboard server."""
    here = Path(__file__).parent
    for item in items:
        if here in Path(item.fspath).parents:
            item.add_marker(pytest.mark.slow)
            item.add_marker(pytest.mark.wallclock(
                "a real browser's page at a live dashboard server on a real-time robot"))
