"""Pictures the ``busarm`` command writes, checked by their bytes and pixels: the workspace
picture in the format its name asks for, the twin snapshot's caption, base-frame axes and
bins in their colours, detection labels that never overlap and read on any colour, and
scene files in TOML or JSON by their name.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.bench.synthetic import Block, render_blocks
from busarm.cli.main import cli
from busarm.twin.scene import load_scene, random_scene
from busarm.twin.snapshot import AXIS_BGR, OverviewView
from busarm.twin.twin import Twin
from busarm.vision.annotate import LABEL_BG

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

MAGIC = {".png": b"\x89PNG\r\n\x1a\n", ".jpg": b"\xff\xd8\xff", ".jpeg": b"\xff\xd8\xff",
         ".svg": b"<?xml", ".pdf": b"%PDF"}


def run(*args: str) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, list(args))


def one_error(result: Result, code: int = 2) -> str:
    assert result.exit_code == code, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


@pytest.mark.parametrize("suffix", list(MAGIC))
def test_workspace_writes_the_format_its_name_asks_for(tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"ws{suffix}"
    result = run("arm", "workspace", "--png", str(out), "--cell", "10")
    assert result.exit_code == 0, result.stderr
    assert out.read_bytes().startswith(MAGIC[suffix])
    if suffix in (".png", ".jpg", ".jpeg"):
        assert cv2.imread(str(out)).shape[1] > 600


@pytest.mark.parametrize("name", ["ws.txt", "ws", "ws.gif"])
def test_workspace_refuses_a_format_it_cannot_write(tmp_path: Path, name: str) -> None:
    line = one_error(run("arm", "workspace", "--png", str(tmp_path / name)))
    assert "is not one of .png, .jpg, .jpeg, .svg, .pdf" in line
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def snapshot(tmp_path_factory: pytest.TempPathFactory) -> tuple[np.ndarray, str, Path]:
    out = tmp_path_factory.mktemp("snap") / "scene.png"
    result = run("twin", "snapshot", "--seed", "3", "--png", str(out))
    assert result.exit_code == 0, result.stderr
    image = cv2.imread(str(out))
    assert image is not None
    return image, result.stdout, out


def test_snapshot_has_a_caption_saying_what_it_is(
        snapshot: tuple[np.ndarray, str, Path]) -> None:
    image, stdout, path = snapshot
    assert path.read_bytes().startswith(MAGIC[".png"])
    assert image.shape[1] == 1280 and image.shape[0] > 480
    caption = image[480:]
    dark = np.all(caption == LABEL_BG, axis=2).mean()
    bright = (caption.min(axis=2) > 200).sum()
    assert dark > 0.8 and bright > 200  # white text on the dark bar
    assert "scene seed 3 (5 blocks, 3 bins)" in stdout
    assert re.search(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d", stdout)  # when it was made
    for half in (image[:30, :640], image[:30, 640:]):  # each view has its title
        assert (half.min(axis=2) > 200).sum() > 100 and np.all(half == LABEL_BG, axis=2).any()


def test_snapshot_marks_the_bins_in_their_colours_and_the_base_frame(
        snapshot: tuple[np.ndarray, str, Path]) -> None:
    overview = snapshot[0][:480, 640:]
    scene = random_scene(3)
    with Twin(scene=scene, realtime=False) as twin:
        view = OverviewView(twin)
        raw = view.image()  # the same view, unmarked
        z = twin.config.table_z_mm
        bins = [(b.color, view.px([(b.x_mm, b.y_mm, z + 2.0)])[0]) for b in scene.bins]
        origin = view.px([(0.0, 0.0, z)])[0]
        x_mid = view.px([(75.0, 0.0, z)])[0]
        y_mid = view.px([(0.0, 75.0, z)])[0]
    channel = {"blue": 0, "green": 1, "red": 2}
    for color, (u, v) in bins:
        patch = overview[round(v) - 3:round(v) + 4, round(u) - 3:round(u) + 4].reshape(-1, 3)
        plain = raw[round(v) - 3:round(v) + 4, round(u) - 3:round(u) + 4].reshape(-1, 3)
        mean, grey = patch.mean(axis=0), plain.mean(axis=0)
        assert np.ptp(grey) < 20, (color, grey)  # the tray itself is grey...
        others = [mean[c] for c in range(3) if c != channel[color]]
        assert mean[channel[color]] > max(others) + 40, (color, mean)  # ...marked in colour
    u, v = (round(float(c)) for c in origin)
    assert overview[v, u].min() > 220  # the origin: a white dot
    for axis, (u, v) in (("x", x_mid), ("y", y_mid)):
        pixel = overview[round(v), round(u)].astype(int)
        assert np.abs(pixel - AXIS_BGR[axis]).max() < 60, (axis, pixel)


def test_snapshot_refuses_a_picture_format_it_cannot_write(tmp_path: Path) -> None:
    line = one_error(run("twin", "snapshot", "--png", str(tmp_path / "scene.txt")))
    assert "'.txt' is not one of .png, .jpg, .jpeg" in line
    assert list(tmp_path.iterdir()) == []


def test_detection_labels_never_overlap_and_read_on_any_colour(tmp_path: Path) -> None:
    # Blocks side by side (red next to red), one under another, one in a corner.
    blocks = [Block("red", (150, 200), 50, 10), Block("red", (215, 205), 50, -5),
              Block("green", (280, 200), 50, 20), Block("blue", (345, 195), 50, 0),
              Block("red", (410, 200), 50, 30), Block("red", (215, 270), 50, 0),
              Block("yellow", (600, 30), 40, 0)]
    (tmp_path / "in").mkdir()
    cv2.imwrite(str(tmp_path / "in" / "f.png"), render_blocks(blocks))
    result = run("vision", "detect", "--camera", str(tmp_path / "in"), "--save",
                 str(tmp_path / "out"), "--json")
    assert result.exit_code == 0, result.stderr
    assert len(json.loads(result.stdout)["detections"]) == len(blocks)
    saved = tmp_path / "out" / "frame_000000.png"
    assert saved.read_bytes().startswith(MAGIC[".png"])
    image = cv2.imread(str(saved))
    # Every label is a dark box; two that touched or overlapped would be one blob.
    mask = np.all(image == LABEL_BG, axis=2).astype(np.uint8)
    count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    boxes = [s for s in stats[1:] if s[cv2.CC_STAT_AREA] > 80]
    assert len(boxes) == len(blocks) + 1  # and the caption line at the top left
    heights = {int(s[cv2.CC_STAT_HEIGHT]) for s in boxes}
    assert max(heights) - min(heights) <= 1 and max(heights) < 25  # none stacked into one
    for s in boxes:  # white text in each: readable on red, green, blue and yellow blocks
        x, y, w, h = (int(v) for v in s[:4])
        assert (image[y:y + h, x:x + w].min(axis=2) > 200).sum() > 20


def test_scene_files_are_toml_or_json_by_their_name(tmp_path: Path) -> None:
    for name in ("s.toml", "s.json"):
        result = run("twin", "scene", "--seed", "7", "--blocks", "4", "-o", str(tmp_path / name))
        assert result.exit_code == 0, result.stderr
    data = json.loads((tmp_path / "s.json").read_text())
    assert data["format"] == "busarm.scene" and len(data["blocks"]) == 4
    assert tomllib.loads((tmp_path / "s.toml").read_text())["seed"] == 7
    assert load_scene(tmp_path / "s.json").blocks == load_scene(tmp_path / "s.toml").blocks \
        == random_scene(7, 4).blocks
    png = tmp_path / "from-json.png"
    result = run("twin", "snapshot", "--scene", str(tmp_path / "s.json"), "--view", "arm",
                 "--png", str(png))
    assert result.exit_code == 0, result.stderr
    line = one_error(run("twin", "scene", "-o", str(tmp_path / "s.yaml")))
    assert "s.yaml" in line and ".toml or .json" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["from-json.png", "s.json", "s.toml"]
