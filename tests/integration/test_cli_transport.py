"""``busarm transport`` and ``busarm map build`` through the real CLI (a subprocess, in a
folder of its own): on a twin of their own in a seeded arena, a whole job each; and the
input they refuse before anything is opened or driven, in one line each.

A whole run explores the arena and does the job: about a minute, so there are two, started
at once (``whole_runs``: each in its own folder and config folder; on two cores the pair
takes about as long as the transport alone). The transport finds the twin's camera
calibration kept, as after a reader's first job (making and keeping it is
test_cli_calibrations').
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

import cv2
import pytest

from busarm.nav.map_files import load_map
from busarm.nav.points import load_points
from conftest import keep_twin_calibration

pytestmark = pytest.mark.slow  # whole mobile jobs as processes

SEED = 1
TWIN_PORT = f"board://twin?family=arena&seed={SEED}"


def busarm(*args: str, cwd: Path, timeout_s: float = 240.0,
           env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "busarm", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=timeout_s, env=env)


WHOLE_RUNS = {
    "transport": ["transport", "--arena", str(SEED)],
    "map-build": ["map", "build", "--arena", str(SEED), "--out", "x.yaml", "--time", "120"],
}
Done = tuple[Path, subprocess.CompletedProcess[str]]


@pytest.fixture(scope="module")
def whole_runs(tmp_path_factory: pytest.TempPathFactory, twin_calibration: tuple[Path, Path]
               ) -> Iterator[dict[str, Future[Done]]]:
    """The whole runs, started at once; each test waits for its own (its folder and what
    the command did). Each has a config folder of its own (not a test's: this fixture
    outlives them), the transport's with the twin's calibration kept in it."""
    def run(name: str) -> Done:
        folder, config = tmp_path_factory.mktemp(name), tmp_path_factory.mktemp("config")
        if name == "transport":
            keep_twin_calibration(config, twin_calibration)
        return folder, busarm(*WHOLE_RUNS[name], cwd=folder,
                              env=dict(os.environ, XDG_CONFIG_HOME=str(config)))

    with ThreadPoolExecutor(len(WHOLE_RUNS)) as pool:
        yield {name: pool.submit(run, name) for name in WHOLE_RUNS}


@pytest.mark.slow
def test_transport_on_a_seeded_arena_delivers_and_writes_its_report(
        whole_runs: dict[str, Future[Done]]) -> None:
    tmp_path, done = whole_runs["transport"].result()
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    said = done.stdout.strip().splitlines()
    assert len(said) == 1 and said[0].startswith("delivered: "), done.stdout
    assert said[0].endswith("report transport-report/report.json")
    assert "no map given: exploring the arena first" in done.stderr
    folder = tmp_path / "transport-report"
    report = json.loads((folder / "report.json").read_text())
    assert report["format"] == "busarm.transport_report"
    assert report["delivered"] is True and report["why"] == "delivered"
    assert report["pick"] == "pick" and report["place"] == "place"
    assert all(phase["ok"] for phase in report["phases"])
    assert [t["ok"] for t in report["trips"]] and all(t["ok"] for t in report["trips"])
    assert report["placed_at_m"] is not None
    picture = cv2.imread(str(folder / "map.png"))
    assert picture is not None and picture.ndim == 3
    points = load_points(folder / "points.toml")
    assert set(points.points) == {"pick", "place"}
    assert points.map_path == folder / "map.yaml"
    grid = load_map(folder / "map.yaml")  # the map the job ran on, as saved
    assert grid.spec.width > 50 and grid.spec.height > 50


def test_map_build_writes_a_map_that_loads_and_says_what_it_did(
        whole_runs: dict[str, Future[Done]]) -> None:
    tmp_path, done = whole_runs["map-build"].result()
    assert done.returncode == 0, done.stderr
    said = done.stdout.strip().splitlines()
    assert len(said) == 1, done.stdout
    assert said[0].startswith("map x.yaml: ") and " cells of 2.5 cm (" in said[0]
    assert "; stopped: explored" in said[0]
    assert (tmp_path / "x.pgm").is_file()
    # Its numbers are plain numbers: map_server (and `map show`) read it back.
    assert "np." not in (tmp_path / "x.yaml").read_text()
    shown = busarm("map", "show", "x.yaml", cwd=tmp_path, timeout_s=60.0)
    assert shown.returncode == 0, shown.stderr
    grid = load_map(tmp_path / "x.yaml")
    s = grid.spec
    assert f"{s.width} x {s.height} cells" in said[0] and shown.stdout.startswith(
        f"map x.yaml: {s.width} x {s.height} cells")


@pytest.mark.parametrize(("command", "message"), [
    (["transport", "--start", "1,2"],
     "error: --start '1,2': expected X,Y,YAW (m, m, deg), e.g. 0.5,-1.2,90"),
    (["--port", "board://sim", "transport"],
     "error: on a robot, give --map MAP.yaml (made by `busarm map build`) and --points FILE "
     "(where to pick and place)"),
], ids=["two-numbers-for-a-pose", "a-robot-without-map-or-points"])
def test_bad_input_is_one_error_before_anything_is_opened(tmp_path: Path, command: list[str],
                                                          message: str) -> None:
    done = busarm(*command, cwd=tmp_path, timeout_s=60.0)
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [message]
    assert done.stdout == ""
    assert list(tmp_path.iterdir()) == []  # no report, no map: nothing was done


def test_a_twin_on_a_board_port_needs_no_map_or_points(tmp_path: Path) -> None:
    """The twin is an arena: with no map it explores (stopped by Ctrl+C once under way)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "--port", TWIN_PORT, "transport"], cwd=tmp_path,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stderr is not None
        assert proc.stderr.readline() == "no map given: exploring the arena first\n"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith("interrupted: "), err
