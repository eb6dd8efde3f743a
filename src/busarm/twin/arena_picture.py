"""The arena seen from straight above, with the robot, its Lidar's points and its paths.

The ``arena`` camera is orthographic, so a point on the floor maps to a pixel by a scale
and an offset (``ArenaView.px``); the marks are drawn on the render: the robot's outline
and heading where it really is, the true path (green), a path the robot believed it took
(odometry, orange), and one Lidar scan's returns (red) placed from the robot's true pose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D
from busarm.lidar.scan import LaserScan, to_points
from busarm.twin.arena_model import CHASSIS_SIZE_M, arena_view_extent_m
from busarm.twin.twin import Twin
from busarm.vision.annotate import draw_label, label_size

__all__ = [
    "LIDAR_BGR",
    "ODOMETRY_BGR",
    "ROBOT_BGR",
    "TRUE_BGR",
    "ArenaView",
    "FloatArray",
    "Image",
    "arena_picture",
]


FloatArray = npt.NDArray[np.float64]
Image = npt.NDArray[np.uint8]

TRUE_BGR = (60, 190, 60)
ODOMETRY_BGR = (0, 140, 255)
LIDAR_BGR = (40, 40, 230)
ROBOT_BGR = (230, 200, 40)


class ArenaView:
    """The arena camera's picture and its floor-to-pixel mapping."""

    def __init__(self, twin: Twin) -> None:
        if twin.arena is None:
            raise ValueError("an arena view needs a twin with an arena")
        self.twin = twin
        r = twin.arena.room
        self.centre_m = ((r.x_min_m + r.x_max_m) / 2, (r.y_min_m + r.y_max_m) / 2)
        self._image: Image | None = None

    def image(self) -> Image:
        """The render (BGR), made once."""
        if self._image is None:
            rgb = self.twin.render_ideal("arena", live=True)
            self._image = np.ascontiguousarray(rgb[:, :, ::-1])
        return self._image

    def px(self, points_m: npt.ArrayLike) -> npt.NDArray[np.int32]:
        """Floor points (x, y in m, arena frame), shape (N, 2) -> pixel (u, v)."""
        h, w = self.image().shape[:2]
        assert self.twin.arena is not None
        scale = h / arena_view_extent_m(self.twin.arena)
        p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        u = w / 2 + (p[:, 0] - self.centre_m[0]) * scale
        v = h / 2 - (p[:, 1] - self.centre_m[1]) * scale
        return np.round(np.stack([u, v], axis=1)).astype(np.int32)


def _robot_outline(pose: Pose2D) -> FloatArray:
    hx, hy = CHASSIS_SIZE_M[0] / 2, CHASSIS_SIZE_M[1] / 2
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    corners = np.array([(hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy), (hx + 0.08, 0.0)])
    return np.stack([pose.x_m + corners[:, 0] * c - corners[:, 1] * s,
                     pose.y_m + corners[:, 0] * s + corners[:, 1] * c], axis=1)


def _world_points(twin: Twin, scan: LaserScan, pose: Pose2D) -> FloatArray:
    assert twin.chassis is not None
    local = to_points(scan, twin.chassis.lidar)
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    return np.stack([pose.x_m + local[:, 0] * c - local[:, 1] * s,
                     pose.y_m + local[:, 0] * s + local[:, 1] * c], axis=1)


def arena_picture(twin: Twin, *, scan: LaserScan | None = None,
                  odometry_path: Sequence[tuple[float, float]] = (),
                  title: str = "") -> Image:
    """The arena from above with the robot, its true path, ``odometry_path`` (arena
    frame, m) and ``scan``'s returns, and a legend."""
    assert twin.mobile is not None
    view = ArenaView(twin)
    image = view.image().copy()
    with twin.lock:
        pose = twin.mobile.pose(twin.data)
        true_path = [(x, y) for _t, x, y in twin.mobile.path]
    legend = []
    if len(true_path) > 1:
        cv2.polylines(image, [view.px(true_path)], False, TRUE_BGR, 2, cv2.LINE_AA)
        legend.append(("true path", TRUE_BGR))
    if len(odometry_path) > 1:
        cv2.polylines(image, [view.px(odometry_path)], False, ODOMETRY_BGR, 1, cv2.LINE_AA)
        legend.append(("odometry", ODOMETRY_BGR))
    if scan is not None:
        for u, v in view.px(_world_points(twin, scan, pose)):
            cv2.circle(image, (int(u), int(v)), 2, LIDAR_BGR, -1, cv2.LINE_AA)
        legend.append((f"Lidar: {int(scan.valid.sum())} returns", LIDAR_BGR))
    outline = view.px(_robot_outline(pose))
    cv2.polylines(image, [outline[:4]], True, ROBOT_BGR, 2, cv2.LINE_AA)
    centre = view.px([(pose.x_m, pose.y_m)])[0]
    cv2.arrowedLine(image, (int(centre[0]), int(centre[1])),
                    (int(outline[4][0]), int(outline[4][1])), ROBOT_BGR, 2, cv2.LINE_AA,
                    tipLength=0.35)
    legend.insert(0, (f"robot at x {pose.x_m:.2f} m, y {pose.y_m:.2f} m, yaw "
                      f"{pose.yaw_deg:.0f} deg", ROBOT_BGR))
    y = 2
    for text, color in ([(title, None)] if title else []) + legend:
        w, h = label_size(text, swatch=color is not None)
        draw_label(image, text, (2, y, 2 + w, y + h), color)
        y += h + 2
    return image
