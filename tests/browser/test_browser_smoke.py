"""The browser fixtures drive a real headless chromium, and it reaches 127.0.0.1 only."""

from __future__ import annotations

import functools
import threading
from collections.abc import Iterator
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Error, Page, expect

# An address no test may reach (private range, nothing of ours is there): the guard must
# abort requests to it before they are sent.
ELSEWHERE = "10.255.255.1"

INDEX_HTML = """<!doctype html>
<html><head><meta charset="utf-8"><title>smoke</title></head>
<body><p id="out">static</p><p id="data">no data</p><script src="app.js"></script></body>
</html>
"""
APP_JS = """
document.getElementById("out").textContent = "written by app.js";
fetch("data.json").then(r => r.json()).then(d => {
  document.getElementById("data").textContent = d.message;
});
"""


class QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:
        pass


@pytest.fixture
def served(tmp_path: Path) -> Iterator[str]:
    """A page (HTML, a script, JSON) served on 127.0.0.1 at an ephemeral port; its URL."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "index.html").write_text(INDEX_HTML)
    (site / "app.js").write_text(APP_JS)
    (site / "data.json").write_text('{"message": "fetched from 127.0.0.1"}')
    server = ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(QuietHandler, directory=str(site))
    )
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, name="busarm-test-http")
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/index.html"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)


def test_page_runs_its_script(page: Page, served: str) -> None:
    page.goto(served)
    expect(page).to_have_title("smoke")
    expect(page.locator("#out")).to_have_text("written by app.js")
    expect(page.locator("#data")).to_have_text("fetched from 127.0.0.1")


def test_other_addresses_are_aborted_unsent(
    page: Page, served: str, blocked_requests: list[str]
) -> None:
    page.goto(served)
    fetched = page.evaluate(
        "url => fetch(url).then(() => 'fetched', e => 'refused: ' + e.message)",
        f"http://{ELSEWHERE}/data.json",
    )
    assert fetched.startswith("refused")
    socket = page.evaluate(
        """url => new Promise(resolve => {
             const ws = new WebSocket(url);
             ws.onopen = () => resolve("opened");
             ws.onclose = e => resolve("closed " + e.code);
           })""",
        f"ws://{ELSEWHERE}/ws",
    )
    assert socket == "closed 1008"
    with pytest.raises(Error, match="ERR_BLOCKED_BY_CLIENT"):
        page.goto(f"http://{ELSEWHERE}/")
    # Each was stopped by the route guard, not sent and failed on the network.
    assert blocked_requests == [
        f"http://{ELSEWHERE}/data.json",
        f"ws://{ELSEWHERE}/ws",
        f"http://{ELSEWHERE}/",
    ]
    blocked_requests.clear()  # provoked on purpose: the teardown check is not for these
