"""The clutter family: every seed a valid table like a real one (rows, clusters, touching
blocks, distractors, a lamp's light), in reach and clear of the bins, the same every time;
and the twin URL that asks for one."""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.errors import ConfigError
from busarm.robot.port_url import parse_port
from busarm.twin.clutter import (
    BIN_CLEARANCE_MM,
    CLUTTER_DISTRACTOR_COLORS,
    CLUTTER_LIGHTING,
    CLUTTER_MAX_BLOCKS,
    clutter_scene,
)
from busarm.twin.footprints import Footprint
from busarm.twin.scene import (
    COLORS,
    DISTRACTOR_COLORS,
    PLACE_BEARING_DEG,
    REACH_RADIUS_MM,
    Block,
    Lighting,
    Scene,
    check_scene,
    scene_from_toml,
    scene_to_toml,
)
from busarm.twin.spec import TwinSpec

SEEDS = range(201)


def _segment_distance(p: tuple[float, float], a: tuple[float, float],
                      b: tuple[float, float]) -> float:
    (px, py), (ax, ay), (bx, by) = p, a, b
    dx, dy = bx - ax, by - ay
    t = max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / (dx * dx + dy * dy)))
    return math.hypot(px - ax - t * dx, py - ay - t * dy)


def gap_mm(a: Footprint, b: Footprint) -> float:
    """Brute force: how far apart two rectangles are that do not overlap (corner to edge)."""
    ca, cb = a.corners(), b.corners()
    return min(min(_segment_distance(p, q, r) for q, r in zip(edges, edges[1:] + edges[:1],
                                                              strict=True))
               for points, edges in ((ca, cb), (cb, ca)) for p in points)


def _touching(blocks: tuple[Block, ...]) -> Counter[int]:
    """How many neighbours each block touches (within 0.1 mm)."""
    out: Counter[int] = Counter()
    for i, a in enumerate(blocks):
        for j, b in enumerate(blocks):
            if i != j and gap_mm(a.footprint, b.footprint) < 0.1:
                out[i] += 1
    return out


@pytest.fixture(scope="module")
def family() -> list[Scene]:
    return [clutter_scene(seed) for seed in SEEDS]


def test_every_scene_is_valid_in_reach_and_clear_of_the_bins(family: list[Scene]) -> None:
    for scene in family:
        check_scene(scene)
        assert 4 <= len(scene.blocks) <= 8 <= CLUTTER_MAX_BLOCKS
        assert {b.color for b in scene.bins} == set(COLORS)
        for b in scene.blocks:
            r = math.hypot(b.x_mm, b.y_mm)
            bearing = math.degrees(math.atan2(b.y_mm, b.x_mm))
            assert REACH_RADIUS_MM[0] <= r <= REACH_RADIUS_MM[1], (scene.seed, b)
            assert PLACE_BEARING_DEG[0] <= bearing <= PLACE_BEARING_DEG[1], (scene.seed, b)
            for tray in scene.bins:
                assert gap_mm(b.footprint, tray.footprint) >= BIN_CLEARANCE_MM - 1e-6
        for d in scene.distractors:
            assert d.color in DISTRACTOR_COLORS and d.color not in COLORS
        assert scene_from_toml(scene_to_toml(scene), scene.source) == scene


def test_the_family_has_what_real_tables_have(family: list[Scene]) -> None:
    """Counted over seeds 0..200: touching pairs, blocks touching two others (a touching
    row), touching 2x2 squares, single-colour tables and mixed ones, blocks at the edge
    of the reach, distractors of every shape and colour, and lights of every kind."""
    touching = [_touching(s.blocks) for s in family]
    assert sum(1 for t in touching if t) >= 120
    assert sum(1 for t in touching if any(n >= 2 for n in t.values())) >= 40
    # In a touching 2x2 square each block touches the three others (one at a corner).
    squares = sum(1 for t in touching if sum(1 for n in t.values() if n >= 3) >= 4)
    assert squares >= 20
    assert sum(1 for s in family if len({b.color for b in s.blocks}) == 1) >= 10
    assert sum(1 for s in family if any(len({b.color for b in s.blocks}) == k
                                        for k in (3, 4))) >= 50
    edge = REACH_RADIUS_MM[1] - 20.0
    assert sum(1 for s in family if any(math.hypot(b.x_mm, b.y_mm) > edge
                                        for b in s.blocks)) >= 60
    things = [d for s in family for d in s.distractors]
    assert {d.shape for d in things} == {"cylinder", "disc", "bar"}
    assert {d.color for d in things} == set(CLUTTER_DISTRACTOR_COLORS)
    assert sum(1 for s in family if s.distractors) >= 120
    assert len({s.lighting for s in family}) == len(family)
    yaws = {round(b.yaw_deg) for s in family for b in s.blocks}
    assert len(yaws) > 60  # a yaw per group, all sorts


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), blocks=st.integers(0, CLUTTER_MAX_BLOCKS),
       names=st.lists(st.sampled_from(list(COLORS)), min_size=1, max_size=4, unique=True),
       distractors=st.one_of(st.none(), st.integers(0, 4)),
       sizes=st.one_of(st.floats(25, 40), st.tuples(st.floats(25, 32), st.floats(32, 40))))
def test_any_seed_gives_the_same_valid_scene_every_time(
        seed: int, blocks: int, names: list[str], distractors: int | None,
        sizes: float | tuple[float, float]) -> None:
    scene = clutter_scene(seed, blocks, names, distractors=distractors, size_mm=sizes)
    assert scene == clutter_scene(seed, blocks, names, distractors=distractors, size_mm=sizes)
    assert (blocks + 1) // 2 <= len(scene.blocks) <= blocks
    assert {b.color for b in scene.blocks} <= set(names)
    assert {b.color for b in scene.bins} == set(names)
    lo, hi = (sizes, sizes) if isinstance(sizes, float) else sizes
    assert all(lo <= b.size_mm <= hi for b in scene.blocks)
    assert len(scene.distractors) <= (3 if distractors is None else distractors)
    for name, (a, b) in CLUTTER_LIGHTING.items():
        assert a - 5 <= getattr(scene.lighting, name) <= b + 5
    assert clutter_scene(seed, blocks, names, lighting=False).lighting == Lighting()


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"blocks": 13}, r"blocks = 13 is out of range 0\.\.12"),
    ({"size_mm": 20.0}, r"size_mm = 20\.0 mm is out of range 25\.\.40 mm"),
    ({"colors": ["red", "pink"]}, r"colors pink: give distinct colours"),
    ({"distractors": 5}, r"distractors = 5 is out of range 0\.\.4"),
])
def test_bad_requests_are_refused_with_what_is_allowed(kwargs: dict[str, object],
                                                       message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        clutter_scene(1, **kwargs)


def _twin_scene(url: str) -> Scene:
    """The scene on the table of the twin the port ``url`` names."""
    twin = parse_port(url)
    assert isinstance(twin, TwinSpec)
    return twin.make_scene()


def test_the_twin_url_asks_for_a_clutter_scene() -> None:
    assert _twin_scene("twin://?family=clutter&seed=3&blocks=12") == clutter_scene(3, 12)
    assert _twin_scene("twin://?family=clutter") == clutter_scene(0, 8)
    assert _twin_scene("twin://?family=clutter&seed=5&colors=red,blue") == \
        clutter_scene(5, 8, ["red", "blue"])
    # The random family is as it was, named or not.
    assert _twin_scene("twin://?family=random&seed=3") == _twin_scene("twin://?seed=3")
    # The typed twin, as a library user gives it, is the same table.
    assert TwinSpec(family="clutter", seed=3, blocks=12).make_scene() == clutter_scene(3, 12)
    assert TwinSpec(family="clutter", seed=5, colors=("red", "blue")).make_scene() == \
        clutter_scene(5, 8, ["red", "blue"])
    assert TwinSpec(family="random", seed=3).make_scene() == TwinSpec(seed=3).make_scene()


BAD_TWINS = [
    ("twin://?family=clutter&blocks=13", {"family": "clutter", "blocks": 13},
     r"blocks \(family clutter\) = 13 is out of range 0\.\.12"),
    ("twin://?blocks=9", {"blocks": 9}, r"blocks \(family random\) = 9 is out of range 0\.\.8"),
    ("twin://?family=messy", {"family": "messy"}, r"family = 'messy'; allowed: random, clutter"),
    ("twin://?family=clutter&board=tags", {"family": "clutter", "board": "tags"},
     r"board is for family random"),
    ("twin://?family=clutter&scene=x.toml", {"family": "clutter", "scene": Path("x.toml")},
     r"either scene or family"),
]


@pytest.mark.parametrize(("url", "message"), [(url, m) for url, _kw, m in BAD_TWINS])
def test_bad_twin_urls_are_refused_clearly(url: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        _twin_scene(url)


@pytest.mark.parametrize(("kwargs", "message"), [(kw, m) for _url, kw, m in BAD_TWINS])
def test_bad_twins_are_refused_clearly(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        TwinSpec(**kwargs).make_scene()
