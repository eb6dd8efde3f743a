"""Every command line in README.md's "Using it" section runs as written.

The rules, applied to each ```sh code block of the section, in order:

* A line is a shell line of the block; a line ending in ``\\`` continues on the next; a
  line that is only a comment (``# ...``, the rest of the comment above it) is not one.
  Every line must run ``.venv/bin/busarm`` (a pipe into it counts); anything else fails
  the test, so that a new kind of line gets a rule here.
* HARDWARE: a line naming ``/dev/ttyUSB0``, ``/dev/video0`` or ``COM3`` needs hardware
  that a test machine lacks: skipped, and counted.
* SERVERS: a ``sim serve``, ``twin serve`` or ``dashboard`` line is started in the
  background (the dashboard on any free port: ``SERVER_OPTIONS``) and stopped with
  SIGTERM at the end of its block (it must exit 0, no traceback). The
  placeholders of the lines after it, ``/dev/pts/N`` and ``twin://127.0.0.1:PORT``, are
  what it printed.
* SMALLER: the lines in ``SMALLER`` take minutes as written (many scenes, long timed
  runs); they run as the same command with smaller counts, given there (for ``bench
  pick``, one scene, and a seed whose table has the fewest blocks of its family: 3, 6).
* INTERACTIVE: the lines in ``INTERACTIVE`` get the answers a person gives ("y") on
  stdin; every other line gets an empty stdin.
* BENCH: a benchmark line may miss a speed target on a busy test machine: then it prints
  FAIL and exits 1 with the one line ``MISSED`` says, which is not the README's fault;
  any other error is.
* Every other line runs as written, with bash, in a fresh folder per block whose
  ``.venv/bin/busarm`` runs this checkout's busarm, so that the files one line writes
  (camera.json, ws.png) are there for the next. Each must exit 0 with no traceback and
  no ``error:`` line. Nothing runs on the developer's files: the runtime folder (running
  servers) and $XDG_CONFIG_HOME (kept calibrations, saved poses) are the test's own.
* BUSY: the lines run with ``BUSARM_TIMEOUT_MARGIN_MS`` set (``MARGIN_MS``), as the
  README says to on a computer busy with other work: the rest of the suite runs beside.
* CHECKED: the whole jobs (``map build``, ``transport``, ``line-follow``, ``bench
  locate``) are the smoke runs of their commands as processes: what they print and
  write is checked further here (``CHECKED``), as a reader would look at it, rather
  than run again elsewhere.
* KEPT: each block's $XDG_CONFIG_HOME starts with the twin's camera calibration kept in
  it (the session's ``twin_calibration``, as a first ``pick-sort`` would have kept it),
  so that the lines run as they do for a reader after their first sort: none makes it
  again (calibrating and keeping it is test_cli_calibrations'; the lines that calibrate
  on purpose, ``camera calibrate``/``handeye``, still do).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import pytest

from busarm.nav.map_files import load_map
from busarm.nav.points import load_points
from conftest import keep_twin_calibration

README = Path(__file__).resolve().parents[2] / "README.md"
BUSARM = ".venv/bin/busarm"
HARDWARE = ("/dev/ttyUSB0", "/dev/video0", "COM3")
SERVERS = ("sim serve", "twin serve", "dashboard")
SERVER_OPTIONS = {"dashboard": " --http-port 0"}
"""Added to a server's line: a test never takes a fixed TCP port (another may hold it)."""
PTY = "/dev/pts/N"
CAMERA = "twin://127.0.0.1:PORT"
SMALLER = {
    f"{BUSARM} line-follow --arena 3": f"{BUSARM} line-follow --arena 3 --laps 0.2",
    f"{BUSARM} bench": f"{BUSARM} bench --reads 300 --loops 20 --scans 1",
    f"{BUSARM} bench pick --scenes 50 --workers 2":
        f"{BUSARM} bench pick --scenes 1 --workers 2 --seed 11",
    f"{BUSARM} bench pick --family clutter --workers 2":
        f"{BUSARM} bench pick --family clutter --scenes 1 --workers 2 --seed 11",
    f"{BUSARM} bench vision ; {BUSARM} bench locate":
        f"{BUSARM} bench vision --pictures 2 --seconds 0.5 ; {BUSARM} bench locate "
        "--placements 20",
    f"{BUSARM} bench dashboard": f"{BUSARM} bench dashboard --seconds 1 --tries 2",
    f"{BUSARM} bench mobile": f"{BUSARM} bench mobile --squares 1 --scans 2 --seconds 2",
}
"""README line (without its comment) -> the smaller run of the same commands."""
INTERACTIVE = {f"{BUSARM} arm calibrate": "y\n" * 4}


def _check_map_build(folder: Path, out: str, err: str) -> None:
    """``map build ... --out map.yaml``: one line saying what it made, ROS map_server
    files that load, and ``map show`` of them agreeing."""
    said = out.strip().splitlines()
    assert len(said) == 2 and said[1] == "drawn to map.png", out
    assert said[0].startswith("map map.yaml: ") and " cells of 2.5 cm (" in said[0], said
    assert "; stopped: explored" in said[0], said
    assert (folder / "map.pgm").is_file() and cv2.imread(str(folder / "map.png")) is not None
    assert "np." not in (folder / "map.yaml").read_text()  # plain numbers: map_server reads it
    shown = subprocess.run([sys.executable, "-m", "busarm", "map", "show", "map.yaml"],
                           cwd=folder, capture_output=True, text=True, timeout=60)
    assert shown.returncode == 0, shown.stderr
    spec = load_map(folder / "map.yaml").spec
    assert f"{spec.width} x {spec.height} cells" in said[0]
    assert shown.stdout.startswith(f"map map.yaml: {spec.width} x {spec.height} cells")


def _check_transport(folder: Path, out: str, err: str) -> None:
    """``transport --arena N``: explored, delivered, and its report folder whole."""
    said = out.strip().splitlines()
    assert len(said) == 1 and said[0].startswith("delivered: "), out
    assert said[0].endswith("report transport-report/report.json")
    assert "no map given: exploring the arena first" in err
    report_dir = folder / "transport-report"
    report = json.loads((report_dir / "report.json").read_text())
    assert report["format"] == "busarm.transport_report"
    assert report["delivered"] is True and report["why"] == "delivered"
    assert report["pick"] == "pick" and report["place"] == "place"
    assert all(phase["ok"] for phase in report["phases"])
    assert [t["ok"] for t in report["trips"]] and all(t["ok"] for t in report["trips"])
    assert report["placed_at_m"] is not None
    picture = cv2.imread(str(report_dir / "map.png"))
    assert picture is not None and picture.ndim == 3
    points = load_points(report_dir / "points.toml")
    assert set(points.points) == {"pick", "place"}
    assert points.map_path == report_dir / "map.yaml"
    grid = load_map(report_dir / "map.yaml")  # the map the job ran on, as saved
    assert grid.spec.width > 50 and grid.spec.height > 50


def _check_line_follow(folder: Path, out: str, err: str) -> None:
    """``line-follow --arena 3`` (a fifth of a lap): what it says it does, its summary,
    and its report folder (how well it followed, by the twin's truth: test_line_follow)."""
    assert err.splitlines()[:2] == [
        "Robot('JetAuto Pro arm' on twin, cameras=['overview', 'wrist'], base, lidar): 0.2 "
        "lap(s) of the line at 0.2 m/s", "the arm looks ahead: following the line"], err
    summary = out.strip().splitlines()[-1]
    data = json.loads((folder / "line-follow-report" / "report.json").read_text())
    cleared = sum(b["outcome"] == "cleared" for b in data["blocks"])
    assert summary.startswith("followed 0.2"), summary
    assert f"{cleared} block(s) cleared, 0 stop(s)" in summary, summary
    assert summary.endswith("Report: line-follow-report/"), summary
    assert data["format"] == "busarm.line_follow_report" and data["finished"]
    assert data["why"] == "0.2 laps done" and data["laps_done"] >= 0.2
    assert data["travelled_m"] > 0.5 and data["lateral_max_mm"] < 30.0
    assert len(data["blocks"]) == cleared  # every block met was put aside
    picture = cv2.imread(str(folder / "line-follow-report" / "path.png"))
    assert picture is not None and picture.shape[2] == 3


PYTHON_REPR = re.compile(r"\[[^\]]*\]|\{'|None|drop_rate|duration_s|speed_deg_s|e\+\d")
"""A Python list, dict repr, None, an internal name or an exponent in a message."""


def _check_bench_locate(folder: Path, out: str, err: str) -> None:
    """``bench vision ; bench locate``: the located blocks counted per bearing of the arm,
    the lens's distortion and the median error said in words, no Python in sight."""
    assert re.search(r"^location error: median [\d.]+ mm \(ok <= 2\)", out, re.M), out
    assert re.search(r"lens distortion k1 -?[\d.]+, k2 -?[\d.]+, p1 ", out), out
    assert not PYTHON_REPR.search(out), out
    bearings = re.findall(r"^bearing ([-+]\d+) deg: (\d+) located, (\d+) missed", err, re.M)
    assert len(bearings) >= 2, err
    located = re.search(r"located (\d+)", out)
    assert located and sum(int(n) for _, n, _ in bearings) == int(located.group(1)), (err, out)


CHECKED = {
    f"{BUSARM} map build --arena 3 --out map.yaml --png map.png": _check_map_build,
    f"{BUSARM} transport --arena 3": _check_transport,
    f"{BUSARM} line-follow --arena 3": _check_line_follow,
    f"{BUSARM} bench vision ; {BUSARM} bench locate": _check_bench_locate,
}
"""README line (without its comment) -> a check of what it printed and wrote (CHECKED)."""
MISSED = re.compile(r"error: \d+ target\(s\) missed: FAIL in the report")
"""The line of a benchmark that printed FAIL (exit code 1): allowed (see BENCH)."""
LINE_TIMEOUT_S = 120.0
MARGIN_MS = "200"
"""The reply margin the lines run with (BUSARM_TIMEOUT_MARGIN_MS, as the README says to
set on a busy computer): the rest of the suite runs beside them, and a served arm's
replies may come tens of ms late; the lines themselves run as written."""


def _section(text: str, title: str = "## Using it") -> str:
    start = text.index(f"\n{title}\n")
    end = text.find("\n## ", start + 1)
    return text[start:end if end >= 0 else None]


def _command(line: str) -> str:
    """The line without its trailing ``# comment``, whitespace squeezed."""
    return " ".join(re.sub(r"\s#\s.*$", "", line).split())


def readme_blocks() -> list[list[str]]:
    """The shell lines of each ```sh block of "Using it", continuations joined."""
    blocks = []
    for body in re.findall(r"```sh\n(.*?)```", _section(README.read_text()), re.DOTALL):
        lines: list[str] = []
        pending = ""
        for raw in body.splitlines():
            if raw.rstrip().endswith("\\"):
                pending += raw.rstrip()[:-1] + " "
                continue
            line = (pending + raw).strip()
            pending = ""
            if line and not line.startswith("#"):
                lines.append(line)
        blocks.append(lines)
    return blocks


BLOCKS = readme_blocks()


@dataclass
class Run:
    """What a block's lines did: for the report, and the failures to show."""

    ran: list[tuple[str, float]] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    smaller: list[str] = field(default_factory=list)
    failures: list[str] = field(default_factory=list)

    def check(self, line: str, code: int, out: str, err: str) -> bool:
        """Whether the line did its job (or missed only a speed target); a failure if not."""
        errors = [x for x in err.splitlines() if x.startswith("error:")]
        if f"{BUSARM} bench" in line and errors and all(MISSED.fullmatch(x) for x in errors):
            code, errors = (0 if code == 1 else code), []  # a speed target, missed (BENCH)
        if code != 0 or "Traceback" in out + err or errors:
            self.failures.append(f"{line}\n  exit {code}\n  stderr: {err.strip()[-2000:]}")
            return False
        return True


def _workdir(tmp_path: Path, calibration: tuple[Path, Path]) -> tuple[Path, dict[str, str]]:
    """A folder whose .venv/bin/busarm is this checkout's, and the environment to run in
    (the twin's ``calibration`` kept in its config folder: KEPT)."""
    script = tmp_path / ".venv" / "bin" / "busarm"
    script.parent.mkdir(parents=True)
    script.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m busarm "$@"\n')
    script.chmod(0o755)
    env = {k: v for k, v in os.environ.items()
           if k not in ("BUSARM_PORT", "BUSARM_ARM", "BUSARM_CALIBRATION")}
    env.update(BUSARM_RUNTIME_DIR=str(tmp_path / "run"), XDG_CONFIG_HOME=str(tmp_path / "config"),
               COLUMNS="120", PYTHONUNBUFFERED="1", BUSARM_TIMEOUT_MARGIN_MS=MARGIN_MS)
    keep_twin_calibration(tmp_path / "config", calibration)
    return tmp_path, env


def _start_server(line: str, cwd: Path, env: dict[str, str]) -> tuple[subprocess.Popen[str],
                                                                      dict[str, str]]:
    line = _command(line) + "".join(extra for name, extra in SERVER_OPTIONS.items()
                                    if f"{BUSARM} {name}" in _command(line))
    proc = subprocess.Popen(
        ["bash", "-c", f"exec {line}"], cwd=cwd, env=env, text=True, stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert proc.stdout is not None
    first = proc.stdout.readline().strip()
    if "dashboard" in line:  # its first line is the page's address, once it serves
        assert first.startswith("http://127.0.0.1:"), (line, first)
    values = {PTY: first}
    if "twin serve" in line:
        values[CAMERA] = proc.stdout.readline().strip()
    return proc, values


def _stop_server(line: str, proc: subprocess.Popen[str], run: Run) -> None:
    proc.terminate()
    try:
        out, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    run.check(f"{line} (stopped with SIGTERM)", proc.returncode, out, err)


def run_block(lines: list[str], tmp_path: Path, calibration: tuple[Path, Path]) -> Run:
    """Run one block's lines by the rules above."""
    cwd, env = _workdir(tmp_path, calibration)
    run = Run()
    servers: list[tuple[str, subprocess.Popen[str]]] = []
    values: dict[str, str] = {}
    try:
        for line in lines:
            command = _command(line)
            if BUSARM not in command:
                run.failures.append(f"{line}\n  not a busarm line: give it a rule")
            elif any(device in command for device in HARDWARE):
                run.skipped.append(line)
            elif any(f"{BUSARM} {s}" in command for s in SERVERS):
                proc, printed = _start_server(line, cwd, env)
                servers.append((line, proc))
                values.update(printed)
            else:
                _run_line(line, command, cwd, env, values, run)
    finally:
        for line, proc in servers:
            _stop_server(line, proc, run)
    return run


def _run_line(line: str, command: str, cwd: Path, env: dict[str, str],
              values: dict[str, str], run: Run) -> None:
    if command in SMALLER:
        line = SMALLER[command]
        run.smaller.append(f"{command}  ->  {line}")
    for placeholder, value in values.items():
        line = line.replace(placeholder, value)
    if PTY in line or CAMERA in line:
        run.failures.append(f"{line}\n  names a server no line before it started")
        return
    start = time.monotonic()
    try:
        done = subprocess.run(["bash", "-c", line], cwd=cwd, env=env, text=True,
                              input=INTERACTIVE.get(command, ""), capture_output=True,
                              timeout=LINE_TIMEOUT_S)
    except subprocess.TimeoutExpired as exc:  # what it had said by then: where it stuck
        said = exc.stderr if isinstance(exc.stderr, str) else (exc.stderr or b"").decode(
            errors="replace")
        run.failures.append(f"{line}\n  still running after {LINE_TIMEOUT_S:g} s\n"
                            f"  stderr: {said.strip()[-2000:]}")
        return
    run.ran.append((line, time.monotonic() - start))
    if run.check(line, done.returncode, done.stdout, done.stderr) and command in CHECKED:
        try:
            CHECKED[command](cwd, done.stdout, done.stderr)
        except AssertionError as exc:
            run.failures.append(f"{line}\n  what it printed or wrote: {exc}\n"
                                f"  stdout: {done.stdout.strip()[-2000:]}")


def test_the_using_it_section_has_examples_of_each_kind() -> None:
    lines = [line for block in BLOCKS for line in block]
    assert len(BLOCKS) >= 4 and len(lines) >= 25, BLOCKS
    assert any(any(d in line for d in HARDWARE) for line in lines)
    assert any(any(s in line for s in SERVERS) for line in lines)
    stale = set(SMALLER) | set(INTERACTIVE) | set(CHECKED)
    stale -= {_command(line) for line in lines}
    assert not stale, f"rules for lines the README no longer has: {sorted(stale)}"


BLOCKS_AT_ONCE = 2
"""Blocks run side by side (each in its own folder, runtime folder and configuration:
they share nothing), so that the section takes about half as long on two cores. Under
pytest-xdist the workers are what runs them side by side: each block runs once, in the
worker whose test asks for it."""


@pytest.fixture(scope="module")
def block_runs(tmp_path_factory: pytest.TempPathFactory, twin_calibration: tuple[Path, Path]
               ) -> Iterator[Callable[[int], tuple[Run, float]]]:
    """A block's run and its time, by number; alone, the next block is started while one
    is waited for (BLOCKS_AT_ONCE in all)."""
    def one(number: int) -> tuple[Run, float]:
        start = time.monotonic()
        folder = tmp_path_factory.mktemp(f"block{number + 1}")
        return run_block(BLOCKS[number], folder, twin_calibration), time.monotonic() - start

    ahead = 0 if os.environ.get("PYTEST_XDIST_WORKER") else BLOCKS_AT_ONCE - 1
    started: dict[int, Future[tuple[Run, float]]] = {}
    with ThreadPoolExecutor(BLOCKS_AT_ONCE) as pool:
        def result(number: int) -> tuple[Run, float]:
            for n in range(number, min(number + 1 + ahead, len(BLOCKS))):
                if n not in started:
                    started[n] = pool.submit(one, n)
            return started[number].result()

        yield result


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.wallclock("the README's lines run as written, as processes, some on a served arm")
@pytest.mark.parametrize("number", range(len(BLOCKS)), ids=lambda n: f"block{n + 1}")
def test_readme_block_runs_as_written(number: int,
                                      block_runs: Callable[[int], tuple[Run, float]]) -> None:
    run, took = block_runs(number)
    report = [f"block {number + 1}: {len(run.ran)} run, {len(run.skipped)} skipped (hardware), "
              f"{len(run.smaller)} smaller, {took:.1f} s"]
    report += [f"  {seconds:5.1f} s  {line}" for line, seconds in run.ran]
    report += [f"  skipped (hardware): {line}" for line in run.skipped]
    report += [f"  smaller: {line}" for line in run.smaller]
    print("\n".join(report))
    assert not run.failures, "\n".join([*report, "failed:", *run.failures])
