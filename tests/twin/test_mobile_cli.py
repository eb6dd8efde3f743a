"""The mobile twin from the command line, as a user runs it: ``busarm twin serve --arena``
in its own process (board, camera and Lidar ports; found by ``lidar scan`` and ``base``
without --lidar/--port), ``twin snapshot --arena``, and bad input as one error each.

The served twin is the one process here (on the wall clock, as a user runs it; the
SIGINT test's subject is that process). Every other ``busarm`` command runs in this
process through click's runner: those at the served twin find it by its runtime file
and talk to it through its real ptys (wall-clock time, so they carry the ``wallclock``
mark, with a generous reply margin); the rest (an in-process arena twin on its simulated
clock, a snapshot, bad input) never touch the wall clock.

The served twin has its own runtime folder (BUSARM_RUNTIME_DIR), so nothing here sees a
server another test or a developer runs, and is shared by the tests that need it (they
run in file order; the last one stops it).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.base.config import load_chassis_config
from busarm.cli.main import cli
from busarm.twin.arena import Arena, Room, StartPose, save_arena
from busarm.twin.arena_picture import LIDAR_BGR

pytestmark = pytest.mark.slow
at_the_served_twin = pytest.mark.wallclock(
    "`busarm twin serve --arena` as its own process (wall-clock time), with commands run "
    "in this process at it through its ptys")

WALL_X_M = 1.5
"""The wall the robot faces: the room's +x side, straight ahead of its start."""
MOVE_M = 0.3
MAP_ARENA = 1
"""A seeded arena too big to see whole from the start (exploring takes a while)."""


def run(*args: str, env: dict[str, str | None] | None = None) -> Result:
    """``busarm ARGS`` in this process through click's runner, its output captured; ``env``
    changes this process's environment for the command only (None: unset)."""
    return CliRunner(mix_stderr=False).invoke(cli, list(args), env=env)


def ok(result: Result) -> str:
    assert result.exit_code == 0, (result.exit_code, result.stdout, result.stderr,
                                   result.exception)
    assert result.exception is None, result.exc_info  # not a crash
    return result.stdout


def one_error(result: Result) -> str:
    """The single ``error:`` line of a command refused as bad input (exit 2)."""
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr,
                                   result.exception)
    assert isinstance(result.exception, SystemExit), result.exc_info  # not a crash
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    return lines[0]


def facing_a_wall(path: Path) -> Path:
    """An arena file: an empty room whose +x wall is WALL_X_M ahead of the robot."""
    save_arena(path, Arena(room=Room(-1.0, WALL_X_M, -1.0, 1.0), start=StartPose(0.0, 0.0, 0.0),
                           name="facing a wall"))
    return path


UNSET = ("BUSARM_PORT", "BUSARM_LIDAR", "BUSARM_ARM", "BUSARM_CALIBRATION")
"""What a user who finds the served twin has not set: no port, Lidar or arm options."""


@dataclass
class Served:
    """``busarm twin serve --arena FILE`` running: its process, the environment changes a
    command at it runs with (``run``'s env), its runtime folder and its three lines."""

    proc: subprocess.Popen[str]
    env: dict[str, str | None]
    runtime: Path
    board: str
    camera: str
    lidar: str


@contextmanager
def serving(arena: str, folder: Path) -> Iterator[Served]:
    """``busarm twin serve --arena ARENA`` running, its runtime and config in ``folder``."""
    given = {"BUSARM_RUNTIME_DIR": str(folder / "run"),
             "XDG_CONFIG_HOME": str(folder / "config"), "COLUMNS": "200",
             # The served twin answers in wall-clock time beside the rest of the suite: a
             # generous reply margin, as the README says to set on a busy computer.
             "BUSARM_TIMEOUT_MARGIN_MS": "200"}
    env: dict[str, str | None] = {**dict.fromkeys(UNSET), **given}
    server_env = {**{k: v for k, v in os.environ.items() if k not in UNSET}, **given,
                  "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "twin", "serve", "--arena", arena],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=server_env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stdout is not None
        lines = [proc.stdout.readline().strip() for _ in range(3)]
        assert all(lines), proc.communicate(timeout=10)
        yield Served(proc, env, folder / "run", *lines)
    finally:
        if proc.poll() is None:  # the stopping test did not run or failed
            proc.kill()
            proc.communicate(timeout=10)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    folder = tmp_path_factory.mktemp("mobile")
    with serving(str(facing_a_wall(folder / "wall.toml")), folder) as twin:
        yield twin


def scan_json(served: Served) -> dict[str, Any]:
    """``busarm lidar scan --json`` without --lidar."""
    data: dict[str, Any] = json.loads(ok(run("lidar", "scan", "--json", env=served.env)))
    return data


def range_ahead_m(scan: dict[str, Any]) -> float:
    """The median range of the beams within 5 deg of straight ahead (bearing 0): about
    five beams, of which a Lidar may miss one or two (a flat wall 1 m off is 4 mm further
    at 5 deg)."""
    ahead = [r for a, r in zip(scan["angles_deg"], scan["ranges_m"], strict=True)
             if r is not None and min(a % 360, 360 - a % 360) <= 5.0]
    assert len(ahead) >= 2, scan["ranges_m"]
    return float(np.median(ahead))


# ---------------------------------------------------------------------- twin serve --arena


@at_the_served_twin
def test_serve_arena_gives_board_camera_and_lidar_ports(served: Served) -> None:
    assert re.fullmatch(r"board:///dev/pts/\d+", served.board), served.board
    assert re.fullmatch(r"twin://127\.0\.0\.1:\d+", served.camera), served.camera
    assert re.fullmatch(r"/dev/pts/\d+", served.lidar), served.lidar
    assert served.lidar != served.board.removeprefix("board://")
    session = json.loads((served.runtime / f"twin-{served.proc.pid}.json").read_text())
    assert (session["kind"], session["port"], session["camera"], session["lidar"]) == (
        "twin", served.board, served.camera, served.lidar)


@at_the_served_twin
def test_lidar_scan_without_lidar_reads_the_served_lidar(served: Served) -> None:
    scan = scan_json(served)
    assert scan["port"] == served.lidar
    assert scan["health"] == "GOOD"
    assert 190 <= scan["beams"] <= 210 and len(scan["ranges_m"]) == scan["beams"]
    assert scan["returns"] >= 0.95 * scan["beams"]  # walls all round, within range
    assert 8.0 <= scan["rate_hz"] <= 12.0
    # The nearest walls are the sides, 1 m left and right of the Lidar (bearing 90 or 270).
    assert scan["nearest_m"] == pytest.approx(1.0, abs=0.05)
    assert abs(scan["nearest_bearing_deg"] % 180 - 90) <= 10.0, scan["nearest_bearing_deg"]


@at_the_served_twin
def test_moving_forward_brings_the_wall_ahead_closer(served: Served) -> None:
    lidar_x_m = load_chassis_config().lidar.x_m
    before = range_ahead_m(scan_json(served))
    assert before == pytest.approx(WALL_X_M - lidar_x_m, abs=0.03)

    moved = ok(run("base", "move-by", str(MOVE_M), "0", "0", env=served.env))
    found = re.search(r"moved to x ([-+.\d]+) m, y ([-+.\d]+) m, yaw ([-+.\d]+) deg", moved)
    assert found, moved
    assert float(found[1]) == pytest.approx(MOVE_M, abs=0.02)
    assert float(found[2]) == pytest.approx(0.0, abs=0.02)

    after = range_ahead_m(scan_json(served))
    assert before - after == pytest.approx(MOVE_M, abs=0.04)


@at_the_served_twin
def test_base_odom_prints_a_pose(served: Served) -> None:
    result = run("base", "odom", "--time", "0.2", env=served.env)
    text = ok(result)
    # Its own odometry starts where the robot stands: at rest, at the origin.
    found = re.search(r"x ([-+.\d]+) m\s+y ([-+.\d]+) m\s+yaw ([-+.\d]+) deg\s+\(moving "
                      r".*odometry from (\w+)\)", text)
    assert found, text
    assert [float(found[k]) for k in (1, 2)] == pytest.approx([0.0, 0.0], abs=0.01)
    assert f"(pid {served.proc.pid}) on {served.board}" in result.stderr


@at_the_served_twin
def test_sigint_stops_the_server_and_removes_its_session(served: Served) -> None:
    session = served.runtime / f"twin-{served.proc.pid}.json"
    assert session.exists()
    # Ctrl+C, as a user stops it (tests/conftest.py's sigint_and_wait; that conftest is
    # not importable from here, where tests/twin/conftest.py is "conftest").
    served.proc.send_signal(signal.SIGINT)
    _, err = served.proc.communicate(timeout=30)
    assert served.proc.returncode == 0, err
    assert "Traceback" not in err and "twin stopped" in err
    assert not session.exists()
    assert list(served.runtime.glob("*.json")) == []


# ---------------------------------------------------------------------- lidar scan --lidar


def test_lidar_scan_of_an_in_process_arena_twin() -> None:
    url = "twin://?family=arena&seed=4"
    scan = json.loads(ok(run("lidar", "scan", "--lidar", url, "--json")))
    assert scan["port"] == url
    assert scan["beams"] >= 190 and scan["returns"] >= 0.9 * scan["beams"]


# ---------------------------------------------------------------------- twin snapshot --arena


def test_snapshot_arena_writes_a_picture_from_above(tmp_path: Path) -> None:
    png = tmp_path / "arena.png"
    out = ok(run("twin", "snapshot", "--arena", "3", "--png", str(png)))
    image = cv2.imread(str(png))
    assert image is not None
    h, w = image.shape[:2]
    assert out.startswith(f"wrote {png}: the arena from above ({w}x{h}): ")
    assert "arena seed 3" in out
    assert w >= 320 and h >= 240
    # One scan's returns are drawn on it, in the Lidar's red.
    red = np.all(np.abs(image.astype(int) - np.array(LIDAR_BGR)) <= 30, axis=2)
    assert red.sum() >= 100


def test_snapshot_of_an_arena_with_overlapping_boxes_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "overlap.toml"
    path.write_text(
        'format = "busarm.arena"\nversion = 1\nname = "overlap"\n'
        "room = { x_min_m = -1.0, x_max_m = 3.0, y_min_m = -1.5, y_max_m = 1.5 }\n"
        "[[boxes]]\nx_m = 1.5\ny_m = 0.0\nsize_x_m = 0.4\nsize_y_m = 0.4\nheight_m = 0.3\n"
        "[[boxes]]\nx_m = 1.7\ny_m = 0.1\nsize_x_m = 0.4\nsize_y_m = 0.4\nheight_m = 0.3\n")
    png = tmp_path / "never.png"
    error = one_error(run("twin", "snapshot", "--arena", str(path), "--png", str(png)))
    assert str(path) in error and "box 0 and box 1 overlap" in error
    assert not png.exists()


# ---------------------------------------------------------------------- bad input


@pytest.mark.parametrize(("args", "named"), [
    (["twin", "serve", "--arena", "2", "--seed", "3"], ["--arena", "--seed"]),
    (["twin", "serve", "--arena", "2", "--echo"], ["--echo", "--arena"]),
    (["twin", "serve", "--arena", "missing.toml"], ["missing.toml"]),
    (["twin", "snapshot", "--arena", "3", "--png", "x.png", "--view", "arm"],
     ["--arena", "--view"]),
    (["lidar", "scan", "--lidar", "twin://?seed=1"], ["twin://?seed=1", "family=arena"]),
    (["base", "odom", "--port", "board://twin?family=arena&blocks=3"],
     ["family arena", "blocks"]),
    (["scan", "--port", "twin://?slip=0"], ["slip", "family arena"]),
    (["base", "odom", "--port", "board://twin?arena=missing.toml"], ["missing.toml"]),
], ids=["serve-seed", "serve-echo", "serve-missing-file", "snapshot-view",
        "lidar-table-twin", "url-arena-blocks", "url-slip-without-arena", "url-missing-file"])
def test_bad_input_is_one_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                args: list[str], named: list[str]) -> None:
    monkeypatch.chdir(tmp_path)  # relative files are in tmp_path
    result = run(*args, env={"BUSARM_RUNTIME_DIR": str(tmp_path / "run")})
    error = one_error(result)
    for name in named:
        assert name in error, (name, error)
    assert result.stdout == ""  # no port announced, no picture written
    assert not (tmp_path / "x.png").exists()
    assert not list((tmp_path / "run").glob("*.json"))


@at_the_served_twin
def test_sigterm_stops_a_map_build_keeps_its_map_and_the_base_stands_still(
        tmp_path: Path) -> None:
    """What `timeout`, systemd and container runtimes send (issue 30), to `map build`
    exploring a served twin's arena: exit 143, one line (the wheels stopped, the map so
    far kept where --out says), and the base stands still after (its odometry, from the
    twin's wheels, over a second)."""
    with serving(str(MAP_ARENA), tmp_path) as twin:
        env = {**{k: v for k, v in os.environ.items() if k not in UNSET},
               **{k: v for k, v in twin.env.items() if v is not None},
               "PYTHONUNBUFFERED": "1"}
        out = tmp_path / "room.yaml"
        before = scan_json(twin)
        proc = subprocess.Popen(
            [sys.executable, "-m", "busarm", "--port", twin.board, "map", "build", "--lidar",
             twin.lidar, "--chassis", "jetauto", "--out", str(out)], stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True, env=env)
        try:
            assert proc.stderr is not None
            assert proc.stderr.readline().startswith("exploring with Robot(")
            # Under way: 10 s explored (however long a busy computer takes for it).
            assert re.fullmatch(r"explored 1\d s: \d+ scans, [\d.]+ m\^2 of floor seen\n",
                                proc.stderr.readline())
            proc.send_signal(signal.SIGTERM)
            printed, err = proc.communicate(timeout=30)
        finally:
            proc.kill()
        assert proc.returncode == 143, err
        assert printed == "" and re.fullmatch(
            r"stopped by SIGTERM: nothing was written to the servos; the wheels stopped; the "
            rf"map so far \(\d+ scans\): {re.escape(str(out))}\n", err), err
        after = scan_json(twin)
        still = ok(run("base", "odom", "--time", "1.0", env=twin.env))
        twin.proc.terminate()
    moved = [abs(after[k] - before[k]) for k in ("nearest_m", "nearest_bearing_deg")]
    assert moved[0] > 0.02 or moved[1] > 5.0, (before, after)  # it had been exploring
    found = re.search(r"x ([-+.\d]+) m\s+y ([-+.\d]+) m\s+yaw ([-+.\d]+) deg", still)
    assert found, still
    x_m, y_m, yaw_deg = (abs(float(found[k])) for k in (1, 2, 3))
    assert x_m < 0.005 and y_m < 0.005 and yaw_deg < 0.5, still
    shown = ok(run("map", "show", str(out)))  # what was explored, readable
    free = re.search(r"free ([\d.]+)%", shown)
    assert free and float(free[1]) > 5.0, shown
