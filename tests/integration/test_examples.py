"""The programs in examples/ run as written, on the twin, each in a folder of its own; what
they claim is checked against what they wrote and, where it matters, the twin's truth."""

from __future__ import annotations

import json
import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def run_example(name: str, folder: Path, monkeypatch: pytest.MonkeyPatch,
                capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """Run examples/NAME as ``python NAME ARGS`` would, in ``folder``; its output."""
    path = EXAMPLES / name
    monkeypatch.chdir(folder)
    monkeypatch.setattr("sys.argv", [str(path), *args])
    runpy.run_path(str(path), run_name="__main__")
    return capsys.readouterr().out


@pytest.fixture
def calibrated(tmp_path: Path, twin_config_home: Path) -> Path:
    """A folder to run in, the twin's camera calibration kept (as the first run of an
    example leaves it), so the examples that look do not make it again."""
    return tmp_path


def test_every_example_is_tested() -> None:
    here = Path(__file__).read_text(encoding="utf-8")
    programs = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert len(programs) >= 6
    assert [p for p in programs if f'"{p}"' not in here] == []


def test_open_and_move(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                       capsys: pytest.CaptureFixture[str]) -> None:
    out = run_example("01_open_and_move.py", tmp_path, monkeypatch, capsys)
    assert "Robot('JetAuto Pro arm' on twin" in out
    assert "gripper at: Pose(x_mm=1" in out and "done in" in out


def test_open_and_move_on_a_robot_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    from busarm import RobotConfig, SimSpec, save_robot_file

    save_robot_file(tmp_path / "robot.toml", RobotConfig(SimSpec()), "desk arm")
    out = run_example("01_open_and_move.py", tmp_path, monkeypatch, capsys, "robot.toml")
    assert "on sim" in out and "done in" in out


@pytest.mark.slow
def test_look_and_locate(calibrated: Path, monkeypatch: pytest.MonkeyPatch,
                         capsys: pytest.CaptureFixture[str]) -> None:
    out = run_example("02_look_and_locate.py", calibrated, monkeypatch, capsys)
    seen = [line.split() for line in out.splitlines() if "block at" in line]
    assert sorted(words[0] for words in seen) == ["blue", "green", "red", "red"]


@pytest.mark.slow
def test_pick_one_block(calibrated: Path, monkeypatch: pytest.MonkeyPatch,
                        capsys: pytest.CaptureFixture[str]) -> None:
    out = run_example("03_pick_one_block.py", calibrated, monkeypatch, capsys)
    assert "held it" in out
    truth = next(line for line in out.splitlines() if line.startswith("truth:"))
    assert float(truth.split(" mm ")[0].split()[-1]) < 35.0  # in the bin (IN_BIN_MM)


def test_drive_and_scan(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                        capsys: pytest.CaptureFixture[str]) -> None:
    out = run_example("04_drive_and_scan.py", tmp_path, monkeypatch, capsys)
    assert "LaserScan(" in out and "returns" in out
    after = next(line for line in out.splitlines() if line.startswith("odometry after 2 s"))
    x_m = float(after.split("x_m=")[1].split(",")[0])
    assert 0.2 < x_m < 0.35  # 0.15 m/s for 2 s, with the ramp up


@pytest.mark.slow
def test_map_and_navigate(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                          capsys: pytest.CaptureFixture[str]) -> None:
    out = run_example("05_map_and_navigate.py", tmp_path, monkeypatch, capsys)
    assert "arrived" in out
    assert (tmp_path / "room.yaml").is_file() and (tmp_path / "room.pgm").is_file()


def test_record_observations(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                             capsys: pytest.CaptureFixture[str]) -> None:
    out = run_example("06_record_observations.py", tmp_path, monkeypatch, capsys)
    assert "Observation(" in out
    lines = [json.loads(line) for line in
             (tmp_path / "observations.jsonl").read_text(encoding="utf-8").splitlines()]
    assert len(lines) == 20
    stamps = [line["t"] for line in lines]
    assert stamps == sorted(stamps)
    assert 1.9 <= stamps[-1] - stamps[0] < 3.0  # 19 waits of 0.1 s, and the reads' own time
    assert lines[-1]["base.x"] > lines[0]["base.x"]  # it drove ahead
