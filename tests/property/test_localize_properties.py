"""Properties of pixel -> table localisation (hypothesis, derandomized).

Under random camera poses above the table and random lens distortion (pinhole with
radial and tangential terms, or fisheye):

- a table point seen in the image comes back from its pixel (table -> pixel -> table)
  and its pixel from the point (pixel -> table -> pixel);
- a cube's exact silhouette centroid (hull of its corners in the undistorted image,
  the outline bent by OpenCV's lens model) gives the cube's position back.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from busarm.errors import VisionError
from busarm.vision import localize
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.localize import locate_block, locate_blocks, table_points_from_pixels

Array = npt.NDArray[np.float64]
PROPS = settings(max_examples=60, deadline=None, derandomize=True)


def look_at(camera: Array, target: Array, roll_deg: float) -> Array:
    z = (target - camera) / np.linalg.norm(target - camera)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    a = math.radians(roll_deg)  # turn the image about the optical axis
    x, y = math.cos(a) * x + math.sin(a) * y, -math.sin(a) * x + math.cos(a) * y
    out = np.eye(4)
    out[:3, :3] = np.stack([x, y, z], axis=1)
    out[:3, 3] = camera
    return out


@st.composite
def cameras(draw: st.DrawFn) -> CameraIntrinsics:
    f = draw(st.floats(350.0, 600.0))
    k = np.array([[f * draw(st.floats(0.98, 1.02)), 0.0, draw(st.floats(300.0, 340.0))],
                  [0.0, f, draw(st.floats(220.0, 260.0))], [0.0, 0.0, 1.0]])
    if draw(st.booleans()):
        dist = [draw(st.floats(-0.3, 0.1)), draw(st.floats(-0.05, 0.05)),
                draw(st.floats(-0.005, 0.005)), draw(st.floats(-0.005, 0.005)),
                draw(st.floats(-0.02, 0.02))]
        return CameraIntrinsics("pinhole", 640, 480, k, np.array(dist))
    dist = [draw(st.floats(-0.05, 0.05)) for _ in range(4)]
    return CameraIntrinsics("fisheye", 640, 480, k, np.array(dist))


@st.composite
def poses(draw: st.DrawFn) -> Array:
    """cam2base above the table, looking down at a point of the work area."""
    camera = np.array([draw(st.floats(0.0, 250.0)), draw(st.floats(-150.0, 150.0)),
                       draw(st.floats(150.0, 400.0))])
    target = np.array([draw(st.floats(150.0, 320.0)), draw(st.floats(-120.0, 120.0)), 0.0])
    assume(np.linalg.norm(target - camera) > 150.0)
    return look_at(camera, target, draw(st.floats(-180.0, 180.0)))


def to_camera(points: Array, cam2base: Array) -> Array:
    out: Array = (points - cam2base[:3, 3]) @ cam2base[:3, :3]
    return out


def in_image(px: Array) -> bool:
    return bool(np.all((px[:, 0] > 0) & (px[:, 0] < 639) & (px[:, 1] > 0) & (px[:, 1] < 479)))


def opencv_pixels(intr: CameraIntrinsics, rays: Array) -> Array:
    if intr.model == "pinhole":
        px, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), intr.camera_matrix,
                                  intr.distortion)
    else:
        px, _ = cv2.fisheye.projectPoints(rays.reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                                          intr.camera_matrix, intr.distortion)
    out: Array = px.reshape(-1, 2)
    return out


@PROPS
@given(cameras(), poses(), st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(-10.0, 40.0))
def test_table_pixel_table(
    intr: CameraIntrinsics, cam2base: Array, fu: float, fv: float, plane: float
) -> None:
    # A pixel of the image (where the lens model is one-to-one), to the table and back.
    px = np.array([[20.0 + 600.0 * fu, 20.0 + 440.0 * fv]])
    try:
        point = table_points_from_pixels(px, intr, cam2base, plane_z_mm=plane)
    except VisionError:
        assume(False)  # its ray misses the plane or the lens cannot image it
        raise
    assert abs(point[0, 2] - plane) < 1e-9
    back = intr.pixels_from_camera_points(to_camera(point, cam2base))
    assert np.abs(back - px).max() < 1e-4
    # And from the point: the pixel OpenCV projects it to gives the point again.
    again = table_points_from_pixels(opencv_pixels(intr, to_camera(point, cam2base)), intr,
                                     cam2base, plane_z_mm=plane)
    assert np.abs(again - point).max() < 0.01


def silhouette_centroid(intr: CameraIntrinsics, cam2base: Array, corners: Array) -> Array:
    p = to_camera(corners, cam2base)
    n = p[:, :2] / p[:, 2:]
    hull = n[cv2.convexHull(n.astype(np.float32), returnPoints=False).ravel()]
    t = np.arange(300) / 300
    outline = np.concatenate(
        [a + t[:, None] * (b - a) for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True)]
    )
    px = opencv_pixels(intr, np.hstack([outline, np.ones((outline.shape[0], 1))]))
    x, y = px.T
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    out: Array = np.array([((x + xn) * cross).sum(), ((y + yn) * cross).sum()]) / (
        3.0 * cross.sum()
    )
    return out


@PROPS
@given(cameras(), poses(), st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(0.0, 90.0),
       st.floats(20.0, 40.0), st.floats(-5.0, 20.0))
def test_silhouette_gives_the_cube_back(
    intr: CameraIntrinsics, cam2base: Array, fu: float, fv: float, yaw: float, size: float,
    table: float,
) -> None:
    # Put the cube where pixel (fu, fv) of the image looks at the table.
    px = np.array([[60.0 + 520.0 * fu, 60.0 + 360.0 * fv]])
    try:
        spot = table_points_from_pixels(px, intr, cam2base, plane_z_mm=table)[0]
    except VisionError:
        assume(False)
        raise
    # The wrist camera sees blocks within about half a metre; farther out, at the rim of a
    # strong lens, a few 0.001 px of outline chord error reach 0.01 mm (seen at 598 mm).
    assume(np.linalg.norm(spot - cam2base[:3, 3]) < 500.0)
    c, s = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    corners = np.array([
        [spot[0] + size * (c * dx - s * dy), spot[1] + size * (s * dx + c * dy), table + size * dz]
        for dx in (-0.5, 0.5) for dy in (-0.5, 0.5) for dz in (0.0, 1.0)
    ])
    p = to_camera(corners, cam2base)
    assume(np.all(p[:, 2] > 2.0 * size))
    assume(in_image(intr.pixels_from_camera_points(p)))
    measured = silhouette_centroid(intr, cam2base, corners)
    loc = locate_block(measured, intr, cam2base, table_z_mm=table, block_size_mm=size,
                       yaw_deg=yaw)
    assert math.hypot(loc.x_mm - spot[0], loc.y_mm - spot[1]) < 0.01
    assert loc.z_mm == table + size and loc.residual_px < 0.01


@PROPS
@given(cameras(), poses(), st.lists(st.tuples(st.floats(0.1, 0.9), st.floats(0.1, 0.9),
                                              st.floats(0.0, 90.0)), min_size=1, max_size=4))
def test_the_start_changes_no_answer(
    intr: CameraIntrinsics, cam2base: Array, blobs: list[tuple[float, float, float]]
) -> None:
    # The solve from the estimated start (and with the Jacobian kept near the answer)
    # ends where the one from the plain start (the measured pixel) does.
    px = np.array([[60.0 + 520.0 * fu, 60.0 + 360.0 * fv] for fu, fv, _ in blobs])
    yaws = [yaw for _, _, yaw in blobs]
    try:
        plain_start = localize._better_start
        localize._better_start = lambda *args: None
        try:
            plain = locate_blocks(px, intr, cam2base, yaw_deg=yaws)
        finally:
            localize._better_start = plain_start
    except VisionError:
        assume(False)
        raise
    got = locate_blocks(px, intr, cam2base, yaw_deg=yaws)
    for a, b in zip(plain, got, strict=True):
        assert math.hypot(a.x_mm - b.x_mm, a.y_mm - b.y_mm) < 1e-3
        assert b.residual_px < 0.01
    stacked = localize._yaw_matrices(yaws)
    assert np.abs(stacked - np.stack([localize._yaw_matrix(y) for y in yaws])).max() < 1e-15
