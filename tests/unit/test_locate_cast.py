"""BlockLocator casts every whole blob's outline onto the blocks' top plane in one call:
the same points as one blob at a time, and a blob whose rays miss the plane is None
without spoiling the others, nor (part by part) the parts of its own that meet it."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.bench.vision import _true_camera
from busarm.perception.locate import BlockLocator
from busarm.perception.top_plane import cast_blobs
from busarm.perception.top_plane import straight_outline as _straight_outline
from busarm.vision.color import ColorDetector
from busarm.vision.color_thresholds import default_thresholds
from busarm.vision.localize import table_points_from_pixels


def _locator() -> BlockLocator:
    intrinsics, hand_eye = _true_camera()
    detector = ColorDetector(default_thresholds().select(["red", "green", "blue"]))
    return BlockLocator(ArmKinematics.from_config(load_arm_config()), intrinsics, hand_eye,
                        detector)


def _picture() -> npt.NDArray[np.uint8]:
    """Grey, with a red square above the picture's middle and a tilted one below it."""
    img = np.full((480, 640, 3), 128, np.uint8)
    cv2.rectangle(img, (280, 60), (340, 120), (30, 30, 200), -1)
    box = cv2.boxPoints(((400.0, 330.0), (70.0, 50.0), 25.0)).astype(np.int32)
    cv2.fillPoly(img, [box], (30, 30, 200))
    return img


def _looking_level() -> npt.NDArray[np.float64]:
    """A camera 300 mm up looking along the base's x, level: the picture's upper half
    sees no table."""
    cam2base = np.eye(4)
    cam2base[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    cam2base[:3, 3] = (0.0, 0.0, 300.0)
    return cam2base


def test_outlines_cast_together_as_each_alone() -> None:
    locator = _locator()
    detections = locator.detector.detect(_picture())
    assert len(detections) == 2
    cam2base = np.eye(4)
    cam2base[:3, :3] = np.diag([1.0, -1.0, -1.0])  # looking straight down
    cam2base[:3, 3] = (150.0, 0.0, 400.0)
    top = locator.table_z_mm + locator.block_size_mm
    together = locator._cast_outlines(detections, cam2base)
    for d, cast in zip(detections, together, strict=True):
        alone = table_points_from_pixels(_straight_outline(d).astype(np.float64),
                                         locator.intrinsics, cam2base, top)[:, :2]
        assert cast is not None
        np.testing.assert_array_equal(cast, alone)


def test_an_outline_that_misses_the_plane_spoils_no_other() -> None:
    locator = _locator()
    detections = locator.detector.detect(_picture())
    cast = locator._cast_outlines(detections, _looking_level())
    above = [d.centroid_px[1] < 240 for d in detections]
    assert [c is None for c in cast] == above
    assert locator._cast_outlines([], _looking_level()) == []


def test_a_blob_cast_part_by_part_when_one_part_misses_the_plane() -> None:
    # A tall thin blob across the horizon of a level camera: its centroid and its
    # rectangle's edge (below the horizon) meet the plane, its outline does not.
    img = np.full((480, 640, 3), 128, np.uint8)
    cv2.rectangle(img, (300, 200), (312, 420), (30, 30, 200), -1)
    cv2.rectangle(img, (100, 300), (160, 360), (30, 30, 200), -1)
    locator = _locator()
    detections = locator.detector.detect(img)
    assert len(detections) == 2
    top = locator.table_z_mm + locator.block_size_mm
    casts = cast_blobs(detections, locator.intrinsics, _looking_level(), top)
    tall = next(i for i, d in enumerate(detections) if d.contour_px[:, 1].min() < 240)
    assert casts[tall].outline is None
    assert casts[tall].centre is not None and casts[tall].yaw_deg is not None
    other = casts[1 - tall]
    assert other.centre is not None and other.outline is not None and other.yaw_deg is not None
    alone = cast_blobs([detections[1 - tall]], locator.intrinsics, _looking_level(), top)[0]
    assert other.outline is not None and alone.outline is not None
    np.testing.assert_array_equal(other.outline, alone.outline)
    assert cast_blobs([], locator.intrinsics, _looking_level(), top) == []
