"""Pixels to the table, and blocks from their blob centroids.

References are computed independently of ``busarm.vision.localize``: the cube's
silhouette is the convex hull of its projected corners (``cv2.convexHull`` on the
undistorted image), its outline bent by ``cv2.projectPoints``, or a supersampled
pixel mask; the solver must put the block back where it was.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from busarm.errors import ConfigError, VisionError
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.localize import (
    BlockLocation,
    average_locations,
    camera_to_base,
    locate_block,
    locate_blocks,
    table_points_from_pixels,
)

VENDOR = CameraIntrinsics.vendor_default()
IDEAL = CameraIntrinsics("pinhole", 640, 480, VENDOR.camera_matrix, np.zeros(5))
STRONG = CameraIntrinsics("pinhole", 640, 480, VENDOR.camera_matrix,
                          np.array([-0.25, 0.08, 0.003, -0.002, -0.01]))


def look_at(camera: list[float], target: list[float]) -> np.ndarray:
    """cam2base of a camera at ``camera`` (mm) looking at ``target``, image x to the
    right when the view is horizontal."""
    c, t = np.asarray(camera, float), np.asarray(target, float)
    z = (t - c) / np.linalg.norm(t - c)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    out = np.eye(4)
    out[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    out[:3, 3] = c
    return out


OBLIQUE = look_at([80.0, 0.0, 280.0], [230.0, 0.0, 0.0])
DOWN = look_at([220.0, 10.0, 330.0], [220.0, 10.0, 0.0])


def cube_corners(x: float, y: float, size: float, yaw_deg: float, table: float = 0.0) -> np.ndarray:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pts = []
    for dx in (-0.5, 0.5):
        for dy in (-0.5, 0.5):
            for dz in (0.0, 1.0):
                pts.append([x + size * (c * dx - s * dy), y + size * (s * dx + c * dy),
                            table + size * dz])
    return np.array(pts)


def to_camera(points: np.ndarray, cam2base: np.ndarray) -> np.ndarray:
    return (points - cam2base[:3, 3]) @ cam2base[:3, :3]


def hull_centroid(
    intr: CameraIntrinsics, cam2base: np.ndarray, corners: np.ndarray, per_edge: int = 400
) -> np.ndarray:
    """The silhouette's area centroid (px): hull of the corners in the undistorted
    image (exact: straight edges there), each edge bent through OpenCV's lens model."""
    p = to_camera(corners, cam2base)
    n = p[:, :2] / p[:, 2:]
    hull = n[cv2.convexHull(n.astype(np.float32), returnPoints=False).ravel()]
    t = np.arange(per_edge) / per_edge
    outline = np.concatenate(
        [a + t[:, None] * (b - a) for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True)]
    )
    rays = np.hstack([outline, np.ones((outline.shape[0], 1))])
    px, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), intr.camera_matrix, intr.distortion)
    x, y = px.reshape(-1, 2).T
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    return np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (3.0 * cross.sum())


def mask_centroid(
    intr: CameraIntrinsics, cam2base: np.ndarray, corners: np.ndarray, sub: int = 4
) -> np.ndarray:
    """The centroid of the cube's pixels, as a blob detector sees it: ``sub`` x ``sub``
    samples per pixel, a sample counts if its ray passes through the cube."""
    p = to_camera(corners, cam2base)
    px = intr.pixels_from_camera_points(p)
    lo = np.floor(px.min(axis=0)).astype(int) - 3
    hi = np.ceil(px.max(axis=0)).astype(int) + 3
    offsets = (np.arange(sub) + 0.5) / sub - 0.5
    us = (np.arange(lo[0], hi[0])[:, None] + offsets).ravel()
    vs = (np.arange(lo[1], hi[1])[:, None] + offsets).ravel()
    grid = np.stack(np.meshgrid(us, vs), axis=-1).reshape(-1, 2)
    n = intr.normalized_from_pixels(grid)
    hull = cv2.convexHull((p[:, :2] / p[:, 2:]).astype(np.float32))
    inside = np.array([
        cv2.pointPolygonTest(hull, (float(a), float(b)), False) >= 0 for a, b in n
    ])
    samples = grid[inside]
    # A pixel's samples average to its centre, so this is the pixel-mask centroid.
    return samples.mean(axis=0)


# --------------------------------------------------------------------------- table points


@pytest.mark.parametrize("intr", [VENDOR, STRONG], ids=["vendor", "strong"])
@pytest.mark.parametrize("cam2base", [OBLIQUE, DOWN], ids=["oblique", "down"])
def test_table_points_round_trip(intr: CameraIntrinsics, cam2base: np.ndarray) -> None:
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(150, 300, 400), rng.uniform(-100, 100, 400),
                           np.full(400, 12.5)])
    px = intr.pixels_from_camera_points(to_camera(pts, cam2base))
    inside = (px[:, 0] > 0) & (px[:, 0] < 639) & (px[:, 1] > 0) & (px[:, 1] < 479)
    assert inside.sum() > 100
    back = table_points_from_pixels(px[inside], intr, cam2base, plane_z_mm=12.5)
    assert np.abs(back - pts[inside]).max() < 1e-4
    assert np.all(back[:, 2] == 12.5)


def test_rays_that_miss_the_table() -> None:
    # Looking level: the upper half of the image is above the horizon.
    level = look_at([0.0, 0.0, 100.0], [500.0, 0.0, 100.0])
    with pytest.raises(VisionError, match=r"pixel \(320\.00, 100\.00\) \(#1\) never meets the "
                                          r"plane z = 0 mm"):
        table_points_from_pixels([[320.0, 400.0], [320.0, 100.0]], VENDOR, level)
    with pytest.raises(VisionError, match="#0"):  # the plane above the camera, looking down
        table_points_from_pixels([[320.0, 240.0]], VENDOR, DOWN, plane_z_mm=400.0)
    with pytest.raises(ConfigError, match="cam2base is not a rigid transform"):
        table_points_from_pixels([[320.0, 240.0]], VENDOR, np.diag([1.0, 1.0, 2.0, 1.0]))


def test_camera_to_base() -> None:
    link2base = look_at([200.0, 50.0, 250.0], [300.0, 0.0, 0.0])
    cam2link = look_at([-51.0, -64.0, 0.0], [0.0, 200.0, 0.0])
    assert np.allclose(camera_to_base(link2base, cam2link), link2base @ cam2link)
    with pytest.raises(ConfigError, match="cam2link"):
        camera_to_base(link2base, np.zeros((4, 4)))


# --------------------------------------------------------------------------- blocks


@pytest.mark.parametrize("cam2base", [OBLIQUE, DOWN], ids=["oblique", "down"])
@pytest.mark.parametrize("yaw", [0.0, 30.0, 45.0])
@pytest.mark.parametrize("where", [(230.0, 0.0), (300.0, 90.0), (180.0, -100.0)])
def test_silhouette_without_distortion_is_exact(
    cam2base: np.ndarray, yaw: float, where: tuple[float, float]
) -> None:
    corners = cube_corners(*where, 30.0, yaw, table=5.0)
    centroid = hull_centroid(IDEAL, cam2base, corners, per_edge=1)  # straight edges: exact
    loc = locate_block(centroid, IDEAL, cam2base, table_z_mm=5.0, block_size_mm=30.0,
                       yaw_deg=yaw)
    assert abs(loc.x_mm - where[0]) < 1e-6 and abs(loc.y_mm - where[1]) < 1e-6
    assert loc.z_mm == 35.0 and loc.size_mm == 30.0 and loc.silhouette
    assert loc.residual_px < 0.01


@pytest.mark.parametrize("intr", [VENDOR, STRONG], ids=["vendor", "strong"])
@pytest.mark.parametrize("where", [(230.0, 0.0), (300.0, 90.0), (180.0, -100.0)])
def test_silhouette_with_distortion(intr: CameraIntrinsics, where: tuple[float, float]) -> None:
    corners = cube_corners(*where, 30.0, 20.0)
    centroid = hull_centroid(intr, OBLIQUE, corners)
    loc = locate_block(centroid, intr, OBLIQUE, block_size_mm=30.0, yaw_deg=20.0)
    assert math.hypot(loc.x_mm - where[0], loc.y_mm - where[1]) < 0.01
    # The top-face ray hit is what a naive localiser does: millimetres off.
    naive = locate_block(centroid, intr, OBLIQUE, block_size_mm=30.0, silhouette=False)
    assert math.hypot(naive.x_mm - where[0], naive.y_mm - where[1]) > 3.0


def test_pixel_mask_centroid() -> None:
    # What a colour detector reports: the mean of the blob's pixel indices.
    where = (300.0, 90.0)
    corners = cube_corners(*where, 30.0, 10.0)
    measured = mask_centroid(VENDOR, OBLIQUE, corners)
    assert np.abs(measured - hull_centroid(VENDOR, OBLIQUE, corners)).max() < 0.02
    loc = locate_block(measured, VENDOR, OBLIQUE, block_size_mm=30.0, yaw_deg=10.0)
    assert math.hypot(loc.x_mm - where[0], loc.y_mm - where[1]) < 0.05


def test_top_face_only() -> None:
    # A blob of the top face alone: its centre is the ray's hit at the top-face height
    # (up to the top face's own perspective, which is the caller's centroid to give).
    where = (260.0, 40.0)
    px = VENDOR.pixels_from_camera_points(to_camera(np.array([[*where, 30.0]]), OBLIQUE))
    loc = locate_block(px[0], VENDOR, OBLIQUE, block_size_mm=30.0, silhouette=False)
    assert abs(loc.x_mm - where[0]) < 1e-6 and abs(loc.y_mm - where[1]) < 1e-6
    assert loc.z_mm == 30.0 and not loc.silhouette and loc.residual_px == 0.0


def test_locate_blocks_in_one_pass() -> None:
    rng = np.random.default_rng(2)
    truth = np.column_stack([rng.uniform(180, 300, 6), rng.uniform(-90, 90, 6)])
    yaws = rng.uniform(0, 90, 6).tolist()
    centroids = np.array([
        hull_centroid(VENDOR, OBLIQUE, cube_corners(x, y, 30.0, yaw))
        for (x, y), yaw in zip(truth, yaws, strict=True)
    ])
    locs = locate_blocks(centroids, VENDOR, OBLIQUE, block_size_mm=30.0, yaw_deg=yaws)
    got = np.array([loc.xy_mm for loc in locs])
    assert np.abs(got - truth).max() < 0.01
    for c, yaw, loc in zip(centroids, yaws, locs, strict=True):
        one = locate_block(c, VENDOR, OBLIQUE, block_size_mm=30.0, yaw_deg=yaw)
        assert abs(one.x_mm - loc.x_mm) < 1e-9 and abs(one.y_mm - loc.y_mm) < 1e-9
        assert loc.centroid_px == (float(c[0]), float(c[1]))
    assert locate_blocks(np.zeros((0, 2)), VENDOR, OBLIQUE) == []


def test_locate_block_refuses() -> None:
    level = look_at([0.0, 0.0, 100.0], [500.0, 0.0, 100.0])
    with pytest.raises(VisionError, match=r"centroid \(320\.00, 60\.00\) \(#0\)"):
        locate_block([320.0, 60.0], VENDOR, level)
    low = look_at([150.0, 0.0, 40.0], [200.0, 0.0, 0.0])  # nearly touching the block
    with pytest.raises(VisionError):
        locate_block([320.0, 240.0], VENDOR, low, block_size_mm=80.0)
    with pytest.raises(ConfigError, match="block_size_mm"):
        locate_block([320.0, 240.0], VENDOR, OBLIQUE, block_size_mm=0.0)
    with pytest.raises(ConfigError, match="yaw_deg has 1 values for 2 blocks"):
        locate_blocks([[320.0, 240.0], [300.0, 200.0]], VENDOR, OBLIQUE, yaw_deg=[0.0])
    with pytest.raises(ConfigError, match="one pixel"):
        locate_block([[320.0, 240.0], [300.0, 200.0]], VENDOR, OBLIQUE)
    with pytest.raises(ConfigError, match="finite"):
        locate_block([np.nan, 240.0], VENDOR, OBLIQUE)


# --------------------------------------------------------------------------- averaging


def test_average_locations() -> None:
    def at(x: float, y: float, yaw: float, frames: int = 1) -> BlockLocation:
        return BlockLocation(x, y, 30.0, yaw, 30.0, (300.0, 200.0), 0.001, True, frames)

    avg = average_locations([at(100.0, 0.0, 88.0), at(102.0, 0.0, -88.0, frames=3)])
    assert avg.x_mm == pytest.approx(101.5) and avg.y_mm == 0.0 and avg.z_mm == 30.0
    assert avg.frames == 4
    assert avg.spread_max_mm == pytest.approx(1.5)
    assert avg.spread_mean_mm == pytest.approx((1.5 * 1 + 0.5 * 3) / 4)
    # 88 and -88 deg are 4 deg apart for a cube (90 deg symmetry): the mean is near +-90.
    assert min(abs(avg.yaw_deg - 90.0), abs(avg.yaw_deg + 90.0), abs(avg.yaw_deg)) < 2.0
    single = average_locations([at(1.0, 2.0, 5.0)])
    assert (single.x_mm, single.y_mm, single.spread_max_mm) == (1.0, 2.0, 0.0)
    with pytest.raises(ConfigError, match="at least one"):
        average_locations([])
    other = BlockLocation(0.0, 0.0, 40.0, 0.0, 40.0, (0.0, 0.0))
    with pytest.raises(ConfigError, match="different sizes"):
        average_locations([at(0.0, 0.0, 0.0), other])
