"""Colour thresholds (our TOML, the vendor's YAML, validation) and the block detector on
synthetic frames with known blocks: positions, yaw, agreement with the vendor-style
pipeline, and frames that must give nothing (blank, saturated, no match)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from busarm.bench.synthetic import (
    ARM_RGB,
    BLOCK_RGB,
    TABLE_RGB,
    Block,
    bgr_from_rgb,
    render_blocks,
    synthetic_frames,
)
from busarm.bench.vision import bench_detection, match_detections
from busarm.errors import ConfigError
from busarm.vision.color import (
    ColorDetector,
    Detection,
    normalize_yaw_deg,
    vendor_style_detect,
)
from busarm.vision.color_thresholds import (
    ColorRange,
    ColorThresholds,
    default_thresholds,
    load_thresholds,
    parse_color_names,
    save_thresholds,
    thresholds_from_toml,
    thresholds_from_vendor_yaml,
    thresholds_to_toml,
)

VENDOR_YAML = Path(__file__).resolve().parents[1] / "data" / "vendor" / "lab_config.yaml"
RGB3 = ("red", "green", "blue")
DEFAULT = default_thresholds()


def yaw_error_deg(a: float, b: float) -> float:
    return abs(normalize_yaw_deg(a - b)[0])


def nearest(dets: list[Detection], block: Block) -> Detection:
    same = [d for d in dets if d.color == block.color]
    assert same, f"no {block.color} detection for {block}"
    return min(same, key=lambda d: math.dist(d.centroid_px, block.center_px))


# ---------------------------------------------------------------------- thresholds


def test_color_range_validation() -> None:
    r = ColorRange("red", (0, 150, 130), [255, 255, 255])  # type: ignore[arg-type]
    assert r.lab_max == (255, 255, 255) and r.contains((100, 200, 140))
    assert not r.contains((100, 149, 140))
    cases = [
        (("red", (0, 160, 0), (255, 150, 255)), "lab_min a = 160 is above lab_max a = 150"),
        (("red", (0, 0, 256), (255, 255, 255)), "lab_min b = 256 is out of range 0..255"),
        (("red", (0, 0), (255, 255, 255)), "must be 3 integers"),
        (("red", (0, 0, 1.5), (255, 255, 255)), "b must be an integer 0..255"),
        (("2red", (0, 0, 0), (255, 255, 255)), "colour name '2red'"),
        (("re d", (0, 0, 0), (255, 255, 255)), "colour name 're d'"),
    ]
    for args, words in cases:
        with pytest.raises(ConfigError) as err:
            ColorRange(*args)  # type: ignore[arg-type]
        assert words in str(err.value)


def test_thresholds_mapping_select_and_errors() -> None:
    assert list(DEFAULT) == ["red", "green", "blue", "yellow"]
    sub = DEFAULT.select(["blue", "red", "blue"])
    assert sub.names == ("blue", "red") and sub["red"] == DEFAULT["red"]
    with pytest.raises(ConfigError) as err:
        DEFAULT.select(["red", "purple"])
    assert "no colour 'purple'; colours: red, green, blue, yellow" in str(err.value)
    with pytest.raises(ConfigError, match="given twice"):
        ColorThresholds([DEFAULT["red"], DEFAULT["red"]])
    with pytest.raises(ConfigError, match="no colour defined"):
        ColorThresholds([])
    with pytest.raises(ConfigError, match="image width 0"):
        ColorThresholds([DEFAULT["red"]], image_size_px=(0, 480))
    assert parse_color_names(" red, green,red ,") == ["red", "green"]
    with pytest.raises(ConfigError, match="no colour name"):
        parse_color_names(" , ")


def test_toml_round_trip(tmp_path: Path) -> None:
    table = ColorThresholds(
        [ColorRange("red", (1, 2, 3), (4, 5, 6)), ColorRange("dark-blue_2", (0, 0, 0),
                                                              (255, 255, 255))],
        image_size_px=(640, 480),
    )
    path = tmp_path / "c.toml"
    save_thresholds(path, table)
    back = load_thresholds(path)
    assert back == table and back.names == ("red", "dark-blue_2")
    assert back.image_size_px == (640, 480) and back.source == str(path)
    assert thresholds_from_toml(thresholds_to_toml(DEFAULT)) == DEFAULT
    assert [p.name for p in tmp_path.iterdir()] == ["c.toml"]  # no temporary left behind


GOOD = 'format = "busarm.colors"\nversion = 1\n[colors.red]\nlab_min = [0, 150, 130]\n' \
       "lab_max = [255, 255, 255]\n"


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("format = ", "not valid TOML"),
        (GOOD.replace('"busarm.colors"', '"other"'), "format: must be 'busarm.colors'"),
        (GOOD.replace("version = 1", "version = 2"), "version: 2; this busarm reads version 1"),
        (GOOD.replace("[0, 150, 130]", "[0, 300, 130]"),
         "colors.red: colour red lab_min a = 300 is out of range 0..255"),
        (GOOD.replace("[0, 150, 130]", "[0, 150]"), "colors.red: colour red lab_min must be 3"),
        (GOOD.replace("lab_max = [255, 255, 255]", "lab_max = [255, 100, 255]"),
         "lab_min a = 150 is above lab_max a = 100"),
        (GOOD.replace("lab_max = [255, 255, 255]\n", ""), "colors.red.lab_max: missing"),
        (GOOD.replace("lab_max", "lab_top"), "colors.red: unknown key(s) ['lab_top']"),
        ('format = "busarm.colors"\nversion = 1\n', "colors: missing"),
        (GOOD.replace("[colors.red]", "[colors]\nextra = 1\n[colors.red]"),
         "colors.extra: must be a table"),
        ("hue = 1\n" + GOOD, "top level: unknown key(s) ['hue']"),
        (GOOD + "[image]\nwidth_px = 640\n", "image: must be a table with exactly"),
        (GOOD + "[image]\nwidth_px = 640\nheight_px = -1\n", "image.height_px: -1 is not"),
    ],
)
def test_bad_toml_names_the_file_and_key(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_thresholds(path)
    message = str(err.value)
    assert message.startswith(f"thresholds {path}: ") and words in message, message


def test_load_errors(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        load_thresholds(tmp_path / "none.toml")
    with pytest.raises(ConfigError, match=r"unknown kind '\.json'"):
        load_thresholds(tmp_path / "x.json")
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConfigError, match="cannot read it"):
        load_thresholds(tmp_path / "bin.toml")


def test_vendor_yaml_sample() -> None:
    mono = load_thresholds(VENDOR_YAML)
    assert mono.names == ("black", "blue", "green", "red", "white")
    assert mono["red"] == ColorRange("red", (0, 150, 130), (255, 255, 255))
    assert mono["blue"] == ColorRange("blue", (20, 70, 0), (220, 160, 115))
    assert mono.image_size_px == (640, 480)
    stereo = load_thresholds(VENDOR_YAML, section="Stereo")
    assert "yellow" in stereo and stereo["yellow"].lab_min == (135, 129, 132)
    assert stereo["red"].lab_min == (0, 142, 125)
    with pytest.raises(ConfigError, match="section 'Left' is not one of Mono, Stereo"):
        load_thresholds(VENDOR_YAML, section="Left")


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("lab: [unclosed", "not valid YAML"),
        ("- 1\n- 2\n", "top level: must be a mapping"),
        ("size: {width: [640], height: [480]}\n", "lab: missing"),
        ("lab:\n  Stereo:\n    red: {min: [0, 0, 0], max: [1, 1, 1]}\n",
         "lab.Mono: missing or empty (sections: Stereo)"),
        ("lab:\n  Mono:\n    red: {min: [0, 0, 0]}\n", "lab.Mono.red.max: missing"),
        ("lab:\n  Mono:\n    red: {min: [0, 200, 0], max: [255, 100, 255]}\n",
         "lab.Mono.red: colour red: lab_min a = 200 is above lab_max a = 100"),
        ("lab:\n  Mono:\n    red: {min: [0, 0, -1], max: [255, 255, 255]}\n",
         "lab.Mono.red: colour red lab_min b = -1 is out of range 0..255"),
        ("lab:\n  Mono:\n    red: 5\n", "lab.Mono.red: must be a mapping"),
        ("lab:\n  Mono:\n    red: {min: [0, 0, 0], max: [9, 9, 9]}\nsize: {width: [0], "
         "height: [480]}\n", "size.width: 0 is not an integer"),
    ],
)
def test_bad_vendor_yaml(tmp_path: Path, text: str, words: str) -> None:
    path = tmp_path / "lab_config.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_thresholds(path)
    message = str(err.value)
    assert str(path) in message and words in message, message


def test_vendor_yaml_from_text_matches_file() -> None:
    text = VENDOR_YAML.read_text()
    assert thresholds_from_vendor_yaml(text, section="Stereo") == load_thresholds(
        VENDOR_YAML, section="Stereo")


# ---------------------------------------------------------------------- the shipped tuning


@pytest.mark.parametrize("gain", [0.5, 0.75, 1.0, 1.15])
def test_default_thresholds_separate_the_twin_colours(gain: float) -> None:
    """Each block colour lit from half to 115 % falls in its own box only; the table and
    the arm (and their shadows) fall in none."""
    patches = {name: bgr_from_rgb(rgb, gain) for name, rgb in BLOCK_RGB.items()}
    patches["table"] = bgr_from_rgb(TABLE_RGB, gain)
    patches["arm"] = bgr_from_rgb(ARM_RGB, gain)
    for name, bgr in patches.items():
        lab = cv2.cvtColor(np.array([[bgr]], np.uint8), cv2.COLOR_BGR2LAB)[0, 0]
        inside = [c for c, r in DEFAULT.items() if r.contains(lab)]
        expected = [name] if name in BLOCK_RGB else []
        assert inside == expected, (name, gain, lab.tolist())


# ---------------------------------------------------------------------- detection


@pytest.fixture(scope="module")
def scenes() -> list[tuple[np.ndarray, list[Block]]]:
    return synthetic_frames(12, seed=7, colors=("red", "green", "blue", "yellow"))


def test_finds_every_block_where_it_is(scenes: list[tuple[np.ndarray, list[Block]]]) -> None:
    detector = ColorDetector(DEFAULT)
    for image, blocks in scenes:
        dets = detector.detect(image)
        assert sorted(d.color for d in dets) == sorted(b.color for b in blocks)
        for block in blocks:
            d = nearest(dets, block)
            assert math.dist(d.centroid_px, block.center_px) < 0.5
            assert math.dist(d.rect_center_px, block.center_px) < 1.0
            assert yaw_error_deg(d.yaw_deg, block.yaw_deg) < 2.5
            assert -45 < d.yaw_deg <= 45
            # The threshold takes in part of the anti-aliased edge: a bit above side^2.
            assert 0.97 < d.area_px / block.side_px**2 < 1.2
            for side in d.rect_size_px:
                assert block.side_px - 1 < side < block.side_px + 4
            assert d.box_px.shape == (4, 2) and d.contour_px.dtype == np.int32
            assert not d.box_px.flags.writeable


def test_agrees_with_the_vendor_pipeline(scenes: list[tuple[np.ndarray, list[Block]]]) -> None:
    detector = ColorDetector(DEFAULT, RGB3)
    for image, _ in scenes:
        ours = detector.detect(image)
        ref = vendor_style_detect(image, DEFAULT, RGB3)
        assert [d.color for d in ours] == [d.color for d in ref]
        pairs = match_detections(ref, ours)
        assert len(pairs) == len(ref)
        assert max(d for _, _, d in pairs) < 0.6


def test_sorted_by_color_order_then_area() -> None:
    blocks = [Block("red", (100, 100), 40, 0), Block("blue", (300, 100), 50, 10),
              Block("red", (100, 300), 70, 20), Block("blue", (400, 300), 80, -30)]
    image = render_blocks(blocks)
    dets = ColorDetector(DEFAULT, ["blue", "red"]).detect(image)
    assert [(d.color, round(math.sqrt(d.area_px) / 10)) for d in dets] == [
        ("blue", 8), ("blue", 5), ("red", 7), ("red", 4)]
    only_red = ColorDetector(DEFAULT, "red").detect(image)
    assert [d.color for d in only_red] == ["red", "red"]


def test_coarse_only_and_full_resolution_modes() -> None:
    blocks = [Block("green", (210.3, 170.8), 64, 17.0), Block("yellow", (455.6, 322.1), 48, -31)]
    image = render_blocks(blocks, seed=3)
    for kwargs, tol_px in [({"refine": False}, 1.5), ({"downscale": 1}, 0.5),
                           ({"downscale": 4}, 0.5)]:
        dets = ColorDetector(DEFAULT, **kwargs).detect(image)  # type: ignore[arg-type]
        assert len(dets) == 2, kwargs
        for block in blocks:
            assert math.dist(nearest(dets, block).centroid_px, block.center_px) < tol_px, kwargs


def test_near_blocks_border_blocks_and_a_thin_tail() -> None:
    # 5 px apart: one blob at the coarse scale, two at full resolution.
    pair = [Block("red", (200, 200), 60, 0), Block("red", (265, 200), 60, 0)]
    dets = ColorDetector(DEFAULT).detect(render_blocks(pair))
    assert sorted(round(d.centroid_px[0]) for d in dets) == [200, 265]
    # Cut by the frame's edge: still found, measured on what is visible.
    edge = ColorDetector(DEFAULT).detect(render_blocks([Block("blue", (10, 240), 60, 0)]))
    assert len(edge) == 1 and edge[0].centroid_px[0] == pytest.approx(20.0, abs=0.6)
    # A 3 px tail the coarse pass misses: the window grows until the whole blob is in.
    image = render_blocks([Block("red", (300, 240), 60, 0)], noise_sigma=0)
    cv2.rectangle(image, (330, 239), (420, 241), bgr_from_rgb(BLOCK_RGB["red"]), cv2.FILLED)
    (det,) = ColorDetector(DEFAULT).detect(image)
    x, _, w, _ = cv2.boundingRect(det.contour_px)
    assert x + w - 1 == 420


def test_min_max_area_and_overlapping_boxes() -> None:
    blocks = [Block("red", (150, 150), 30, 0), Block("red", (400, 300), 80, 0)]
    image = render_blocks(blocks)
    assert len(ColorDetector(DEFAULT, "red").detect(image)) == 2
    assert len(ColorDetector(DEFAULT, "red", min_area_px=1500).detect(image)) == 1
    assert len(ColorDetector(DEFAULT, "red", max_area_px=1500).detect(image)) == 1
    # Two colours whose boxes overlap both see the red block.
    wide = ColorThresholds([DEFAULT["red"], ColorRange("warm", (0, 140, 0), (255, 255, 255))])
    dets = ColorDetector(wide).detect(image)
    assert [d.color for d in dets] == ["red", "red", "warm", "warm"]


def test_more_than_eight_colours() -> None:
    """Colours past the eighth go to a second look-up table."""
    fillers = [ColorRange(f"c{i}", (0, 0, 0), (1, 1, 1)) for i in range(9)]
    table = ColorThresholds([*fillers, DEFAULT["blue"]])
    dets = ColorDetector(table).detect(render_blocks([Block("blue", (320, 240), 50, 12)]))
    assert [d.color for d in dets] == ["blue"]


def test_small_images_are_done_at_full_resolution() -> None:
    image = render_blocks([Block("red", (20.4, 15.2), 14, 0)], 40, 30)
    (det,) = ColorDetector(DEFAULT, min_area_px=50).detect(image)
    assert det.centroid_px == pytest.approx((20.4, 15.2), abs=0.5)


@pytest.mark.parametrize(
    "fill",
    [(0, 0, 0), (255, 255, 255), bgr_from_rgb(TABLE_RGB), bgr_from_rgb(BLOCK_RGB["red"]),
     bgr_from_rgb(BLOCK_RGB["blue"])],
)
def test_uniform_frames_give_nothing(fill: tuple[int, int, int]) -> None:
    """Blank, saturated, or one colour edge to edge (a covered lens): no block."""
    image = np.full((480, 640, 3), fill, np.uint8)
    assert ColorDetector(DEFAULT).detect(image) == []
    assert vendor_style_detect(image, DEFAULT) == []


def test_thresholds_that_match_nothing() -> None:
    image = render_blocks([Block("red", (320, 240), 60, 5)])
    nothing = ColorThresholds([ColorRange("violet", (0, 200, 0), (255, 255, 60))])
    detector = ColorDetector(nothing)
    assert detector.detect(image) == []
    assert detector.matched_pixels(image) == {"violet": 0}
    counts = ColorDetector(DEFAULT).matched_pixels(image)
    assert counts["red"] > 3600 and counts["blue"] == counts["green"] == 0


def test_mask_is_full_resolution() -> None:
    image = render_blocks([Block("green", (100, 80), 40, 0)], noise_sigma=0)
    detector = ColorDetector(DEFAULT)
    mask = detector.mask(image, "green")
    assert mask.shape == (480, 640) and mask.dtype == np.uint8
    ys, xs = np.nonzero(mask)
    assert (xs.mean(), ys.mean()) == pytest.approx((100, 80), abs=0.3)
    with pytest.raises(ConfigError, match="colour 'purple' is not detected here"):
        detector.mask(image, "purple")


def test_bad_input_and_arguments() -> None:
    detector = ColorDetector(DEFAULT)
    for bad, words in [(np.zeros((480, 640), np.uint8), "shape (480, 640)"),
                       (np.zeros((480, 640, 3), np.float64), "dtype float64"),
                       ([[0, 0, 0]], "got list")]:
        with pytest.raises(ConfigError) as err:
            detector.detect(bad)  # type: ignore[arg-type]
        assert words in str(err.value)
    with pytest.raises(ConfigError, match="downscale = 0 is out of range 1..8"):
        ColorDetector(DEFAULT, downscale=0)
    with pytest.raises(ConfigError, match="min_area_px = -1"):
        ColorDetector(DEFAULT, min_area_px=-1)
    with pytest.raises(ConfigError, match="max_area_px 10 is below min_area_px 200"):
        ColorDetector(DEFAULT, max_area_px=10)
    with pytest.raises(ConfigError, match="no colour 'pink'"):
        ColorDetector(DEFAULT, ["red", "pink"])
    with pytest.raises(ConfigError, match="must be ColorThresholds"):
        ColorDetector({"red": DEFAULT["red"]})  # type: ignore[arg-type]


def test_yaw_normalisation() -> None:
    assert normalize_yaw_deg(90.0) == (0.0, 1)
    assert normalize_yaw_deg(45.0) == (45.0, 0)
    assert normalize_yaw_deg(-45.0) == (45.0, -1)
    assert normalize_yaw_deg(46.0) == (-44.0, 1)
    assert normalize_yaw_deg(-135.5) == pytest.approx((44.5, -2))


def test_oblong_blob_reports_the_side_along_yaw() -> None:
    image = np.full((480, 640, 3), bgr_from_rgb(TABLE_RGB), np.uint8)
    rect = cv2.boxPoints(((320, 240), (120, 40), 30.0))
    cv2.fillPoly(image, [np.rint(rect).astype(np.int32)], bgr_from_rgb(BLOCK_RGB["red"]))
    (det,) = ColorDetector(DEFAULT).detect(image)
    assert det.yaw_deg == pytest.approx(30.0, abs=1.0)
    assert det.rect_size_px == pytest.approx((120, 40), abs=2.5)
    # The long side turned a quarter: the yaw is the same modulo 90, w and h swap.
    image2 = np.full((480, 640, 3), bgr_from_rgb(TABLE_RGB), np.uint8)
    rect2 = cv2.boxPoints(((320, 240), (120, 40), 120.0))
    cv2.fillPoly(image2, [np.rint(rect2).astype(np.int32)], bgr_from_rgb(BLOCK_RGB["red"]))
    (det2,) = ColorDetector(DEFAULT).detect(image2)
    assert det2.yaw_deg == pytest.approx(30.0, abs=1.0)
    assert det2.rect_size_px == pytest.approx((40, 120), abs=2.5)


def test_detection_to_dict_is_json() -> None:
    (det,) = ColorDetector(DEFAULT).detect(render_blocks([Block("yellow", (300, 200), 50, 9)]))
    data = json.loads(json.dumps(det.to_dict(contour=True)))
    assert data["color"] == "yellow" and len(data["box_px"]) == 4
    assert data["centroid_px"] == pytest.approx([300, 200], abs=0.5)
    assert len(data["contour_px"]) == len(det.contour_px)
    assert "contour_px" not in det.to_dict()


# ---------------------------------------------------------------------- the bench's plumbing


def test_bench_detection_report_shape() -> None:
    frames = [f for f, _ in synthetic_frames(2, seed=11)]
    report = bench_detection(frames, DEFAULT, RGB3, seconds_per_case=0.02, rounds=2)
    json.dumps(report.to_dict())
    assert report.frames == 2 and report.colors == list(RGB3)
    agreement = report.agreement
    assert agreement.all_same_counts is True
    assert agreement.unmatched == 0
    assert agreement.matched == agreement.vendor_blocks > 0
    assert agreement.centroid_distance_px.max < 0.6
    assert len(report.vendor_fps_rounds) == len(report.ours_fps_rounds) == 2
    assert cv2.getNumThreads() != 1 or report.threads == 1  # the thread count is restored
    with pytest.raises(ValueError, match="at least one frame"):
        bench_detection([], DEFAULT)
