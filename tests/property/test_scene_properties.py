"""Seeded scenes: always valid, reproducible, and a scene file reads back identically."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.twin.scene import (
    COLORS,
    MIN_GAP_MM,
    PLACE_BEARING_DEG,
    PLACE_RADIUS_MM,
    random_scene,
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
