"""Scenes: seeded ones always valid and reproducible, a scene file (distractors and
lighting too) reads back identically, and the overlap rule is exact: checked against a
brute-force polygon intersection, touching accepted, 0.1 mm of overlap refused."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.errors import ConfigError
from busarm.twin.footprints import Footprint, overlaps, penetration_mm
from busarm.twin.scene import (
    COLORS,
    DEFAULT_BINS,
    MIN_GAP_MM,
    PLACE_BEARING_DEG,
    PLACE_RADIUS_MM,
    Bin,
    Block,
    Distractor,
    Lighting,
    Scene,
    load_scene,
    random_scene,
    save_scene,
    scene_from_toml,
    scene_to_toml,
)

colors = st.lists(st.sampled_from(list(COLORS)), min_size=1, max_size=4, unique=True)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 8), names=colors)
def test_random_scenes_are_valid_spread_and_reproducible(seed: int, n: int,
                                                         names: list[str]) -> None:
    scene = random_scene(seed, n, names)
    assert scene == random_scene(seed, n, names)
    assert len(scene.blocks) == n
    if n >= len(names):
        assert {b.color for b in scene.blocks} == set(names)
    for i, b in enumerate(scene.blocks):
        r = math.hypot(b.x_mm, b.y_mm)
        assert PLACE_RADIUS_MM[0] - 0.01 <= r <= PLACE_RADIUS_MM[1] + 0.01
        bearing = math.degrees(math.atan2(b.y_mm, b.x_mm))
        assert PLACE_BEARING_DEG[0] - 0.01 <= bearing <= PLACE_BEARING_DEG[1] + 0.01
        for other in scene.blocks[i + 1:]:
            gap = math.hypot(b.x_mm - other.x_mm, b.y_mm - other.y_mm)
            assert gap >= b.size_mm * math.sqrt(2) + MIN_GAP_MM - 0.02
    assert {t.color for t in scene.bins} == set(names)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 6), names=colors)
def test_scene_files_read_back_identically(seed: int, n: int, names: list[str]) -> None:
    scene = random_scene(seed, n, names)
    again = scene_from_toml(scene_to_toml(scene), scene.source)
    assert again == scene


# ---------------------------------------------------------------- the overlap rule

Polygon = list[tuple[float, float]]


def _polygon(fp: Footprint, sides: int = 720) -> Polygon:
    """The footprint as a counter-clockwise polygon (a disc as an inscribed 720-gon,
    within 0.001 mm of the circle)."""
    if not fp.round:
        return fp.corners()
    return [(fp.x_mm + fp.half_x_mm * math.cos(2 * math.pi * k / sides),
             fp.y_mm + fp.half_x_mm * math.sin(2 * math.pi * k / sides)) for k in range(sides)]


def _clip(subject: Polygon, clip: Polygon) -> Polygon:
    """Sutherland-Hodgman: the part of convex ``subject`` inside convex ``clip`` (CCW)."""
    out = subject
    for (ax, ay), (bx, by) in zip(clip, clip[1:] + clip[:1], strict=True):
        def inside(p: tuple[float, float], ax: float = ax, ay: float = ay, bx: float = bx,
                   by: float = by) -> float:
            return (bx - ax) * (p[1] - ay) - (by - ay) * (p[0] - ax)

        points, out = out, []
        for p, q in zip(points, points[1:] + points[:1], strict=True):
            sp, sq = inside(p), inside(q)
            if sp >= 0:
                out.append(p)
            if (sp >= 0) != (sq >= 0):
                t = sp / (sp - sq)
                out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
        if not out:
            return []
    return out


def _area(poly: Polygon) -> float:
    return abs(sum(x0 * y1 - x1 * y0 for (x0, y0), (x1, y1)
                   in zip(poly, poly[1:] + poly[:1], strict=True))) / 2


def overlap_area(a: Footprint, b: Footprint) -> float:
    """Brute force: the area both footprints cover (mm^2)."""
    pa, pb = _polygon(a), _polygon(b)
    if len(pa) < len(pb):
        pa, pb = pb, pa  # clip by the one with fewer edges: 4 passes, not 720
    return _area(_clip(pa, pb))


def _moved(fp: Footprint, dx: float, dy: float) -> Footprint:
    return replace(fp, x_mm=fp.x_mm + dx, y_mm=fp.y_mm + dy)


rects = st.builds(Footprint, x_mm=st.floats(-60, 60), y_mm=st.floats(-60, 60),
                  half_x_mm=st.floats(3, 40), half_y_mm=st.floats(3, 40),
                  yaw_deg=st.floats(-180, 180))
discs = st.builds(Footprint.disc, x_mm=st.floats(-60, 60), y_mm=st.floats(-60, 60),
                  diameter_mm=st.floats(6, 100))
footprints = st.one_of(rects, discs)
OVERLAPPING_MM2 = 1e-7
"""A shared area above this is an overlap; a corner 0.01 mm deep covers 1e-4 mm^2."""


@settings(max_examples=200, deadline=None)
@given(a=footprints, b=rects, swap=st.booleans(), direction_deg=st.floats(0, 360))
def test_penetration_is_the_shortest_shift_that_parts_two_footprints(
        a: Footprint, b: Footprint, swap: bool, direction_deg: float) -> None:
    """Checked against the brute-force shared area: overlapping exactly when the
    penetration is positive; no shift shorter than it parts them (any direction); for two
    rectangles one of their edge normals parts them with a shift just longer."""
    if swap:
        a, b = b, a
    depth = penetration_mm(a, b)
    assert depth == pytest.approx(penetration_mm(b, a), abs=1e-9)
    area = overlap_area(a, b)
    if depth > 0.01:
        assert area > OVERLAPPING_MM2, (depth, area)
        assert overlaps(a, b)
        u = math.radians(direction_deg)
        shorter = _moved(b, (depth - 0.01) * math.cos(u), (depth - 0.01) * math.sin(u))
        assert overlap_area(a, shorter) > OVERLAPPING_MM2
        if not (a.round or b.round):
            parted = [overlap_area(a, _moved(b, sign * (depth + 0.01) * nx,
                                             sign * (depth + 0.01) * ny))
                      for nx, ny in (*a.axes(), *b.axes()) for sign in (1, -1)]
            assert min(parted) <= OVERLAPPING_MM2
    elif depth < -0.001:
        assert area <= OVERLAPPING_MM2, (depth, area)
        assert not overlaps(a, b)


def test_two_discs_overlap_when_nearer_than_their_radii() -> None:
    a, b = Footprint.disc(0.0, 0.0, 40.0), Footprint.disc(30.0, 40.0, 60.0)  # 50 mm apart
    assert penetration_mm(a, b) == pytest.approx(0.0)
    assert not overlaps(a, b)
    assert overlaps(a, _moved(b, -0.06, -0.08))  # 0.1 mm nearer
    assert penetration_mm(a, _moved(b, 3.0, 4.0)) == pytest.approx(-5.0)


def _touching_pair(size_a: float, size_b: float, yaw_a: float, yaw_b: float, side: int,
                   along: float) -> tuple[Block, Block, tuple[float, float]]:
    """Block b resting against face ``side`` (0-3) of block a (at 200, 0), its lowest
    corner (or edge) on that face ``along`` (-1..1) of the way from its middle to 2 mm
    from its ends; and the face's outward normal."""
    a = Block("red", 200.0, 0.0, yaw_a, size_a)
    ux, uy = a.footprint.axes()[side % 2]
    sign = 1 if side < 2 else -1
    nx, ny = sign * ux, sign * uy
    tx, ty = -ny, nx
    b0 = Block("blue", 0.0, 0.0, yaw_b, size_b).footprint
    low_x, low_y = min(b0.corners(), key=lambda c: c[0] * nx + c[1] * ny)  # toward a
    t = along * (size_a / 2 - 2.0)
    px = a.x_mm + nx * size_a / 2 + tx * t
    py = a.y_mm + ny * size_a / 2 + ty * t
    return a, Block("blue", px - low_x, py - low_y, yaw_b, size_b), (nx, ny)


@settings(max_examples=150, deadline=None)
@given(size_a=st.floats(25, 40), size_b=st.floats(25, 40), yaw_a=st.floats(-90, 90),
       yaw_b=st.floats(-90, 90), side=st.integers(0, 3), along=st.floats(-1, 1))
def test_blocks_may_touch_but_not_overlap_by_a_tenth_of_a_mm(
        size_a: float, size_b: float, yaw_a: float, yaw_b: float, side: int,
        along: float) -> None:
    a, b, (nx, ny) = _touching_pair(size_a, size_b, yaw_a, yaw_b, side, along)
    assert penetration_mm(a.footprint, b.footprint) == pytest.approx(0.0, abs=1e-6)
    assert overlap_area(a.footprint, b.footprint) <= OVERLAPPING_MM2
    assert Scene(blocks=(a, b)).blocks == (a, b)
    pushed = replace(b, x_mm=b.x_mm - 0.1 * nx, y_mm=b.y_mm - 0.1 * ny)
    assert penetration_mm(a.footprint, pushed.footprint) == pytest.approx(0.1, abs=1e-6)
    with pytest.raises(ConfigError, match=r"blocks\[0\].*blocks\[1\].*overlap by 0\.10 mm"):
        Scene(blocks=(a, pushed))


def test_blocks_stand_against_a_bin_wall_but_not_in_it() -> None:
    tray = Bin("red", 200.0, 0.0)  # 90 mm square: its walls' outer faces at 155/245, -45/45
    for block in (Block("red", 260.0, 0.0), Block("red", 200.0, 60.0, 0.0),
                  Block("red", 139.99, -40.0, 0.0, 30.0), Block("red", 260.0, 60.0)):
        Scene(blocks=(block,), bins=(tray,))
    for block in (Block("red", 259.9, 0.0), Block("red", 200.0, 59.9, 0.0),
                  Block("red", 200.0, 0.0), Block("red", 260.0, 0.0, 10.0)):
        with pytest.raises(ConfigError, match=r"blocks\[0\].*bins\[0\].*overlap"):
            Scene(blocks=(block,), bins=(tray,))


def test_sizes_of_toy_blocks_are_accepted_and_odd_ones_refused() -> None:
    row = tuple(Block("green", 200.0 + x, 0.0, 0.0, s)
                for x, s in ((-32.5, 25.0), (0.0, 40.0), (35.0, 30.0)))
    assert Scene(blocks=row).blocks == row  # 25, 40 and 30 mm, each touching the next
    with pytest.raises(ConfigError, match=r"blocks\[0\]\.size_mm = 70\.0 is out of range 10\.\.60"):
        Scene(blocks=(Block("green", 200.0, 0.0, 0.0, 70.0),))


# ---------------------------------------------------------------- distractors and light

PEN = Distractor("bar", "purple", 200.0, -80.0, 140.0, 10.0, 10.0, 30.0, 15.0)
CUP = Distractor("cylinder", "white", 260.0, 60.0, 70.0, 70.0, 90.0, 0.0, 150.0)
COIN = Distractor("disc", "brown", 150.0, 60.0, 25.0, 25.0, 2.0)


def test_distractors_and_lighting_round_trip_through_a_scene_file(tmp_path: Path) -> None:
    light = Lighting(intensity=0.8, key_azimuth_deg=-120.0, key_elevation_deg=35.0,
                     key_share=0.5, color_temp_k=3000.0)
    scene = Scene(blocks=(Block("red", 200.0, 0.0, 10.0),), bins=DEFAULT_BINS[:2],
                  distractors=(PEN, CUP, COIN), lighting=light, source=str(tmp_path / "s.toml"))
    save_scene(tmp_path / "s.toml", scene)
    text = (tmp_path / "s.toml").read_text()
    assert "[lighting]" in text and text.count("[[distractors]]") == 3
    assert load_scene(tmp_path / "s.toml") == scene
    # ... and a scene in the usual light writes no [lighting] (older files stay as they were).
    plain = replace(scene, lighting=Lighting())
    assert "[lighting]" not in scene_to_toml(plain)
    assert scene_from_toml(scene_to_toml(plain), scene.source) == plain


@pytest.mark.parametrize(("change", "message"), [
    ({"shape": "cube"}, r"distractors\[0\]\.shape = 'cube'; allowed: cylinder, disc, bar"),
    ({"color": "pink"}, r"distractors\[0\]\.color = 'pink'; allowed: grey, white, brown, "
                        r"purple, red, green, blue, yellow"),
    ({"height_mm": 25.0}, r"height_mm of a cylinder = 25\.0 is out of range 30\.\.120"),
    ({"width_mm": 40.0}, r"width_mm = 40\.0: a cylinder is round"),
    ({"x_mm": 60.0, "y_mm": 0.0}, r"within 90 mm of the arm base"),
    ({"x_mm": 215.0, "y_mm": 0.0}, r"blocks\[0\].*distractors\[0\].*overlap"),
    ({"x_mm": 400.0}, r"hangs off the table"),
])
def test_bad_distractors_are_refused_with_what_is_allowed(change: dict[str, object],
                                                          message: str) -> None:
    thing = replace(CUP, **change)
    with pytest.raises(ConfigError, match=message):
        Scene(blocks=(Block("red", 200.0, 0.0),), distractors=(thing,))


def test_bad_lighting_is_refused_with_its_range() -> None:
    with pytest.raises(ConfigError, match=r"lighting\.color_temp_k = 10000\.0 is out of "
                                          r"range 2700\.\.6500"):
        Scene(lighting=Lighting(color_temp_k=10000.0))
    with pytest.raises(ConfigError, match=r"lighting: unknown key\(s\) lux;"):
        scene_from_toml('format = "busarm.scene"\nversion = 1\n[lighting]\nlux = 300\n')
