"""The block locator on twin pictures with the twin's true camera: every block, in mm,
and nothing that is not a block; implausible calibrations are refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, VisionError
from busarm.perception.locate import BlockLocator
from busarm.twin.lens import LensSpec
from busarm.twin.model import AS_BUILT_MOUNT_ERROR
from busarm.twin.scene import random_scene
from busarm.twin.twin import Twin
from busarm.vision.calibration import CameraIntrinsics, HandEyeResult
from busarm.vision.color import ColorDetector
from busarm.vision.color_thresholds import ColorRange, ColorThresholds, default_thresholds


def _truth_calibration(**changes: object) -> tuple[CameraIntrinsics, HandEyeResult]:
    lens = LensSpec()
    intr = CameraIntrinsics(model="pinhole", width_px=lens.width_px, height_px=lens.height_px,
                            camera_matrix=lens.camera_matrix, distortion=lens.dist_coeffs)
    fields: dict[str, object] = {
        "cam2link": CameraMount.jetauto().offset(*AS_BUILT_MOUNT_ERROR).cam2link,
        "board2base": np.eye(4), "rms_px": 0.1, "per_view_rms_px": (), "views_used": (),
        "intrinsics": intr}
    fields.update(changes)
    return intr, HandEyeResult(**fields)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def picture() -> tuple[np.ndarray, tuple[float, ...], list]:
    cfg = load_arm_config()
    with Twin(cfg, random_scene(8, 6, ["red", "green", "blue", "yellow"], bins=False),
              realtime=False, start_joints_deg=cfg.pose("look")) as tw:
        return tw.render_camera(), tw.joints_deg(), tw.blocks()


def test_every_block_is_located_to_a_millimetre(picture: tuple) -> None:
    image, joints, truth = picture
    intr, he = _truth_calibration()
    kin = ArmKinematics.from_config(load_arm_config())
    found = BlockLocator(kin, intr, he, ColorDetector(default_thresholds())).locate(image, joints)
    assert len(found) == len(truth)
    for block in truth:
        best = min(found, key=lambda s: math.hypot(s.location.x_mm - block.x_mm,
                                                   s.location.y_mm - block.y_mm))
        assert best.color == block.color
        assert math.hypot(best.location.x_mm - block.x_mm, best.location.y_mm - block.y_mm) < 1.0
        assert best.reachable and best.top_down
        # A cube's yaw is known modulo 90 degrees.
        assert abs((best.location.yaw_deg - block.yaw_deg + 45) % 90 - 45) < 8.0


def test_blobs_that_are_not_blocks_are_left_out(picture: tuple) -> None:
    image, joints, _ = picture
    intr, he = _truth_calibration()
    kin = ArmKinematics.from_config(load_arm_config())
    # A box that takes the light table for a colour: one huge blob, not a block.
    table = ColorThresholds([ColorRange("tablecloth", (150, 110, 110), (255, 145, 145))])
    assert BlockLocator(kin, intr, he, ColorDetector(table)).locate(image, joints) == []
    # The vendor's black and white are for lines and the table, never blocks.
    dark = ColorThresholds([ColorRange("black", (0, 0, 0), (60, 255, 255))])
    assert BlockLocator(kin, intr, he, ColorDetector(dark)).locate(image, joints) == []


def test_a_blob_cut_by_the_pictures_edge_is_not_taken_as_whole(picture: tuple) -> None:
    """Half a block at the corner (where the lens bends most, its ray can even miss the
    table): not a whole silhouette, so its location is flagged rough, or it is left out;
    the others are still located as before."""
    image, joints, truth = picture
    intr, he = _truth_calibration()
    kin = ArmKinematics.from_config(load_arm_config())
    locator = BlockLocator(kin, intr, he, ColorDetector(default_thresholds()))
    before = locator.locate(image, joints)
    assert all(s.whole for s in before)
    red = next(s for s in before if s.color == "red")
    assert red.detection is not None
    u, v = (round(c) for c in red.detection.centroid_px)
    cut = image.copy()
    cut[440:, :30] = image[v, u]  # a red patch in the bottom-left corner
    assert any(d.color == "red" and d.centroid_px[0] < 30
               for d in locator.detector.detect(cut))  # it is seen as red ...
    found = locator.locate(cut, joints)
    whole = [s for s in found if s.whole]
    assert [s.location for s in whole] == [s.location for s in before]
    assert len(whole) == len(truth)
    for s in found:  # ... but never taken for a whole block
        assert s.detection is not None
        assert s.whole == (s.detection.centroid_px[0] > 30)


def test_a_blob_the_lens_model_cannot_undo_spoils_no_other(picture: tuple) -> None:
    """With a lens model that cannot be inverted at the picture's very corner (a fitted
    k3 does that), a blob there is left out, and every other block keeps its position
    and its yaw (once, all yaws fell back to 0 and a block was grasped on its edges)."""
    image, joints, truth = picture
    lens = LensSpec()
    distortion = np.array(lens.dist_coeffs, dtype=float)
    distortion[4] = -0.3
    intr = CameraIntrinsics(model="pinhole", width_px=lens.width_px, height_px=lens.height_px,
                            camera_matrix=lens.camera_matrix, distortion=distortion)
    _, he = _truth_calibration(intrinsics=intr)
    kin = ArmKinematics.from_config(load_arm_config())
    locator = BlockLocator(kin, intr, he, ColorDetector(default_thresholds()))
    before = locator.locate(image, joints)
    assert len(before) == len(truth)
    red = next(s for s in before if s.color == "red")
    assert red.detection is not None
    u, v = (round(c) for c in red.detection.centroid_px)
    cut = image.copy()
    cut[455:, :22] = image[v, u]
    with pytest.raises(VisionError, match="cannot be undistorted"):  # all at once fails
        locator._table_yaws(locator.detector.detect(cut), locator.cam2base(joints))
    assert [s.location for s in locator.locate(cut, joints)] == [s.location for s in before]


def test_implausible_hand_eye_calibrations_are_refused() -> None:
    kin = ArmKinematics.from_config(load_arm_config())
    far = np.eye(4)
    far[0, 3] = 5000.0
    intr, he = _truth_calibration(cam2link=far)
    with pytest.raises(ConfigError, match="5000 mm from the wrist"):
        BlockLocator(kin, intr, he, ColorDetector(default_thresholds()))
    intr, he = _truth_calibration(link="elbow_pitch")
    with pytest.raises(ConfigError, match="elbow_pitch"):
        BlockLocator(kin, intr, he, ColorDetector(default_thresholds()))
