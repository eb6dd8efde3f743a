"""Kept camera calibrations, through the ``busarm`` command run in this process (click's
runner; the files kept are the subject here, not the process): where they are kept (the
robot's folder under $XDG_CONFIG_HOME/busarm/), that ``pick-sort`` makes them once and
reuses them, that the camera commands write them and ``vision locate`` uses them, and that
a missing or stale one is refused with a message saying why, where it looked and which
commands make it (a twin's ``pick-sort`` makes it again).

Every run gets XDG_CONFIG_HOME in a temporary folder: nothing touches the real home.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

from busarm.bus.ports import SerialPort
from busarm.cli.main import cli
from busarm.fileio import config_home, robot_key
from busarm.robot.calibration_store import CalibrationStore
from busarm.robot.port_url import parse_port
from busarm.sim.spec import SimSpec
from busarm.twin.spec import TwinSpec

pytestmark = pytest.mark.slow  # the twin's calibration flows, made again and again


def busarm(*args: str, config: Path) -> subprocess.CompletedProcess[str]:
    """Run the CLI in this process with ``config`` as XDG_CONFIG_HOME; its exit code and
    output as a CompletedProcess. A crash (an exception other than the SystemExit of an
    exit code) fails the test: the runner would swallow it."""
    result = CliRunner(mix_stderr=False).invoke(cli, list(args),
                                                env={"XDG_CONFIG_HOME": str(config)})
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        result.exc_info, result.stdout, result.stderr)
    return subprocess.CompletedProcess(["busarm", *args], result.exit_code, result.stdout,
                                       result.stderr)


def one_error(done: subprocess.CompletedProcess[str], code: int = 2) -> str:
    assert done.returncode == code, (done.stdout, done.stderr)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), done.stderr
    assert "Traceback" not in done.stdout + done.stderr  # (and busarm() checked: no crash)
    return lines[0]


def made_for(path: Path) -> dict[str, Any]:
    record: dict[str, Any] = json.loads(path.read_text())["meta"]["made_for"]
    return record


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory
              ) -> tuple[Path, subprocess.CompletedProcess[str]]:
    """pick-sort on the twin with nothing kept yet: it calibrates and keeps the result."""
    config = tmp_path_factory.mktemp("xdg")
    report = tmp_path_factory.mktemp("report")
    done = busarm("pick-sort", "--blocks", "0", "--report", str(report), config=config)
    assert done.returncode == 0, done.stderr
    return config, done


def test_robot_keys_and_the_config_folder(monkeypatch: pytest.MonkeyPatch,
                                          tmp_path: Path) -> None:
    def key(port: str) -> str:  # the key of the robot the command line's port names
        return parse_port(port).robot_key

    assert key("twin") == key("twin://?seed=3&lens=vendor") == "twin"
    assert TwinSpec().robot_key == TwinSpec(seed=3, lens="vendor").robot_key == "twin"
    assert key("sim") == key("sim://?ids=1,2") == "sim"
    assert SimSpec().robot_key == SimSpec(ids=(1, 2)).robot_key == "sim"
    assert robot_key("/dev/ttyUSB0") == "ttyUSB0" and robot_key("/dev/pts/7") == "pts-7"
    assert key("/dev/ttyUSB0") == SerialPort("/dev/ttyUSB0").robot_key == "ttyUSB0"
    assert key("/dev/pts/7") == SerialPort("/dev/pts/7").robot_key == "pts-7"
    assert robot_key("socket://10.0.0.2:4000") == "socket-10.0.0.2-4000"
    assert key("socket://10.0.0.2:4000") == "socket-10.0.0.2-4000"
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert CalibrationStore.for_port(SerialPort("/dev/ttyUSB0")).folder == \
        tmp_path / "busarm" / "ttyUSB0"
    monkeypatch.setenv("XDG_CONFIG_HOME", "relative/ignored")  # the XDG rule: absolute only
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert config_home() == tmp_path / "home" / ".config"


def test_locate_without_a_calibration_says_where_it_looked_and_what_makes_it(
        tmp_path: Path) -> None:
    line = one_error(busarm("--port", "twin", "vision", "locate", config=tmp_path))
    folder = tmp_path / "busarm" / "twin"
    assert f"in {folder}/ (camera.json, hand_eye.json)" in line
    assert "`busarm --port twin camera calibrate`, then `busarm --port twin camera handeye`" \
        in line
    # A device that is there (a missing one is said first: busarm.bus.transport.check_device).
    line = one_error(busarm("--port", "/dev/null", "vision", "locate", "--camera",
                            "/dev/video0", config=tmp_path))
    assert f"{tmp_path / 'busarm' / 'null'}/" in line
    assert "`busarm --port /dev/null camera calibrate`" in line
    line = one_error(busarm("--port", "twin", "camera", "handeye", config=tmp_path))
    assert "no camera intrinsics are kept for robot 'twin'" in line
    assert "`busarm --port twin camera calibrate`" in line
    assert not (tmp_path / "busarm").exists()  # asking made nothing


def test_the_second_pick_sort_reuses_the_kept_calibration(
        first_run: tuple[Path, subprocess.CompletedProcess[str]],
        tmp_path: Path) -> None:
    config, first = first_run
    folder = config / "busarm" / "twin"
    assert "calibrating the twin's camera" in first.stderr
    files = [folder / "camera.json", folder / "hand_eye.json"]
    before = [(p.read_bytes(), p.stat().st_mtime_ns) for p in files]
    record = made_for(files[1])
    assert record["robot"] == "twin" and record["image_px"] == [640, 480]
    assert record["twin_lens"]["distortion"][0] == pytest.approx(-0.30)

    second = busarm("pick-sort", "--blocks", "0", "--report", str(tmp_path / "r"),
                    config=config)
    assert second.returncode == 0, second.stderr
    assert f"using the camera calibration kept in {folder}/" in second.stderr
    assert "calibrating" not in second.stderr
    assert [(p.read_bytes(), p.stat().st_mtime_ns) for p in files] == before
    report = json.loads((tmp_path / "r" / "report.json").read_text())
    assert report["camera_calibration"] == f"kept in {folder}/"


def _stale(config: Path, name: str, change: Any) -> None:
    path = config / "busarm" / "twin" / name
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


STALE = {
    "picture size": ("camera.json", lambda d: d["meta"]["made_for"].update(image_px=[320, 240]),
                     "made for 320x240 pictures, this is 640x480 pictures", "calibrate"),
    "older file format": ("camera.json", lambda d: d.update(version=0),
                          "key 'version' is 0; this busarm reads version 1", "calibrate"),
    "older store": ("hand_eye.json",
                    lambda d: d["meta"]["made_for"].update(store_version=0),
                    "kept by another busarm (store version 0", "handeye"),
    "another arm": ("hand_eye.json",
                    lambda d: d["meta"]["made_for"]["arm"].update(digest="0123456789abcdef"),
                    "made for arm config 'JetAuto Pro arm' (digest 0123456789abcdef)",
                    "handeye"),
    "another mount": ("hand_eye.json",
                      lambda d: d["meta"]["made_for"]["twin_mount"][0].__setitem__(3, 90.0),
                      "made for a twin camera mounted at (90.0,", "handeye"),
    "no record": ("hand_eye.json", lambda d: d["meta"].clear(),
                  "does not say what it was made for", "handeye"),
}


@pytest.mark.parametrize("kind", list(STALE))
def test_a_stale_calibration_is_refused_saying_why(
        first_run: tuple[Path, subprocess.CompletedProcess[str]], tmp_path: Path,
        kind: str) -> None:
    name, change, why, step = STALE[kind]
    shutil.copytree(first_run[0] / "busarm", tmp_path / "busarm")
    _stale(tmp_path, name, change)
    line = one_error(busarm("--port", "twin", "vision", "locate", config=tmp_path))
    assert f"{tmp_path / 'busarm' / 'twin' / name}" in line and why in line, line
    assert f"`busarm --port twin camera {step}`" in line
    if step == "handeye":  # the intrinsics are fine: only the hand-eye is to be made again
        assert "camera calibrate" not in line


@pytest.mark.slow
def test_a_twin_with_another_lens_calibrates_again_and_the_commands_remake_it(
        first_run: tuple[Path, subprocess.CompletedProcess[str]],
        tmp_path: Path) -> None:
    shutil.copytree(first_run[0] / "busarm", tmp_path / "busarm")
    folder = tmp_path / "busarm" / "twin"
    done = busarm("--port", "twin://?lens=vendor&blocks=0", "pick-sort", "--report",
                     str(tmp_path / "r"), config=tmp_path)
    assert done.returncode == 0, done.stderr
    assert ("it was made for the twin's 'wide' lens (twin://?lens=wide), this is the twin's "
            "'vendor' lens (twin://?lens=vendor): calibrating the twin's camera again"
            ) in " ".join(done.stderr.split())
    assert made_for(folder / "camera.json")["twin_lens"]["distortion"][0] == \
        pytest.approx(-0.0275)
    # Back on the usual lens, the kept one is stale: refused, and the commands remake it.
    line = one_error(busarm("--port", "twin", "vision", "locate", config=tmp_path))
    assert "made for the twin's 'vendor' lens" in line and "this is the twin's 'wide'" in line
    # Few views (6): what is checked is which files the commands remake, not how well.
    done = busarm("--port", "twin", "camera", "calibrate", "--views", "6", config=tmp_path)
    assert done.returncode == 0, done.stderr
    assert f"wrote {folder / 'camera.json'}" in done.stdout
    assert "next, where the camera sits: `busarm --port twin camera handeye`" in done.stderr
    line = one_error(busarm("--port", "twin", "vision", "locate", config=tmp_path))
    assert "hand_eye.json is stale" in line and "`busarm --port twin camera handeye`" in line
    done = busarm("--port", "twin", "camera", "handeye", "--views", "6", config=tmp_path)
    assert done.returncode == 0, done.stderr
    assert made_for(folder / "hand_eye.json")["twin_lens"]["distortion"][0] == \
        pytest.approx(-0.30)
    done = busarm("--port", "twin://?seed=3&blocks=2", "vision", "locate", "--json",
                     config=tmp_path)
    assert done.returncode == 0, done.stderr
    assert len(json.loads(done.stdout)["blocks"]) == 2
    assert f"using the camera calibration kept in {folder}/" in done.stderr
