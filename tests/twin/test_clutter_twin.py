"""Cluttered tables in the twin: touching blocks settle where the scene puts them (no
explosions), distractors are free bodies ``distractor<i>`` that render in their colours,
and the scene's lighting reaches the model's lights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from busarm.twin.clutter import clutter_scene
from busarm.twin.model import M_PER_MM, light_tint
from busarm.twin.scene import (
    DEFAULT_BINS,
    DISTRACTOR_COLORS,
    Block,
    Distractor,
    Lighting,
    Scene,
)
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin


def _deepest_contact_mm(tw: Twin) -> float:
    """How far the deepest contact interpenetrates (mm; 0 if none does)."""
    d = tw.data
    return max([0.0, *(-float(d.contact[k].dist) / M_PER_MM for k in range(d.ncon))])


def _distractor_pose(tw: Twin, i: int) -> tuple[np.ndarray, np.ndarray]:
    """Position (mm) and z axis of distractor body ``i``, straight from MuJoCo."""
    body = tw.data.body(f"distractor{i}")
    return body.xpos / M_PER_MM, body.xmat.reshape(3, 3)[:, 2]


def _assert_nothing_moved(tw: Twin, scene: Scene, tolerance_mm: float = 1.0) -> None:
    for state, block in zip(tw.blocks(), scene.blocks, strict=True):
        moved = math.hypot(state.x_mm - block.x_mm, state.y_mm - block.y_mm)
        assert moved < tolerance_mm, (state, block)
        assert state.z_mm == pytest.approx(block.size_mm / 2, abs=0.5)
        assert state.is_upright
        assert (state.yaw_deg - block.yaw_deg + 45) % 90 - 45 == pytest.approx(0, abs=0.5)
    for i, thing in enumerate(scene.distractors):
        pos, z_axis = _distractor_pose(tw, i)
        assert np.hypot(*(pos[:2] - (thing.x_mm, thing.y_mm))) < tolerance_mm, (i, pos)
        assert pos[2] == pytest.approx(thing.height_mm / 2, abs=0.5)
        assert z_axis[2] > math.cos(math.radians(2)), (i, z_axis)
    assert _deepest_contact_mm(tw) < 0.2


def _cluttered_seeds(count: int) -> list[int]:
    """The first seeds whose 12-block scene has a touching 2x2 square or row."""
    out = []
    for seed in range(100):
        scene = clutter_scene(seed, 12, distractors=4)
        fps = [b.footprint for b in scene.blocks]
        near = sum(1 for i, a in enumerate(fps) for b in fps[i + 1:]
                   if math.hypot(a.x_mm - b.x_mm, a.y_mm - b.y_mm) < a.half_x_mm * 2 + 0.1)
        if near >= 3 and len(scene.distractors) == 4:
            out.append(seed)
        if len(out) == count:
            return out
    raise AssertionError("no cluttered seeds")


@pytest.mark.parametrize("seed", _cluttered_seeds(3))
def test_clutter_scenes_settle_with_nothing_moving(seed: int) -> None:
    scene = clutter_scene(seed, 12, distractors=4)
    with Twin(scene=scene, realtime=False) as tw:
        _assert_nothing_moved(tw, scene)  # after the twin's own settling
        tw.step(1.0)
        _assert_nothing_moved(tw, scene)


def test_exactly_touching_blocks_stay_put() -> None:
    """No gap at all: a 2x2 square turned 30 deg, a row of 25, 40 and 30 mm blocks, a
    block against a bin's wall and one against a pen lying on the table."""
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    square = [Block("red", 230 + c * u - s * v, 60 + s * u + c * v, 30.0)
              for u in (-15.0, 15.0) for v in (-15.0, 15.0)]
    row = [Block("green", 200.0 + x, -90.0, 0.0, size)
           for x, size in ((-32.5, 25.0), (0.0, 40.0), (35.0, 30.0))]
    tray = DEFAULT_BINS[0]  # red, at (66.69, 183.24), 90 mm
    against_bin = Block("blue", tray.x_mm + 45.0 + 15.0, tray.y_mm)
    pen = Distractor("bar", "grey", 290.0, -20.0, 120.0, 10.0, 10.0, 90.0, 15.0)
    against_pen = Block("yellow", 290.0 - 5.0 - 15.0, -20.0)
    scene = Scene(blocks=(*square, *row, against_bin, against_pen), bins=(tray,),
                  distractors=(pen,))
    with Twin(scene=scene, realtime=False) as tw:
        _assert_nothing_moved(tw, scene)
        tw.step(1.0)
        _assert_nothing_moved(tw, scene)


def _overview_pixel(tw: Twin, point_mm: tuple[float, float, float]) -> tuple[int, int]:
    """Where the overview camera (MuJoCo's: looking along -z, y up) sees a point."""
    cam = tw.model.camera("overview")
    pos, rot = tw.data.cam_xpos[cam.id], tw.data.cam_xmat[cam.id].reshape(3, 3)
    p = rot.T @ (np.asarray(point_mm) * M_PER_MM - pos)
    f = 240 / math.tan(math.radians(float(cam.fovy[0]) / 2))  # the 640x480 render
    return round(320 + f * p[0] / -p[2]), round(240 - f * p[1] / -p[2])


def test_distractors_render_in_their_colours() -> None:
    things = (Distractor("cylinder", "purple", 200.0, 100.0, 50.0, 50.0, 60.0),
              Distractor("disc", "white", 200.0, -100.0, 60.0, 60.0, 4.0),
              Distractor("bar", "brown", 280.0, 0.0, 150.0, 15.0, 12.0, 90.0),
              Distractor("cylinder", "grey", 150.0, 0.0, 40.0, 40.0, 50.0))
    images = {}
    for scene in (Scene(distractors=things), Scene()):
        with Twin(scene=scene, realtime=False) as tw:
            images[len(scene.distractors)] = tw.render_overview()[:, :, ::-1] / 255.0  # RGB
            pixels = [_overview_pixel(tw, (d.x_mm, d.y_mm, d.height_mm)) for d in things]
    for thing, (u, v) in zip(things, pixels, strict=True):
        seen = images[4][v - 1:v + 2, u - 1:u + 2].reshape(-1, 3).mean(axis=0)
        # Its top, lit from above, is its own colour a little dimmed; the table is not.
        ratio = seen / np.array(DISTRACTOR_COLORS[thing.color])
        assert np.all((ratio > 0.85) & (ratio < 1.05)), (thing.color, seen)
        assert np.ptp(ratio) < 0.05, (thing.color, seen)
        bare = images[0][v - 1:v + 2, u - 1:u + 2].reshape(-1, 3).mean(axis=0)
        assert np.abs(bare - seen).max() > 0.05


def test_the_scene_lighting_reaches_the_model() -> None:
    lamp = Lighting(intensity=1.2, key_azimuth_deg=90.0, key_elevation_deg=30.0,
                    key_share=0.6, color_temp_k=3000.0)
    means = {}
    for lighting in (lamp, Lighting(color_temp_k=6500.0)):
        with Twin(scene=Scene(lighting=lighting), realtime=False) as tw:
            top, side = tw.model.light("top"), tw.model.light("side0")
            tint = light_tint(lighting.color_temp_k) * lighting.intensity
            np.testing.assert_allclose(top.diffuse, 1.25 * lighting.key_share * tint,
                                       rtol=1e-6)
            np.testing.assert_allclose(side.diffuse, 1.25 * (1 - lighting.key_share) / 4 * tint,
                                       rtol=1e-6)
            np.testing.assert_allclose(tw.model.vis.headlight.ambient, 0.12 * tint, rtol=1e-6)
            means[lighting.color_temp_k] = tw.render_overview().reshape(-1, 3).mean(axis=0)
            if lighting is lamp:  # from the left (+y), 30 deg above the table
                el = math.radians(30)
                np.testing.assert_allclose(top.dir, (0.0, -math.cos(el), -math.sin(el)),
                                           atol=1e-6)
    warm, cool = means[3000.0], means[6500.0]  # BGR
    assert warm[2] / warm[0] > 1.3 * cool[2] / cool[0]


def test_the_usual_light_is_the_twins_light_from_before() -> None:
    with Twin(scene=Scene(), realtime=False) as tw:
        top = tw.model.light("top")
        np.testing.assert_allclose(top.pos, (0.1, 0.0, 1.6))
        np.testing.assert_allclose(top.dir, (0.0, 0.0, -1.0))
        for name in ("top", "side0", "side1", "side2", "side3"):
            np.testing.assert_allclose(tw.model.light(name).diffuse, 0.25)
        np.testing.assert_allclose(tw.model.vis.headlight.ambient, 0.12)
        np.testing.assert_allclose(tw.model.vis.headlight.diffuse, 0.1)


def test_a_twin_of_the_clutter_family_builds_a_clutter_table() -> None:
    with TwinSpec(family="clutter", seed=3, blocks=8).build() as tw:
        assert tw.scene == clutter_scene(3, 8)
        assert len(tw.blocks()) == len(tw.scene.blocks)
        for i in range(len(tw.scene.distractors)):
            assert tw.model.body(f"distractor{i}").id > 0
