"""AprilTag 36h11: tags rendered through a known camera (pinhole, pinhole with distortion,
fisheye) at known poses, detected, and their poses solved back to tight tolerances."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from busarm.errors import ConfigError
from busarm.vision.tags import (
    DEFAULT_TAG_SIZE_MM,
    TAG_COUNT,
    TagDetection,
    detect_tags,
    tag_image,
    tag_object_points,
    tag_pose,
)

K = np.array([[600.0, 0.0, 322.5], [0.0, 602.0, 238.0], [0.0, 0.0, 1.0]])
W, H = 640, 480
SIZE_MM = 30.0
CELL_PX = 16
SUPERSAMPLE = 2
FLIP = np.diag([1.0, -1.0, -1.0])
"""Turns the tag to face the camera (its z towards the viewer)."""


def pose(rx_deg: float, ry_deg: float, rz_deg: float, t_mm: tuple[float, float, float]
         ) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (tag to camera) and translation of a tag facing the camera, tilted."""
    rot = cv2.Rodrigues(np.radians([rx_deg, ry_deg, 0.0]))[0]
    spin = cv2.Rodrigues(np.radians([0.0, 0.0, rz_deg]))[0]
    return rot @ FLIP @ spin, np.array(t_mm, float)


def undistort(points: np.ndarray, dist: np.ndarray | None, fisheye: bool) -> np.ndarray:
    pts = points.reshape(-1, 1, 2)
    if fisheye:
        return cv2.fisheye.undistortPoints(pts, K, dist).reshape(-1, 2)
    return cv2.undistortPoints(pts, K, dist).reshape(-1, 2)


def render(tags: list[tuple[int, np.ndarray, np.ndarray, float]], dist: np.ndarray | None = None,
           fisheye: bool = False) -> np.ndarray:
    """Grey 640x480 image of tags (id, R, t, size mm) seen through the camera (K, dist):
    each pixel's ray (2x supersampled) meets each tag's plane, the tag's texture is
    sampled bilinearly there (so an edge sits exactly where it is), then averaged."""
    s = SUPERSAMPLE
    uu, vv = np.meshgrid(np.arange(W * s), np.arange(H * s))
    pix = np.stack([(uu + 0.5) / s - 0.5, (vv + 0.5) / s - 0.5], -1).reshape(-1, 2)
    rays = np.column_stack([undistort(pix.astype(np.float64), dist, fisheye),
                            np.ones(len(pix))])
    out = np.full((H * s, W * s), 128.0, np.float32)
    for tag_id, rot, t, size_mm in tags:
        border = 2 * CELL_PX
        img = tag_image(tag_id, 8 * CELL_PX, border).astype(np.float32)
        plane = np.column_stack([rot[:, 0], rot[:, 1], t])  # (X, Y, 1) -> camera ray
        tag_xy = np.linalg.solve(plane, rays.T).T
        x = tag_xy[:, 0] / tag_xy[:, 2]
        y = tag_xy[:, 1] / tag_xy[:, 2]
        px_per_mm = 8 * CELL_PX / size_mm
        col = (border + (x + size_mm / 2) * px_per_mm - 0.5).reshape(H * s, W * s)
        row = (border + (size_mm / 2 - y) * px_per_mm - 0.5).reshape(H * s, W * s)
        n = img.shape[0]
        inside = (col >= 0) & (col <= n - 1) & (row >= 0) & (row <= n - 1)
        sampled = cv2.remap(img, col.astype(np.float32), row.astype(np.float32),
                            cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        out[inside] = sampled[inside]
    return np.asarray(cv2.resize(out, (W, H), interpolation=cv2.INTER_AREA).round(), np.uint8)


def project(rot: np.ndarray, t: np.ndarray, size_mm: float, dist: np.ndarray | None = None,
            fisheye: bool = False) -> np.ndarray:
    rvec = cv2.Rodrigues(rot)[0]
    obj = tag_object_points(size_mm)
    if fisheye:
        pts, _ = cv2.fisheye.projectPoints(obj.reshape(-1, 1, 3), rvec, t, K, dist)
    else:
        pts, _ = cv2.projectPoints(obj, rvec, t, K, dist)
    return pts.reshape(4, 2)


def rotation_error_deg(a: np.ndarray, b: np.ndarray) -> float:
    c = (np.trace(a.T @ b) - 1.0) / 2.0
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


POSES = [
    (3, (0.0, 0.0, 0.0), (0.0, 0.0, 200.0)),
    (17, (25.0, -10.0, 40.0), (-20.0, 15.0, 180.0)),
    (586, (-20.0, 30.0, -75.0), (30.0, -25.0, 230.0)),
    (0, (35.0, 20.0, 170.0), (10.0, 30.0, 160.0)),
]


@pytest.mark.parametrize(("tag_id", "angles", "t_mm"), POSES)
def test_pinhole_corners_and_pose(tag_id: int, angles: tuple[float, float, float],
                                  t_mm: tuple[float, float, float]) -> None:
    rot, t = pose(*angles, t_mm)
    image = render([(tag_id, rot, t, SIZE_MM)])
    (det,) = detect_tags(image)
    truth = project(rot, t, SIZE_MM)
    assert det.tag_id == tag_id
    assert np.abs(det.corners_px - truth).max() < 0.08, det.corners_px - truth
    centre = project(rot, t, 0.0)[0]  # the tag's origin
    assert math.dist(det.center_px, centre) < 0.05
    tag2cam, err = tag_pose(det, SIZE_MM, K, np.zeros(5))
    assert err < 0.05
    assert np.linalg.norm(tag2cam[:3, 3] - t) < 0.15
    # Face-on, the tilt is the least determined part of a tag's pose.
    assert rotation_error_deg(tag2cam[:3, :3], rot) < 0.3
    assert np.allclose(tag2cam[3], [0, 0, 0, 1]) and tag2cam.dtype == np.float64


def test_noisy_image() -> None:
    rot, t = pose(15.0, 25.0, 100.0, (-30.0, 20.0, 300.0))
    clean = render([(11, rot, t, SIZE_MM)]).astype(np.float64)
    noisy = np.clip(clean + np.random.default_rng(5).normal(0, 4, clean.shape), 0, 255)
    (det,) = detect_tags(noisy.astype(np.uint8))
    assert np.abs(det.corners_px - project(rot, t, SIZE_MM)).max() < 0.15
    tag2cam, err = tag_pose(det, SIZE_MM, K, None)
    assert err < 0.15
    assert np.linalg.norm(tag2cam[:3, 3] - t) < 0.5
    assert rotation_error_deg(tag2cam[:3, :3], rot) < 0.5


def test_pose_through_lens_distortion() -> None:
    dist = np.array([-0.12, 0.05, 0.001, -0.0005, 0.0])
    rot, t = pose(20.0, -15.0, 25.0, (60.0, -45.0, 190.0))
    image = render([(42, rot, t, SIZE_MM)], dist)
    (det,) = detect_tags(image)
    # Edges are curved: straight-edge corners are a little off, the pose is not.
    assert np.abs(det.corners_px - project(rot, t, SIZE_MM, dist)).max() < 0.2
    tag2cam, err = tag_pose(det, SIZE_MM, K, dist)
    assert err < 0.05
    assert np.linalg.norm(tag2cam[:3, 3] - t) < 0.3
    assert rotation_error_deg(tag2cam[:3, :3], rot) < 0.2
    # Ignoring the distortion shows: the pose is off by much more.
    wrong, _ = tag_pose(det, SIZE_MM, K, None)
    assert np.linalg.norm(wrong[:3, 3] - t) > 3.0


def test_fisheye_pose() -> None:
    dist = np.array([0.08, -0.02, 0.005, 0.0])
    rot, t = pose(-15.0, 20.0, -30.0, (-50.0, 40.0, 170.0))
    image = render([(99, rot, t, SIZE_MM)], dist, fisheye=True)
    (det,) = detect_tags(image)
    assert np.abs(det.corners_px - project(rot, t, SIZE_MM, dist, fisheye=True)).max() < 0.4
    tag2cam, err = tag_pose(det, SIZE_MM, K, dist, fisheye=True)
    assert err < 0.1
    assert np.linalg.norm(tag2cam[:3, 3] - t) < 0.5
    assert rotation_error_deg(tag2cam[:3, :3], rot) < 0.3
    # The same corners taken as a pinhole camera's: clearly another pose.
    wrong, _ = tag_pose(det, SIZE_MM, K, None)
    assert np.linalg.norm(wrong[:3, 3] - t) > 2.0
    with pytest.raises(ConfigError, match="fisheye camera must be 4"):
        tag_pose(det, SIZE_MM, K, np.zeros(5), fisheye=True)


def test_several_tags_sorted_and_filtered() -> None:
    tags = [(9, *pose(0, 0, 10, (-45.0, 0.0, 250.0)), 25.0),
            (2, *pose(0, 0, -20, (45.0, 10.0, 250.0)), 25.0),
            (5, *pose(10, 0, 0, (0.0, -40.0, 250.0)), 25.0)]
    image = render([(i, r, t, s) for i, r, t, s in tags])
    assert [d.tag_id for d in detect_tags(image)] == [2, 5, 9]
    assert [d.tag_id for d in detect_tags(image, ids=[9, 5])] == [5, 9]
    assert detect_tags(image, ids=[]) == []
    bgr = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    assert [d.tag_id for d in detect_tags(bgr)] == [2, 5, 9]
    data = json.loads(json.dumps(detect_tags(bgr)[0].to_dict()))
    assert data["tag_id"] == 2 and len(data["corners_px"]) == 4


def test_no_tags_and_bad_images() -> None:
    assert detect_tags(np.full((H, W), 255, np.uint8)) == []
    assert detect_tags(np.zeros((H, W, 3), np.uint8)) == []
    for bad in (np.zeros((H, W), np.float32), np.zeros((H, W, 4), np.uint8), "img"):
        with pytest.raises(ConfigError, match="must be an H x W x 3"):
            detect_tags(bad)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"tag id 587 is out of range 0\.\.586"):
        detect_tags(np.zeros((H, W), np.uint8), ids=[587])


def test_tag_image() -> None:
    img = tag_image(7, 80, 10)
    assert img.shape == (100, 100) and img.dtype == np.uint8
    assert (img[:10] == 255).all() and (img[:, -10:] == 255).all()  # the white margin
    assert (img[10:20, 10:90] == 0).all()  # the black border cell row
    # It decodes as itself.
    (det,) = detect_tags(cv2.copyMakeBorder(img, 20, 20, 20, 20, cv2.BORDER_CONSTANT,
                                            value=255))
    assert det.tag_id == 7
    # Corner 0 is the black square's top-left (pixel 30 is its first, so its edge is 29.5).
    assert det.corners_px[0] == pytest.approx((29.5, 29.5), abs=0.01)
    assert det.corners_px[2] == pytest.approx((109.5, 109.5), abs=0.01)
    assert tag_image(TAG_COUNT - 1, 8, 0).shape == (8, 8)
    for args, words in [((TAG_COUNT, 80, 0), "tag id 587"), ((-1, 80, 0), "tag id -1"),
                        ((1, 7, 0), "size_px = 7"), ((1, 80, -1), "border_px = -1")]:
        with pytest.raises(ConfigError, match=words):
            tag_image(*args)


def test_tag_pose_checks_its_arguments() -> None:
    det = TagDetection(1, tag_object_points(40.0)[:, :2] + 300.0, (300.0, 300.0))
    with pytest.raises(ConfigError, match="tag_size_mm = 0"):
        tag_pose(det, 0, K, None)
    with pytest.raises(ConfigError, match="camera_matrix must be 3 x 3"):
        tag_pose(det, DEFAULT_TAG_SIZE_MM, np.eye(2), None)
    with pytest.raises(ConfigError, match="fx, fy > 0"):
        tag_pose(det, DEFAULT_TAG_SIZE_MM, np.diag([0.0, 1.0, 1.0]), None)
    with pytest.raises(ConfigError, match="pinhole camera must be 0 or 4 or 5"):
        tag_pose(det, DEFAULT_TAG_SIZE_MM, K, np.zeros(3))
    assert DEFAULT_TAG_SIZE_MM == 23.8
    obj = tag_object_points(2.0)
    assert obj.tolist() == [[-1, 1, 0], [1, 1, 0], [1, -1, 0], [-1, -1, 0]]
