"""``busarm vision detect`` end to end through click's CliRunner: folders and videos of
synthetic frames, the vendor's YAML, JSON lines, annotated frames, and every bad input
ending as one ``error:`` line with exit code 2 (bad input) or 1 (no frames)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.bench.synthetic import Block, render_blocks, synthetic_frames
from busarm.cli import vision_cmds
from busarm.cli.main import cli
from busarm.vision import camera as camera_mod
from busarm.vision.color import DEFAULT_MIN_AREA_PX

VENDOR_YAML = Path(__file__).resolve().parents[1] / "data" / "vendor" / "lab_config.yaml"


def run(*args: str) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["vision", *args])


def assert_one_error(result: Result, code: int) -> str:
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[list[Block]]]:
    path = tmp_path_factory.mktemp("frames")
    scenes = synthetic_frames(3, seed=21)
    for i, (image, _) in enumerate(scenes):
        cv2.imwrite(str(path / f"frame{i}.png"), image)
    return path, [blocks for _, blocks in scenes]


def test_detect_text(folder: tuple[Path, list[list[Block]]]) -> None:
    path, scenes = folder
    result = run("detect", "--camera", str(path), "--frames", "2")
    assert result.exit_code == 0, result.stderr
    out = result.stdout
    assert out.startswith("frame 0 (640x480 px, t=") and f"{len(scenes[0])} block(s)" in out
    assert "frame 1 (" in out and "frame 2 (" not in out
    rows = [line.split() for line in out.splitlines() if line.startswith("  ")]
    assert len(rows) == len(scenes[0]) + len(scenes[1])
    assert {r[0] for r in rows} <= {"red", "green", "blue"}


def test_detect_json_matches_the_blocks(folder: tuple[Path, list[list[Block]]]) -> None:
    path, scenes = folder
    result = run("detect", "--camera", str(path), "--frames", "0", "--json")
    assert result.exit_code == 0, result.stderr
    frames = [json.loads(line) for line in result.stdout.splitlines()]
    assert [f["frame"] for f in frames] == [0, 1, 2]
    for data, blocks in zip(frames, scenes, strict=True):
        assert (data["width_px"], data["height_px"]) == (640, 480) and "note" not in data
        assert sorted(d["color"] for d in data["detections"]) == sorted(b.color for b in blocks)
        for block in blocks:
            best = min(math.dist(d["centroid_px"], block.center_px)
                       for d in data["detections"] if d["color"] == block.color)
            assert best < 0.5


def test_colors_filter_and_nothing_found(folder: tuple[Path, list[list[Block]]]) -> None:
    path, scenes = folder
    assert {b.color for b in scenes[0]} == {"blue"}
    result = run("detect", "--camera", str(path), "--colors", "blue", "--json")
    data = json.loads(result.stdout)
    assert {d["color"] for d in data["detections"]} == {"blue"}
    assert len(data["detections"]) == len(scenes[0])
    result = run("detect", "--camera", str(path), "--colors", "yellow,blue", "--min-area", "1e8")
    assert result.exit_code == 0, result.stderr
    assert "no blocks found: blue" in result.stdout and "minimum area 1e+08 px" in result.stdout
    result = run("detect", "--camera", str(path), "--colors", "yellow")
    assert result.exit_code == 0
    assert "no blocks found: thresholds for yellow matched no pixels" in result.stdout
    result = run("detect", "--camera", str(path), "--colors", "yellow", "--json")
    assert json.loads(result.stdout)["note"] == (
        "no blocks found: thresholds for yellow matched no pixels")


def test_save_annotated_frames_and_tags(folder: tuple[Path, list[list[Block]]],
                                        tmp_path: Path) -> None:
    path, _ = folder
    out = tmp_path / "out" / "deeper"
    result = run("detect", "--camera", str(path), "--frames", "2", "--save", str(out), "--tags")
    assert result.exit_code == 0, result.stderr
    assert sorted(p.name for p in out.iterdir()) == ["frame_000000.png", "frame_000001.png"]
    saved = cv2.imread(str(out / "frame_000000.png"))
    original = cv2.imread(str(path / "frame0.png"))
    assert saved.shape == original.shape and np.any(saved != original)
    assert "no AprilTags (36h11) found" in result.stdout


def test_vendor_yaml_thresholds(tmp_path: Path) -> None:
    # A red block (the vendor's Mono red is a >= 150) and a yellow one (only Stereo has
    # a yellow).
    image = render_blocks([Block("red", (200, 200), 60, 10), Block("yellow", (420, 260), 60, 0)])
    cv2.imwrite(str(tmp_path / "f.png"), image)
    result = run("detect", "--camera", str(tmp_path), "--vendor-yaml", str(VENDOR_YAML),
                 "--colors", "red", "--json")
    assert result.exit_code == 0, result.stderr
    (det,) = json.loads(result.stdout)["detections"]
    assert det["color"] == "red" and det["centroid_px"] == pytest.approx([200, 200], abs=0.5)
    result = run("detect", "--camera", str(tmp_path), "--thresholds", str(VENDOR_YAML),
                 "--section", "Stereo", "--colors", "red,yellow", "--json")
    assert result.exit_code == 0, result.stderr
    (det,) = json.loads(result.stdout)["detections"]
    # The vendor's Stereo yellow wants a >= 129; the twin's yellow has a = 121.
    assert det["color"] == "red" and det["centroid_px"] == pytest.approx([200, 200], abs=0.5)
    line = assert_one_error(run("detect", "--camera", str(tmp_path), "--vendor-yaml",
                                str(VENDOR_YAML), "--colors", "yellow"), 2)
    assert "no colour 'yellow'" in line and "black, blue, green, red, white" in line


def test_a_video_file(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 10.0, (640, 480))
    frames = synthetic_frames(2, seed=4)
    for image, _ in frames:
        writer.write(image)
    writer.release()
    result = run("detect", "--camera", str(path), "--frames", "0", "--json")
    assert result.exit_code == 0, result.stderr
    lines = [json.loads(x) for x in result.stdout.splitlines()]
    assert [len(x["detections"]) for x in lines] == [len(b) for _, b in frames]


def test_a_registered_scheme(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    image = render_blocks([Block("green", (100, 100), 50, 0)])
    cv2.imwrite(str(tmp_path / "only.png"), image)
    monkeypatch.setitem(camera_mod.CAMERA_SCHEMES, "frames", f"{__name__}:open_frames")
    monkeypatch.setenv("BUSARM_TEST_FRAMES", str(tmp_path))
    result = run("detect", "--camera", "frames://anything", "--json")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["source"] == str(tmp_path) and data["detections"][0]["color"] == "green"


def open_frames(spec: str) -> camera_mod.CameraSource:
    """A test scheme: the folder named by an environment variable."""
    import os

    return camera_mod.ImageFolderSource(os.environ["BUSARM_TEST_FRAMES"])


def test_cameras_that_cannot_deliver(tmp_path: Path, folder: tuple[Path, list]) -> None:
    line = assert_one_error(run("detect", "--camera", "/dev/video-busarm-none"), 1)
    assert line == "error: no camera at /dev/video-busarm-none"
    line = assert_one_error(run("detect", "--camera", str(tmp_path / "nope")), 1)
    assert "not a device, file, folder or known scheme (known: twin" in line
    # A folder with an unreadable image: the good frame is printed, then one error.
    bad = tmp_path / "bad"
    bad.mkdir()
    cv2.imwrite(str(bad / "1.png"), render_blocks([]))
    (bad / "2.png").write_bytes(b"garbage")
    result = run("detect", "--camera", str(bad), "--frames", "0")
    line = assert_one_error(result, 1)
    assert str(bad / "2.png") in line and "frame 0 (" in result.stdout
    # More frames asked for than a folder has.
    line = assert_one_error(run("detect", "--camera", str(folder[0]), "--frames", "5"), 1)
    assert "end of folder" in line and "after 3 image(s)" in line


def test_bad_input(tmp_path: Path, folder: tuple[Path, list]) -> None:
    cam = str(folder[0])
    bad = tmp_path / "bad.toml"
    bad.write_text('format = "busarm.colors"\nversion = 1\n[colors.red]\nlab_min = [0, 0]\n'
                   "lab_max = [255, 255, 255]\n")
    line = assert_one_error(run("detect", "--camera", cam, "--thresholds", str(bad)), 2)
    assert str(bad) in line and "colors.red" in line and "3 integers" in line
    broken = tmp_path / "broken.yaml"
    broken.write_text("lab: [unclosed")
    line = assert_one_error(run("detect", "--camera", cam, "--vendor-yaml", str(broken)), 2)
    assert str(broken) in line and "not valid YAML" in line
    line = assert_one_error(run("detect", "--camera", cam, "--colors", "purple"), 2)
    assert "no colour 'purple'" in line
    line = assert_one_error(run("detect", "--camera", cam, "--thresholds", str(bad),
                                "--vendor-yaml", str(VENDOR_YAML)), 2)
    assert "not both" in line
    line = assert_one_error(run("detect", "--camera", cam, "--section", "Stereo"), 2)
    assert "--section applies to the vendor's YAML" in line
    line = assert_one_error(run("detect", "--camera", cam, "--min-area", "-5"), 2)
    assert "-5" in line
    line = assert_one_error(run("detect", "--camera", cam, "--thresholds",
                                str(tmp_path / "none.toml")), 2)
    assert "no such file" in line
    (tmp_path / "file").write_text("")
    line = assert_one_error(run("detect", "--camera", cam, "--save", str(tmp_path / "file" /
                                                                        "sub")), 2)
    assert "cannot create the folder" in line
    result = CliRunner(mix_stderr=False).invoke(cli, ["vision", "detect"])
    assert result.exit_code == 2 and "--camera" in result.stderr


def test_cli_default_matches_the_library() -> None:
    assert vision_cmds.DEFAULT_MIN_AREA_PX == DEFAULT_MIN_AREA_PX
    result = CliRunner(mix_stderr=False).invoke(cli, ["--help"])
    assert "vision" in result.stdout
