"""The twin's generated model: it agrees with the arm config and our kinematics, compiles
and runs without MuJoCo warnings, renders a seeded scene identically twice, and its lens
bends the picture the way the OpenCV model it claims says."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from busarm.arm.config import load_arm_config
from busarm.errors import ConfigError
from busarm.twin.lens import LensSpec
from busarm.twin.scene import Block, Distractor, Scene, random_scene
from busarm.twin.twin import Twin

DATA = Path(__file__).parent.parent / "data"


@pytest.fixture(scope="module")
def twin() -> Twin:
    tw = Twin(scene=random_scene(3), realtime=False)
    yield tw
    tw.close()


def test_joint_limits_come_from_the_config(twin: Twin) -> None:
    for j in twin.config.joints:
        lo, hi = twin.model.joint(j.name).range
        assert math.degrees(lo) == pytest.approx(j.min_deg)
        assert math.degrees(hi) == pytest.approx(j.max_deg)


@pytest.mark.parametrize("config", ["jetauto_pro", str(DATA / "armpi_style.toml")])
def test_model_frames_agree_with_the_kinematics(config: str) -> None:
    cfg = load_arm_config(config)
    rng = np.random.default_rng(5)
    with Twin(cfg, Scene(), realtime=False) as tw:
        mj = tw.mujoco
        for _ in range(20):
            q = [rng.uniform(j.min_deg, j.max_deg) for j in cfg.joints]
            for adr, a in zip(tw._joint_qpos, q, strict=True):
                tw.data.qpos[adr] = math.radians(a)
            mj.mj_kinematics(tw.model, tw.data)
            frame4 = tw.kin.frames(q)[3]
            np.testing.assert_allclose(tw.link2base(), frame4, atol=1e-6)
            tool = tw.data.site("tool")
            np.testing.assert_allclose(tool.xpos * 1000, tw.kin.fk_matrix(q)[:3, 3], atol=1e-6)
            mj.mj_camlight(tw.model, tw.data)
            np.testing.assert_allclose(tw.cam2base_from_mujoco(), frame4 @ tw.mount.cam2link,
                                       atol=1e-6)


def test_runs_across_the_control_range_without_warnings(twin: Twin) -> None:
    rng = np.random.default_rng(1)
    before = [int(w.number) for w in twin.data.warning]
    for servo, j in zip(twin.servos, twin.config.joints, strict=False):
        target = j.pulses_from_angle_deg(rng.uniform(j.min_deg + 20, j.max_deg - 20))
        from busarm.protocol import Command, Request

        servo.handle(Request(servo.servo_id, Command.MOVE_TIME_WRITE, (round(target), 800)),
                     twin.clock.now())
    twin.step(1.5)
    after = [int(w.number) for w in twin.data.warning]
    assert after == before, "MuJoCo warned while the arm moved"
    assert np.all(np.isfinite(twin.data.qpos))


def test_a_seeded_scene_renders_the_same_image_twice() -> None:
    images = []
    for _ in range(2):
        with Twin(scene=random_scene(11), realtime=False,
                  start_joints_deg=load_arm_config().pose("look")) as tw:
            images.append((tw.render_camera(), tw.render_overview()))
    assert np.array_equal(images[0][0], images[1][0])
    assert np.array_equal(images[0][1], images[1][1])
    # ... and the picture is of something: coloured blocks on a light table.
    lab = cv2.cvtColor(images[0][0], cv2.COLOR_BGR2LAB)
    assert np.count_nonzero(cv2.inRange(lab, (0, 150, 130), (255, 255, 255))) > 500


def test_blocks_stand_where_the_scene_puts_them(twin: Twin) -> None:
    for state, block in zip(twin.blocks(), twin.scene.blocks, strict=True):
        assert state.x_mm == pytest.approx(block.x_mm, abs=0.05)
        assert state.y_mm == pytest.approx(block.y_mm, abs=0.05)
        assert state.z_mm == pytest.approx(block.size_mm / 2, abs=0.1)
        assert state.is_upright
        assert (state.yaw_deg - block.yaw_deg + 45) % 90 - 45 == pytest.approx(0, abs=0.05)


def _silhouette_centroid_px(tw: Twin) -> np.ndarray:
    b = tw.blocks()[0]
    h = b.size_mm / 2
    corners = np.array([[sx * h, sy * h, sz * h] for sx in (-1, 1) for sy in (-1, 1)
                        for sz in (-1, 1)])
    yaw = math.radians(b.yaw_deg)
    rot = np.array([[math.cos(yaw), -math.sin(yaw), 0], [math.sin(yaw), math.cos(yaw), 0],
                    [0, 0, 1]])
    p_base = corners @ rot.T + [b.x_mm, b.y_mm, b.z_mm]
    base2cam = np.linalg.inv(tw.cam2base())
    p_cam = p_base @ base2cam[:3, :3].T + base2cam[:3, 3]
    px, _ = cv2.projectPoints(p_cam, np.zeros(3), np.zeros(3), tw.lens.camera_matrix,
                              tw.lens.dist_coeffs)
    hull = cv2.convexHull(px.reshape(-1, 2).astype(np.float32))
    m = cv2.moments(hull)
    return np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])


@pytest.mark.parametrize("where", [(230.0, 60.0, 20.0), (120.0, -150.0, -30.0),
                                   (300.0, 170.0, 5.0)])
def test_the_lens_puts_a_block_where_opencv_projects_it(where: tuple[float, float, float]) -> None:
    """The rendered red blob's centroid matches the OpenCV projection (with distortion) of
    the block's true silhouette: the camera pose and the lens model are what they claim."""
    scene = Scene(blocks=(Block("red", *where),))
    with Twin(scene=scene, realtime=False, start_joints_deg=load_arm_config().pose("look")) as tw:
        image = tw.render_camera()
        mask = cv2.inRange(cv2.cvtColor(image, cv2.COLOR_BGR2LAB), (0, 150, 120), (255, 255, 255))
        m = cv2.moments(mask, True)
        blob = np.array([m["m10"] / m["m00"], m["m01"] / m["m00"]])
        expected = _silhouette_centroid_px(tw)
    assert np.linalg.norm(blob - expected) < 1.0, (blob, expected)


def test_the_lens_really_distorts() -> None:
    """Barrel distortion pulls the image corners in: a pixel's ray differs from the
    pinhole ray by tens of pixels at the corner and not at all at the centre."""
    lens = LensSpec()
    rays = lens.normalized_from_pixels([[lens.cx_px, lens.cy_px], [0.0, 0.0]])
    assert np.allclose(rays[0], 0, atol=1e-9)
    pinhole_corner = np.array([(0 - lens.cx_px) / lens.fx_px, (0 - lens.cy_px) / lens.fy_px])
    assert np.linalg.norm(rays[1] - pinhole_corner) * lens.fx_px > 30


def test_bad_lens_and_start_values_are_refused() -> None:
    with pytest.raises(ConfigError, match="width_px"):
        LensSpec(width_px=5)
    with pytest.raises(ConfigError, match="distortion"):
        LensSpec(distortion=(0.1, 0.2, 0.3))
    with pytest.raises(ConfigError, match="shoulder_pitch"):
        Twin(scene=Scene(), realtime=False, start_joints_deg=[0, 10, 0, 0, 0])
    with pytest.raises(ConfigError, match="gripper position 5"):
        Twin(scene=Scene(), realtime=False, gripper_pulses=5)


def test_each_block_is_a_cube_of_its_own_size_and_distractors_are_named_bodies() -> None:
    sizes = (25.0, 33.0, 40.0)
    scene = Scene(blocks=tuple(Block("blue", 200.0, -60.0 + 60.0 * i, 15.0 * i, size)
                               for i, size in enumerate(sizes)),
                  distractors=(Distractor("disc", "grey", 280.0, -80.0, 50.0, 50.0, 3.0),
                               Distractor("bar", "white", 290.0, 60.0, 120.0, 12.0, 8.0, 80.0)))
    with Twin(scene=scene, realtime=False) as tw:
        for i, (size, state) in enumerate(zip(sizes, tw.blocks(), strict=True)):
            np.testing.assert_allclose(tw.model.geom(f"block{i}").size, [size / 2000] * 3)
            assert state.size_mm == size
            assert state.z_mm == pytest.approx(size / 2, abs=0.1)
        mj = tw.mujoco
        disc, bar = tw.model.geom("distractor0"), tw.model.geom("distractor1")
        assert disc.type[0] == mj.mjtGeom.mjGEOM_CYLINDER
        np.testing.assert_allclose(disc.size[:2], (0.025, 0.0015))
        assert bar.type[0] == mj.mjtGeom.mjGEOM_BOX
        np.testing.assert_allclose(bar.size, (0.06, 0.006, 0.004))
        for i in (0, 1):  # a free body each, so a push moves it
            assert tw.model.joint(f"distractor{i}").type[0] == mj.mjtJoint.mjJNT_FREE
            assert tw.model.body(f"distractor{i}").id == tw.data.body(f"distractor{i}").id
