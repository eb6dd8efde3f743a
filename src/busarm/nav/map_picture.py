"""A map for people: the grid's picture enlarged, its origin's axes, a scale bar, and what
happened on it (paths, named points, Lidar returns, where the base is)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D
from busarm.nav.grid import OccupancyGrid
from busarm.nav.map_files import grid_pixels

__all__ = [
    "AXIS_M",
    "MIN_SIDE_PX",
    "PATH_BGR",
    "PLAN_BGR",
    "POSE_BGR",
    "POSE_RADIUS_M",
    "Point",
    "map_picture",
]


MIN_SIDE_PX = 600
AXIS_M = 0.5
Point = tuple[float, float]
PATH_BGR = (200, 120, 0)
PLAN_BGR = (150, 150, 150)
POSE_BGR = (40, 160, 230)
POSE_RADIUS_M = 0.2
"""The base drawn as a disc this wide (the footprint the planners keep clear)."""


def map_picture(grid: OccupancyGrid, *, path: Sequence[Point] = (),
                plans: Sequence[Sequence[Point]] = (),
                marks: Mapping[str, Point] | None = None,
                returns: Sequence[Point] = (),
                pose: Pose2D | None = None) -> npt.NDArray[np.uint8]:
    """BGR: occupied black, free white, unknown grey (as the PGM), enlarged so that its
    longer side is at least MIN_SIDE_PX; the map origin's x (red) and y (green) axes
    AXIS_M long, and a 1 m scale bar. Optionally: planned paths (grey), the path driven
    (blue), named points (labelled), Lidar returns (orange dots) and the base at ``pose``
    (a disc with its heading); all in metres."""
    pixels = grid_pixels(grid)
    h, w = pixels.shape
    scale = max(1, math.ceil(MIN_SIDE_PX / max(h, w)))
    image = cv2.cvtColor(np.repeat(np.repeat(pixels, scale, 0), scale, 1), cv2.COLOR_GRAY2BGR)
    s = grid.spec
    px_per_m = scale / s.resolution_m

    def px(x_m: float, y_m: float) -> tuple[int, int]:
        return (round((x_m - s.origin_x_m) * px_per_m),
                round(h * scale - (y_m - s.origin_y_m) * px_per_m))

    for (dx, dy), bgr in (((AXIS_M, 0.0), (40, 40, 230)), ((0.0, AXIS_M), (40, 170, 40))):
        cv2.arrowedLine(image, px(0.0, 0.0), px(dx, dy), bgr, 2, cv2.LINE_AA, tipLength=0.2)
    for plan in plans:
        _polyline(image, px, plan, PLAN_BGR, 2)
    _polyline(image, px, path, PATH_BGR, 2)
    for x, y in returns:
        cv2.circle(image, px(x, y), 2, (0, 140, 255), -1, cv2.LINE_AA)
    if pose is not None:
        _base(image, px, pose, round(POSE_RADIUS_M * px_per_m))
    for name, (x, y) in (marks or {}).items():
        cv2.drawMarker(image, px(x, y), (180, 0, 180), cv2.MARKER_TILTED_CROSS, 14, 2)
        cv2.putText(image, name, (px(x, y)[0] + 8, px(x, y)[1] - 8), cv2.FONT_HERSHEY_SIMPLEX,
                    0.5, (180, 0, 180), 1, cv2.LINE_AA)
    bar_y = h * scale - 12
    cv2.line(image, (10, bar_y), (10 + round(px_per_m), bar_y), (200, 80, 0), 3)
    cv2.putText(image, "1 m", (12, bar_y - 6), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (200, 80, 0), 1,
                cv2.LINE_AA)
    return np.asarray(image, dtype=np.uint8)


def _base(image: npt.NDArray[Any], px: Callable[[float, float], tuple[int, int]],
          pose: Pose2D, radius_px: int) -> None:
    centre = px(pose.x_m, pose.y_m)
    ahead = px(pose.x_m + POSE_RADIUS_M * math.cos(pose.yaw_rad),
               pose.y_m + POSE_RADIUS_M * math.sin(pose.yaw_rad))
    cv2.circle(image, centre, max(radius_px, 4), POSE_BGR, 2, cv2.LINE_AA)
    cv2.arrowedLine(image, centre, ahead, POSE_BGR, 2, cv2.LINE_AA, tipLength=0.3)


def _polyline(image: npt.NDArray[Any], px: Callable[[float, float], tuple[int, int]],
              points: Sequence[Point], bgr: tuple[int, int, int], thickness: int) -> None:
    if len(points) >= 2:
        pts = np.array([px(x, y) for x, y in points], dtype=np.int32)
        cv2.polylines(image, [pts], False, bgr, thickness, cv2.LINE_AA)
