"""The twin's cheaper paths give what the plain ones did: a recycled snapshot is the
state now, a live frame is the same view (drawn with fewer pixels), and the lens's
tables for a render of another size still send every pixel along its own ray."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt
import pytest

from busarm.arm.config import load_arm_config
from busarm.errors import ConfigError
from busarm.twin.lens import LensSpec
from busarm.twin.scene import Block, Scene
from busarm.twin.twin import LIVE_DENSITY, Twin


def _red_centroid(image: npt.NDArray[np.uint8]) -> npt.NDArray[np.float64]:
    lab = cv2.cvtColor(image, cv2.COLOR_BGR2LAB)
    mask = cv2.inRange(lab, np.array([0, 150, 120]), np.array([255, 255, 255]))
    m = cv2.moments(mask, True)
    return np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])


def test_a_live_frame_shows_the_block_where_the_vision_frame_does() -> None:
    scene = Scene(blocks=(Block("red", 230.0, 60.0, 20.0), Block("blue", 300.0, 170.0, 5.0)))
    with Twin(scene=scene, realtime=False, start_joints_deg=load_arm_config().pose("look")) as tw:
        full, live = tw.render_camera(), tw.render_camera(live=True)
        live_ideal = tw.render_ideal(live=True)
        width, height = tw._render_size
    # About LIVE_DENSITY of the pixels a side (the lens's margin rounded up).
    assert abs(live_ideal.shape[0] - height * LIVE_DENSITY) <= 2
    assert abs(live_ideal.shape[1] - width * LIVE_DENSITY) <= 4
    assert live.shape == full.shape == (480, 640, 3)
    assert np.linalg.norm(_red_centroid(live) - _red_centroid(full)) < 0.5
    # The same picture, a little softer (no antialiasing, fewer pixels): not a shifted one.
    assert float(np.mean(np.abs(live.astype(np.int16) - full))) < 2.0


def test_the_lens_tables_of_its_own_render_geometry_are_the_default_ones() -> None:
    lens = LensSpec()
    default = lens.remap_tables()
    given = LensSpec().remap_tables(lens.render_geometry())
    assert all(np.array_equal(a, b) for a, b in zip(default, given, strict=True))
    width, height, fovy = lens.render_geometry()
    # A render of half the size: every ray lands where it did, at half the scale.
    small = lens.remap_tables((width // 2, height // 2, fovy))
    to_px = [m1.astype(np.float64) + np.stack([m2 & 31, m2 >> 5], -1) / 32.0
             for m1, m2 in (default, small)]
    centre = np.array([(width - 1) / 2, (height - 1) / 2])
    half_centre = np.array([(width // 2 - 1) / 2, (height // 2 - 1) / 2])
    scale = (height // 2) / height
    assert np.abs((to_px[0] - centre) * scale - (to_px[1] - half_centre)).max() < 0.05


def test_a_snapshot_into_an_earlier_one_is_the_state_now() -> None:
    with Twin(scene=Scene(blocks=(Block("red", 230.0, 60.0, 20.0),)), realtime=False) as tw:
        first = tw.snapshot()
        tw.place_block(0, 200.0, -40.0)
        tw.step(0.1)
        again = tw.snapshot(into=first)
        assert again is first
        assert np.array_equal(again.qpos, tw.data.qpos) and again.time == tw.data.time
        assert np.array_equal(tw.render_camera(data=again), tw.render_camera())


def test_equal_lenses_share_their_remap_tables_read_only() -> None:
    # A list (as from a JSON or TOML file) is taken as a tuple.
    first = LensSpec(distortion=[-0.2, 0.05, 0.0, 0.0])  # type: ignore[arg-type]
    again = LensSpec(distortion=(-0.2, 0.05, 0, 0))
    assert first == again and first.distortion == (-0.2, 0.05, 0.0, 0.0)
    tables = first.remap_tables()
    assert again.remap_tables() is tables
    assert not tables[0].flags.writeable and not tables[1].flags.writeable
    other = LensSpec(distortion=(-0.21, 0.05, 0.0, 0.0)).remap_tables()
    assert not np.array_equal(other[0], tables[0])
    with pytest.raises(ConfigError, match="distortion"):
        LensSpec(distortion=("a", 0.0, 0.0, 0.0))  # type: ignore[arg-type]
