"""``busarm bench vision``'s report: detection on the first family's pictures, and detect
+ localise per scene family (random: spaced-out blocks; clutter: the pick bench's
tables), each with its own target, and with shapes judged too."""

from __future__ import annotations

import pytest

from busarm.bench.vision import (
    FAMILIES,
    TARGET_CLUTTER_FPS,
    TARGET_LOCATE_FPS,
    run_vision_bench,
    twin_pictures,
)
from busarm.errors import ConfigError


def test_both_families_are_reported_with_their_targets() -> None:
    report = run_vision_bench(pictures=1, seconds_per_case=0.3)
    random, clutter = report.families
    assert (random.family, clutter.family) == ("random", "clutter")
    assert (random.target_fps, clutter.target_fps) == (TARGET_LOCATE_FPS, TARGET_CLUTTER_FPS)
    assert report.detect_and_locate_fps == random.fps
    assert report.blocks_located == random.blocks_located
    for rate in report.families:
        assert rate.pictures == 1 and rate.fps > 0 and rate.judged_fps > 0
        assert len(rate.fps_rounds) == 3
        assert rate.met == (rate.fps >= rate.target_fps)
    assert report.to_dict()["families"] == [r.__dict__ for r in report.families]


def test_a_cluttered_picture_has_the_familys_blocks() -> None:
    (image, joints), = twin_pictures(1, seed=3, family="clutter")
    assert image.shape == (480, 640, 3) and len(joints) >= 5
    assert FAMILIES["clutter"] == (6, 12)


def test_an_unknown_family_is_refused() -> None:
    with pytest.raises(ConfigError, match="family 'tidy'"):
        twin_pictures(1, family="tidy")
    with pytest.raises(ConfigError, match="families"):
        run_vision_bench(pictures=1, families=("random", "tidy"))
