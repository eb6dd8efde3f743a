"""``busarm twin snapshot | scene`` and scene files: what a user types, what they get."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest
from click.testing import CliRunner, Result

from busarm.cli.main import cli
from busarm.twin.scene import load_scene, random_scene


def run(*args: str) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, list(args))


def one_error(result: Result, code: int = 2) -> str:
    assert result.exit_code == code, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


def test_snapshot_writes_both_views(tmp_path: Path) -> None:
    out = tmp_path / "scene.png"
    result = run("twin", "snapshot", "--seed", "2", "--png", str(out))
    assert result.exit_code == 0, result.stderr
    image = cv2.imread(str(out))
    assert image.shape[1:] == (1280, 3) and image.shape[0] > 480  # a caption under them
    arm_view, overview = image[:480, :640], image[:480, 640:]
    assert arm_view.std() > 10 and overview.std() > 10
    assert not (arm_view == overview).all()


def test_scene_file_round_trip_and_use(tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    result = run("twin", "scene", "--seed", "7", "--blocks", "4", "-o", str(path))
    assert result.exit_code == 0, result.stderr
    scene = load_scene(path)
    assert scene.blocks == random_scene(7, 4).blocks
    png = tmp_path / "s.png"
    assert run("twin", "snapshot", "--scene", str(path), "--png", str(png)).exit_code == 0


@pytest.mark.parametrize(("text", "expected"), [
    ("not toml [", "not valid TOML"),
    ('format = "busarm.scene"\nversion = 2\n', "version"),
    ('format = "busarm.scene"\nversion = 1\n[[blocks]]\ncolor = "red"\nx_mm = 900\ny_mm = 0\n',
     "off the table"),
    ('format = "busarm.scene"\nversion = 1\n[[blocks]]\ncolor = "purple"\nx_mm = 200\n'
     'y_mm = 0\n', "purple"),
    ('format = "busarm.scene"\nversion = 1\n[[blocks]]\ncolor = "red"\nx_mm = 200\ny_mm = 0\n'
     '[[blocks]]\ncolor = "blue"\nx_mm = 210\ny_mm = 0\n', "overlap"),
    ('format = "busarm.scene"\nversion = 1\n[[blocks]]\ncolor = "red"\nx_mm = 200\n',
     "y_mm"),
    ('format = "busarm.scene"\nversion = 1\n[[blocks]]\ncolor = "red"\nx_mm = 20\ny_mm = 0\n',
     "arm base"),
])
def test_a_bad_scene_file_is_one_clear_error(tmp_path: Path, text: str, expected: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    message = one_error(run("twin", "snapshot", "--scene", str(path), "--png",
                            str(tmp_path / "x.png")))
    assert expected in message
    assert not (tmp_path / "x.png").exists()


def test_bad_twin_urls_and_options_are_clear_errors(tmp_path: Path) -> None:
    assert "lens" in one_error(run("--port", "twin://?lens=fish", "arm", "pose"))
    assert "unknown parameter" in one_error(run("--port", "twin://?sede=3", "arm", "pose"))
    assert "board" in one_error(run("--port", "twin://?board=dartboard", "arm", "pose"))
    assert "colors" in one_error(run("twin", "snapshot", "--colors", "red,pink",
                                     "--png", str(tmp_path / "x.png")))
    assert "no pose" in one_error(run("twin", "snapshot", "--pose", "dance",
                                      "--png", str(tmp_path / "x.png")))


def test_more_bad_input_is_one_clear_error(tmp_path: Path) -> None:
    assert "PORT 1..65535" in one_error(run("vision", "detect", "--camera",
                                            "twin://127.0.0.1:abc"))
    assert "PORT 1..65535" in one_error(run("vision", "detect", "--camera",
                                            "twin://127.0.0.1:99999"))
    assert "/dev/pts" in one_error(run("--port", "twin://127.0.0.1:5000", "arm", "pose"))
    assert "twin URL: seed" in one_error(run("--port", "twin://?seed=abc", "arm", "pose"))
    assert "0..8" in one_error(run("--port", "twin://?blocks=40", "arm", "pose"))
    assert "not both" in one_error(run("twin", "snapshot", "--joints", "0,-90,0,-90,0",
                                       "--pose", "home", "--png", str(tmp_path / "x.png")))
    assert "into the table" in one_error(run("twin", "snapshot", "--joints", "0,-20,100,-80,0",
                                             "--png", str(tmp_path / "x.png")))
    scene = tmp_path / "s.toml"
    scene.write_text('format = "busarm.scene"\nversion = 1\n[[boards]]\nkind = "tags"\n'
                     'x_mm = 380\ny_mm = 0\n')
    assert "hangs off the table" in one_error(run("twin", "snapshot", "--scene", str(scene),
                                                  "--png", str(tmp_path / "x.png")))


def test_a_broken_gl_backend_is_one_clear_error(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    result = subprocess.run(
        [sys.executable, "-m", "busarm", "twin", "snapshot", "--png", str(tmp_path / "x.png")],
        capture_output=True, text=True, timeout=60, env=dict(os.environ, MUJOCO_GL="foo"))
    assert result.returncode == 1, result.stderr
    assert result.stderr.startswith("error: MUJOCO_GL='foo'"), result.stderr
    assert "Traceback" not in result.stderr


def test_a_blank_frame_is_named_as_such(tmp_path: Path) -> None:
    import numpy as np

    folder = tmp_path / "frames"
    folder.mkdir()
    cv2.imwrite(str(folder / "black.png"), np.zeros((48, 64, 3), np.uint8))
    result = run("vision", "detect", "--camera", str(folder))
    assert result.exit_code == 0, result.stderr
    assert "the frame is uniform" in result.stdout


def test_the_bus_benchmark_refuses_a_twin_on_a_simulated_clock() -> None:
    result = run("--port", "twin", "bench", "--reads", "10", "--loops", "1", "--scans", "1")
    assert result.exit_code == 2, result.stderr
    assert "runs on a simulated clock" in result.stderr and "reads/s" not in result.stdout
