"""Properties of the vision layer (hypothesis, derandomized so every run is the same):
a rendered square of any place, size, yaw and colour is found once, at its centre, with
its yaw modulo 90; thresholds survive our TOML and the vendor's YAML; yaw normalisation."""

from __future__ import annotations

import math
from pathlib import Path

import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.bench.synthetic import Block, render_blocks
from busarm.vision.color import ColorDetector, normalize_yaw_deg
from busarm.vision.color_thresholds import (
    ColorRange,
    ColorThresholds,
    default_thresholds,
    load_thresholds,
    save_thresholds,
    thresholds_from_toml,
    thresholds_from_vendor_yaml,
    thresholds_to_toml,
)

PROPS = settings(max_examples=60, deadline=None, derandomize=True)
W, H = 320, 240
DETECTOR = ColorDetector(default_thresholds(), min_area_px=150)


@st.composite
def blocks(draw: st.DrawFn) -> Block:
    side = draw(st.floats(22.0, 80.0))
    reach = side * math.sqrt(0.5) + 3.0
    u = draw(st.floats(reach, W - 1 - reach))
    v = draw(st.floats(reach, H - 1 - reach))
    color = draw(st.sampled_from(["red", "green", "blue", "yellow"]))
    return Block(color, (u, v), side, draw(st.floats(-180.0, 180.0)))


@PROPS
@given(blocks(), st.integers(0, 2**16), st.floats(0.0, 0.3))
def test_a_square_is_found_where_it_is(block: Block, seed: int, lighting: float) -> None:
    image = render_blocks([block], W, H, seed=seed, lighting=lighting)
    (det,) = DETECTOR.detect(image)
    assert det.color == block.color
    # A thresholded edge along the pixel grid gains or loses a whole row, which moves
    # the centroid up to half a pixel per axis whatever the size (typically 0.1 px), and
    # tilts the outline by up to about two pixels over its side.
    assert math.dist(det.centroid_px, block.center_px) < 0.75
    assert abs(normalize_yaw_deg(det.yaw_deg - block.yaw_deg)[0]) < 130.0 / block.side_px
    assert -45.0 < det.yaw_deg <= 45.0
    assert 0.95 < det.area_px / block.side_px**2 < 1.3


@PROPS
@given(blocks(), st.integers(1, 4))
def test_downscale_does_not_move_the_centroid(block: Block, downscale: int) -> None:
    image = render_blocks([block], W, H, seed=1)
    (full,) = ColorDetector(default_thresholds(), downscale=1, min_area_px=150).detect(image)
    (coarse,) = ColorDetector(default_thresholds(), downscale=downscale,
                              min_area_px=150).detect(image)
    # The coarse pass only picks the window; the measurement is the same.
    assert math.dist(full.centroid_px, coarse.centroid_px) < 1e-9


lab = st.tuples(st.integers(0, 255), st.integers(0, 255), st.integers(0, 255))
names = st.from_regex(r"[A-Za-z][A-Za-z0-9_-]{0,11}", fullmatch=True)


@st.composite
def thresholds(draw: st.DrawFn) -> ColorThresholds:
    ranges = []
    for name in draw(st.lists(names, min_size=1, max_size=10, unique=True)):
        a, b = draw(lab), draw(lab)
        lo = tuple(min(x, y) for x, y in zip(a, b, strict=True))
        hi = tuple(max(x, y) for x, y in zip(a, b, strict=True))
        ranges.append(ColorRange(name, lo, hi))  # type: ignore[arg-type]
    size = draw(st.none() | st.tuples(st.integers(1, 4096), st.integers(1, 4096)))
    return ColorThresholds(ranges, image_size_px=size)


@PROPS
@given(thresholds())
def test_thresholds_round_trip_our_toml(table: ColorThresholds) -> None:
    back = thresholds_from_toml(thresholds_to_toml(table))
    assert back == table and back.names == table.names


@settings(max_examples=15, deadline=None, derandomize=True)
@given(thresholds())
def test_thresholds_round_trip_through_a_file(tmp_path_factory: object,
                                              table: ColorThresholds) -> None:
    path = Path(tmp_path_factory.mktemp("t")) / "c.toml"  # type: ignore[attr-defined]
    save_thresholds(path, table)
    assert load_thresholds(path) == table


@PROPS
@given(thresholds())
def test_vendor_yaml_reads_what_the_vendor_writes(table: ColorThresholds) -> None:
    doc: dict[str, object] = {"lab": {"Mono": {
        name: {"min": list(r.lab_min), "max": list(r.lab_max)} for name, r in table.items()}}}
    if table.image_size_px is not None:
        doc["size"] = {"width": [table.image_size_px[0]], "height": [table.image_size_px[1]]}
    assert thresholds_from_vendor_yaml(yaml.safe_dump(doc, sort_keys=False)) == table
    # The vendor's files have their colours sorted by name: the same colours.
    back = thresholds_from_vendor_yaml(yaml.safe_dump(doc))
    assert dict(back) == dict(table) and back.image_size_px == table.image_size_px


@PROPS
@given(st.floats(-1e4, 1e4))
def test_yaw_normalisation(angle: float) -> None:
    yaw, turns = normalize_yaw_deg(angle)
    assert -45.0 < yaw <= 45.0
    assert math.isclose(yaw + 90.0 * turns, angle, abs_tol=1e-9)
