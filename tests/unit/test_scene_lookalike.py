"""Issue 32's scenes: tagged blocks, tall boxes and look-alikes in block colours, trays for
size classes; every new field reads back from a scene file, old files read as before,
bad values are refused naming the range; the lookalike, sized and tagged families are
the same for the same seed, valid, in reach and apart."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import replace
from pathlib import Path

import pytest

from busarm.errors import ConfigError
from busarm.twin.block_tags import TAG_CELLS, tag_black_cells, tag_rects, tag_square_mm
from busarm.twin.clutter import BIN_CLEARANCE_MM
from busarm.twin.footprints import penetration_mm
from busarm.twin.lookalike import (
    LOOKALIKE_GAP_MM,
    SIZE_MARGIN_MM,
    block_mass_g,
    lookalike_scene,
    size_class,
    sized_scene,
    tagged_scene,
)
from busarm.twin.scene import (
    COLORS,
    DEFAULT_BINS,
    MIN_GAP_MM,
    PLACE_BEARING_DEG,
    PLACE_RADIUS_MM,
    REACH_RADIUS_MM,
    SIZE_CLASSES_MM,
    Bin,
    Block,
    Distractor,
    Scene,
    load_scene,
    save_scene,
    scene_from_json,
    scene_from_toml,
    scene_to_json,
    scene_to_toml,
)

CARTON = Distractor("box", "green", 250.0, -90.0, 30.0, 25.0, 70.0, 20.0, 40.0)
RED_CUP = Distractor("cylinder", "red", 170.0, 120.0, 32.0, 32.0, 40.0)


def test_new_fields_round_trip_and_old_files_read_as_before(tmp_path: Path) -> None:
    scene = Scene(blocks=(Block("red", 200.0, 0.0, 10.0, 45.0, 67.4, tag_id=586),
                          Block("blue", 200.0, 90.0, 0.0, 20.0, tag_id=0),
                          Block("green", 140.0, -60.0)),
                  bins=(Bin("small", DEFAULT_BINS[0].x_mm, DEFAULT_BINS[0].y_mm),),
                  distractors=(CARTON, RED_CUP))
    for name, read in (("s.toml", scene_from_toml), ("s.json", scene_from_json)):
        path = tmp_path / name
        save_scene(path, scene)
        assert load_scene(path) == replace(scene, source=str(path))
        assert read(path.read_text(), str(path)).blocks[2].tag_id is None
    text = scene_to_toml(scene)
    assert text.count("tag_id = ") == 2 and 'shape = "box"' in text
    # A block without a tag is written as before issue 32, and such a file reads back.
    plain = Scene(blocks=(Block("green", 140.0, -60.0),))
    assert "tag_id" not in scene_to_toml(plain) and "tag_id" not in scene_to_json(plain)
    old = ('format = "busarm.scene"\nversion = 1\n[[blocks]]\ncolor = "red"\nx_mm = 200.0\n'
           'y_mm = 0.0\n[[distractors]]\nshape = "disc"\ncolor = "grey"\nx_mm = 150.0\n'
           'y_mm = 90.0\nlength_mm = 30.0\nwidth_mm = 30.0\nheight_mm = 3.0\n')
    loaded = scene_from_toml(old)
    assert loaded.blocks[0].tag_id is None and loaded.blocks[0].size_mm == 30.0
    assert loaded.distractors[0].color == "grey"


@pytest.mark.parametrize(("scene_args", "message"), [
    ({"blocks": (Block("red", 200.0, 0.0, tag_id=-1),)},
     r"blocks\[0\]\.tag_id \(AprilTag 36h11\) = -1 is out of range 0\.\.586"),
    ({"blocks": (Block("red", 200.0, 0.0, tag_id=587),)},
     r"blocks\[0\]\.tag_id \(AprilTag 36h11\) = 587 is out of range 0\.\.586"),
    ({"blocks": (Block("red", 200.0, 0.0, tag_id=3.0),)},
     r"blocks\[0\]\.tag_id \(AprilTag 36h11\) must be an integer 0\.\.586, got 3\.0"),
    ({"blocks": (Block("red", 200.0, 0.0, tag_id=True),)},
     r"tag_id \(AprilTag 36h11\) must be an integer"),
    ({"distractors": (replace(CARTON, height_mm=35.0),)},
     r"distractors\[0\]\.height_mm of a box = 35\.0 is out of range 50\.\.90"),
    ({"distractors": (replace(CARTON, width_mm=20.0, length_mm=40.0),)},
     r"distractors\[0\] is a box of 40\.0 x 20\.0 mm: its longer side may be at most 1\.5 x"),
    ({"distractors": (replace(CARTON, color="pink"),)},
     r"distractors\[0\]\.color = 'pink'; allowed: .*purple, red, green, blue, yellow"),
    ({"bins": (Bin("huge", 66.69, 183.24),)},
     r"bins\[0\]\.color = 'huge'; allowed: red, green, blue, yellow, small, medium, large"),
])
def test_bad_values_are_refused_naming_the_range(scene_args: dict[str, object],
                                                 message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        Scene(**scene_args)  # type: ignore[arg-type]


def test_tag_cells_are_drawn_exactly_by_the_rectangles() -> None:
    for tag_id in (0, 7, 300, 586):
        cells = tag_black_cells(tag_id)
        drawn = [[0] * TAG_CELLS for _ in range(TAG_CELLS)]
        for row0, col0, rows, cols in tag_rects(tag_id):
            for r in range(row0, row0 + rows):
                for c in range(col0, col0 + cols):
                    drawn[r][c] += 1
        assert drawn == [[int(v) for v in row] for row in cells]  # each black cell once
        assert all(cells[0]) and all(row[0] and row[-1] for row in cells)  # the border
        assert len(tag_rects(tag_id)) < 30
    assert tag_black_cells(1) != tag_black_cells(2)
    assert tag_square_mm(40.0) == 30.0
    with pytest.raises(ConfigError, match="tag id 587 is out of range 0..586"):
        tag_black_cells(587)


def test_size_classes_and_masses() -> None:
    assert [size_class(s) for s in (20.0, 27.9, 28.0, 37.0, 37.1, 45.0)] == [
        "small", "small", "medium", "medium", "large", "large"]
    assert block_mass_g(30.0) == 20.0 and block_mass_g(45.0) == 67.4
    with pytest.raises(ConfigError, match="block side = 61 mm is out of range 10..60 mm"):
        size_class(61)


def _in_reach(x: float, y: float, radius_mm: tuple[float, float]) -> bool:
    bearing = math.degrees(math.atan2(y, x))
    return (radius_mm[0] <= math.hypot(x, y) <= radius_mm[1]
            and PLACE_BEARING_DEG[0] <= bearing <= PLACE_BEARING_DEG[1])


def _apart(scene: Scene, gap_mm: float) -> None:
    fps = [*(b.footprint for b in scene.blocks), *(d.footprint for d in scene.distractors)]
    for i, a in enumerate(fps):
        assert all(penetration_mm(a, b) <= -gap_mm + 1e-6 for b in fps[i + 1:]), scene.source
        assert all(penetration_mm(a, t.footprint) <= -BIN_CLEARANCE_MM + 1e-6
                   for t in scene.bins), scene.source


def test_the_families_are_reproducible_valid_in_reach_and_apart() -> None:
    seen: Counter[str] = Counter()
    for seed in range(50):
        look, sized, tagged = lookalike_scene(seed), sized_scene(seed), tagged_scene(seed)
        assert (look, sized, tagged) == (lookalike_scene(seed), sized_scene(seed),
                                         tagged_scene(seed))
        for scene in (look, sized, tagged):  # a file of it reads back as it is
            assert scene_from_toml(scene_to_toml(scene), scene.source) == scene
        assert 3 <= len(look.blocks) <= 6 and 2 <= len(look.distractors) <= 4
        assert {b.color for b in look.bins} == {"red", "green", "blue"}
        for b in look.blocks + sized.blocks:
            assert 20.0 <= b.size_mm <= 45.0 and b.color in ("red", "green", "blue")
            assert b.mass_g == block_mass_g(b.size_mm) and b.tag_id is None
        for d in look.distractors:
            assert d.color in COLORS or d.color == "purple"
            seen[f"{d.color} {d.shape}" if d.shape != "box" else "box"] += 1
            assert d.shape != "box" or d.height_mm > max(b.size_mm for b in look.blocks)
        assert all(_in_reach(x, y, REACH_RADIUS_MM) for x, y in (
            *((t.x_mm, t.y_mm) for t in (*look.blocks, *sized.blocks)),
            *((d.x_mm, d.y_mm) for d in look.distractors)))
        _apart(look, LOOKALIKE_GAP_MM)
        _apart(sized, LOOKALIKE_GAP_MM)
        classes = [size_class(b.size_mm) for b in sized.blocks]
        assert 4 <= len(classes) <= 6 and set(classes) == set(SIZE_CLASSES_MM)
        assert all(abs(b.size_mm - edge) >= SIZE_MARGIN_MM
                   for b in sized.blocks for edge in (28.0, 37.0))
        assert [b.color for b in sized.bins] == ["small", "medium", "large"]
        ids = [b.tag_id for b in tagged.blocks]
        assert 3 <= len(ids) <= 5 and len(set(ids)) == len(ids)
        assert all(i is not None and 0 <= i <= 9 for i in ids)
        assert len({b.size_mm for b in tagged.blocks}) == 1
        assert 25.0 <= tagged.blocks[0].size_mm <= 35.0
        assert all(_in_reach(b.x_mm, b.y_mm, PLACE_RADIUS_MM) for b in tagged.blocks)
        _apart(tagged, MIN_GAP_MM)
    assert set(seen) == {"purple cylinder", "red cylinder", "green disc", "blue bar", "box"}
    assert lookalike_scene(1) != lookalike_scene(2)
    assert len(lookalike_scene(4, 6).blocks) == 6 and len(tagged_scene(4, 3).blocks) == 3
    with pytest.raises(ConfigError, match="blocks = 7 is out of range 3..6"):
        lookalike_scene(0, 7)
    with pytest.raises(ConfigError, match="blocks = 6 is out of range 3..5"):
        tagged_scene(0, 6)
