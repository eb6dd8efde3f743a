"""A map for people: the grid's picture enlarged, its origin's axes, a scale bar, and what
happened on it (paths, named points, Lidar returns, where the base is)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
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
    "PictureFrame",
    "Point",
    "map_picture",
    "picture_frame",
]


MIN_SIDE_PX = 600
AXIS_M = 0.5
Point = tuple[float, float]
PATH_BGR = (200, 120, 0)
PLAN_BGR = (150, 150, 150)
POSE_BGR = (40, 160, 230)
POSE_RADIUS_M = 0.2
"""The base drawn as a disc this wide (the footprint the planners keep clear)."""


@dataclass(frozen=True)
class PictureFrame:
    """Where the map's metres fall on its picture: pixel (0, 0) is the top-left corner;
    ``(x_m - origin_x_m) * px_per_m`` across and ``height_px - (y_m - origin_y_m) *
    px_per_m`` down."""

    origin_x_m: float
    origin_y_m: float
    px_per_m: float
    width_px: int
    height_px: int

    def pixel(self, x_m: float, y_m: float) -> tuple[int, int]:
        return (round((x_m - self.origin_x_m) * self.px_per_m),
                round(self.height_px - (y_m - self.origin_y_m) * self.px_per_m))

    def metres(self, u_px: float, v_px: float) -> tuple[float, float]:
        """The map's point at picture pixel (u across, v down)."""
        return (self.origin_x_m + u_px / self.px_per_m,
                self.origin_y_m + (self.height_px - v_px) / self.px_per_m)


def picture_frame(grid: OccupancyGrid) -> PictureFrame:
    """The frame of ``map_picture(grid)``: enlarged by a whole factor so that its longer
    side is at least MIN_SIDE_PX."""
    h, w = grid.spec.height, grid.spec.width
    scale = max(1, math.ceil(MIN_SIDE_PX / max(h, w)))
    s = grid.spec
    return PictureFrame(s.origin_x_m, s.origin_y_m, scale / s.resolution_m, w * scale, h * scale)


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
    frame = picture_frame(grid)
    scale = frame.width_px // pixels.shape[1]
    image = cv2.cvtColor(np.repeat(np.repeat(pixels, scale, 0), scale, 1), cv2.COLOR_GRAY2BGR)
    px_per_m, px = frame.px_per_m, frame.pixel

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
    bar_y = frame.height_px - 12
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
