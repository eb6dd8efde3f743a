"""CameraIntrinsics.plane_pixel_maps: a grid of camera points mapped to pixels in one pass
(OpenCV's rectification maps, for a pinhole lens) is the camera model's own projection of
each point, for every lens model; a grid reaching behind the camera is refused."""

from __future__ import annotations

import numpy as np
import pytest

from busarm.errors import VisionError
from busarm.vision.calibration import CameraIntrinsics

K = np.array([[470.0, 0.0, 322.0], [0.0, 468.0, 241.0], [0.0, 0.0, 1.0]])
LENSES = [
    CameraIntrinsics("pinhole", 640, 480, K, np.array([-0.3, 0.12, 0.0008, -0.0006, -0.02])),
    CameraIntrinsics("pinhole", 640, 480, K, np.array([-0.1, 0.01, 0.001, 0.002, 0.0,
                                                        0.02, 0.001, 0.0])),
    CameraIntrinsics("pinhole", 640, 480, K, np.array([0.0, 0.0, 0.0, 0.0])),
    CameraIntrinsics("fisheye", 640, 480, K, np.array([0.05, -0.01, 0.002, 0.0])),
]
# A plane 200..300 mm in front of a camera looking down at it obliquely: 0.5 mm a place.
GRID2CAM = np.array([[0.5, 0.0, -40.0], [0.0, 0.4, -30.0], [0.0, 0.2, 250.0]])


@pytest.mark.parametrize("lens", LENSES, ids=lambda i: f"{i.model}{i.distortion.size}")
def test_the_maps_are_the_projection_of_each_place(lens: CameraIntrinsics) -> None:
    cols, rows, offset = 160, 150, (12.0, -7.0)
    map_u, map_v = lens.plane_pixel_maps(GRID2CAM, cols, rows, offset)
    assert map_u.shape == map_v.shape == (rows, cols) and map_u.dtype == np.float32
    c, r = np.meshgrid(np.arange(cols, dtype=float), np.arange(rows, dtype=float))
    points = np.stack([c.ravel(), r.ravel(), np.ones(c.size)], axis=1) @ GRID2CAM.T
    want = lens.pixels_from_camera_points(points) - offset
    np.testing.assert_allclose(map_u.ravel(), want[:, 0], atol=1e-4)
    np.testing.assert_allclose(map_v.ravel(), want[:, 1], atol=1e-4)


def test_a_grid_reaching_behind_the_camera_is_refused() -> None:
    behind = GRID2CAM.copy()
    behind[2] = (0.0, -2.0, 250.0)  # row 125 on is behind the camera
    with pytest.raises(VisionError, match="behind the camera"):
        LENSES[0].plane_pixel_maps(behind, 10, 150, (0.0, 0.0))
    LENSES[0].plane_pixel_maps(behind, 10, 120, (0.0, 0.0))
