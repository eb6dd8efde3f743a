"""Annotated pictures (drawn on a copy, where the detections are) and atomic image saving."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from busarm.bench.synthetic import Block, render_blocks
from busarm.errors import ConfigError
from busarm.vision.annotate import annotate, save_image
from busarm.vision.color import ColorDetector
from busarm.vision.color_thresholds import default_thresholds
from busarm.vision.tags import detect_tags, tag_image


@pytest.fixture(scope="module")
def scene() -> tuple[np.ndarray, list, list]:
    image = render_blocks([Block("red", (160, 240), 60, 20), Block("blue", (330, 150), 50, -10)])
    tag = cv2.cvtColor(tag_image(4, 80, 12), cv2.COLOR_GRAY2BGR)
    image[350:454, 450:554] = tag
    image.flags.writeable = False  # as a camera frame is
    return image, ColorDetector(default_thresholds()).detect(image), detect_tags(image)


def changed(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.any(a != b, axis=2)


def test_draws_on_a_copy_where_things_are(scene: tuple[np.ndarray, list, list]) -> None:
    image, dets, tags = scene
    assert len(dets) == 2 and [t.tag_id for t in tags] == [4]
    out = annotate(image, dets, tags, ["frame 0", "two blocks"])
    assert out.shape == image.shape and out.dtype == np.uint8 and out.flags.writeable
    assert out is not image
    diff = changed(out, image)
    for det in dets:  # each box outline is drawn
        for corner in det.box_px:
            u, v = np.rint(corner).astype(int)
            assert diff[v - 2 : v + 3, u - 2 : u + 3].any()
        u, v = np.rint(det.centroid_px).astype(int)
        assert diff[v, u - 3 : u + 4].any()  # the centroid cross
    c0 = np.rint(tags[0].corners_px[0]).astype(int)
    assert diff[c0[1] - 2 : c0[1] + 3, c0[0] - 2 : c0[0] + 3].any()
    assert diff[5:40, 5:120].any()  # the text lines
    assert not diff[440:470, 20:200].any()  # and nothing far from all of it
    # Without anything to draw it is an unchanged copy.
    plain = annotate(image)
    assert np.array_equal(plain, image) and plain is not image


def test_grey_images_and_bad_input(scene: tuple[np.ndarray, list, list]) -> None:
    image, dets, _ = scene
    grey = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    out = annotate(grey, dets)
    assert out.shape == image.shape
    with pytest.raises(ConfigError, match="H x W x 3 uint8"):
        annotate(np.zeros((10, 10, 3), np.float32))


def test_save_png_round_trip_and_jpeg(tmp_path: Path, scene: tuple[np.ndarray, list, list]
                                      ) -> None:
    image = scene[0]
    save_image(tmp_path / "a.png", image)
    assert np.array_equal(cv2.imread(str(tmp_path / "a.png")), image)
    save_image(tmp_path / "b.JPG", image)
    back = cv2.imread(str(tmp_path / "b.JPG"))
    assert back.shape == image.shape and np.abs(back.astype(int) - image).mean() < 3
    save_image(tmp_path / "g.png", np.full((5, 7), 9, np.uint8))
    assert cv2.imread(str(tmp_path / "g.png"), cv2.IMREAD_UNCHANGED).shape == (5, 7)
    # Replacing a file leaves only the file (the temporary is renamed over it).
    save_image(tmp_path / "a.png", np.zeros_like(image))
    assert not cv2.imread(str(tmp_path / "a.png")).any()
    assert sorted(os.listdir(tmp_path)) == ["a.png", "b.JPG", "g.png"]


def test_save_errors(tmp_path: Path) -> None:
    img = np.zeros((4, 4, 3), np.uint8)
    with pytest.raises(ConfigError, match=r"extension '\.gif' is not one of \.png, \.jpg"):
        save_image(tmp_path / "a.gif", img)
    with pytest.raises(ConfigError, match="extension '\\(none\\)'"):
        save_image(tmp_path / "noext", img)
    with pytest.raises(ConfigError, match="cannot write image .*missing"):
        save_image(tmp_path / "missing" / "a.png", img)
    with pytest.raises(ConfigError, match="need an H x W x 3 or H x W uint8"):
        save_image(tmp_path / "a.png", np.zeros((4, 4, 3), np.float64))
    assert os.listdir(tmp_path) == []
