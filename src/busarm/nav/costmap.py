"""Where the base may go: an occupancy grid turned into free cells and travel costs.

The base is a disc of ``robot_radius_m`` about its centre. A grid cell is an obstacle
unless the map says it is free (occupied and unknown cells alike: nothing unseen is
driven into); beyond the grid is unknown too. A cell is **free** when the disc fits with
its centre anywhere in the cell: every point of the cell is at least ``robot_radius_m``
from every obstacle cell (square to square, exactly). So a path that stays in free cells
(their closures: a diagonal step through a shared corner too) keeps the disc off every
obstacle, wherever within a cell the base really is. Free cells also carry a cost that
falls from ``INFLATION_COST`` at the robot's radius to 0 at ``inflation_m`` beyond it, so
that paths keep away from walls where there is room.
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.map_files import FREE_THRESH
from busarm.units import check_range

__all__ = [
    "INFLATION_COST",
    "INFLATION_M",
    "ROBOT_RADIUS_M",
    "BoolArray",
    "Costmap",
    "FloatArray",
    "footprint_kernel",
]


FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

INFLATION_COST = 3.0
"""The extra cost per metre (a multiple of the distance) of a free cell right at the
robot's radius from an obstacle; a path there costs 1 + this per metre travelled."""
ROBOT_RADIUS_M = (0.01, 2.0)
INFLATION_M = (0.0, 5.0)


class Costmap:
    """Lethal where occupied or unknown, inscribed within robot_radius of it, a cost
    decaying beyond up to inflation_m (see the module's description)."""

    def __init__(self, spec: GridSpec, obstacle: BoolArray, robot_radius_m: float,
                 inflation_m: float = 0.3) -> None:
        self.spec = spec
        self.robot_radius_m = check_range("robot_radius_m", robot_radius_m, *ROBOT_RADIUS_M,
                                          "m")
        self.inflation_m = check_range("inflation_m", inflation_m, *INFLATION_M, "m")
        self.obstacle = np.asarray(obstacle, dtype=bool)
        if self.obstacle.shape != (spec.height, spec.width):
            raise ConfigError(f"an obstacle mask of shape {self.obstacle.shape}; the grid is "
                              f"{(spec.height, spec.width)}")
        self.free = _free_cells(self.obstacle, spec.resolution_m, self.robot_radius_m)
        """Cells in which the robot's disc fits wherever its centre is."""
        self.cost = self._inflation_cost()
        """Per free cell: the extra cost per metre travelled through it (inf elsewhere)."""

    @classmethod
    def from_grid(cls, grid: OccupancyGrid, robot_radius_m: float, inflation_m: float = 0.3,
                  free_below_p: float = FREE_THRESH) -> Costmap:
        """The costmap of a map: cells with an occupancy probability at most
        ``free_below_p`` (map_server's free threshold by default) are open floor."""
        check_range("free_below_p", free_below_p, 0.0, 0.5)
        return cls(grid.spec, ~(grid.probability <= free_below_p), robot_radius_m,
                   inflation_m)

    def with_obstacles(self, points_m: npt.ArrayLike) -> Costmap:
        """A new costmap with these points (shape (N, 2), map frame: live Lidar returns)
        marked as obstacles too; points beyond the grid are outside it already (unknown).
        This costmap is left as it is: call it on the static map's costmap each scan."""
        rows, cols = self.spec.cells(points_m)
        inside = self.spec.inside(rows, cols)
        obstacle = self.obstacle.copy()
        obstacle[rows[inside], cols[inside]] = True
        return Costmap(self.spec, obstacle, self.robot_radius_m, self.inflation_m)

    def clearance_m(self, x_m: float, y_m: float) -> float:
        """The distance (m) from the point to the nearest obstacle: an obstacle cell's
        square, or the grid's edge (beyond it is unknown); 0 inside either."""
        s = self.spec
        edge_m = min(x_m - s.origin_x_m, s.origin_x_m + s.width * s.resolution_m - x_m,
                     y_m - s.origin_y_m, s.origin_y_m + s.height * s.resolution_m - y_m)
        if edge_m <= 0.0 or self._obstacle_centres.shape[0] == 0:
            return max(edge_m, 0.0)
        tree = self._tree
        nearest_m, _ = tree.query((x_m, y_m))
        half = s.resolution_m / 2.0
        # The nearest square need not have the nearest centre: any within half a diagonal.
        near = self._obstacle_centres[tree.query_ball_point(
            (x_m, y_m), float(nearest_m) + half * math.sqrt(2.0) + 1e-12)]
        gap = np.maximum(np.abs(near - np.array([x_m, y_m])) - half, 0.0)
        return min(float(np.hypot(gap[:, 0], gap[:, 1]).min()), edge_m)

    def is_free(self, x_m: float, y_m: float) -> bool:
        """Whether the robot's disc fits with its centre at this point."""
        return self.clearance_m(x_m, y_m) >= self.robot_radius_m

    def nearest_free(self, x_m: float, y_m: float, max_m: float = 0.5
                     ) -> tuple[float, float] | None:
        """The point itself if its cell is free (a goal the planner takes), else the centre
        of the nearest free cell within ``max_m``; None if there is none."""
        check_range("max_m", max_m, 0.0, 100.0, "m")
        s = self.spec
        rows, cols = s.cells([(x_m, y_m)])
        if s.inside(rows, cols)[0] and self.free[rows[0], cols[0]]:
            return (x_m, y_m)
        free_rows, free_cols = np.nonzero(self.free)
        if len(free_rows) == 0:
            return None
        centres = s.centres(free_rows, free_cols)
        distance_m = np.hypot(centres[:, 0] - x_m, centres[:, 1] - y_m)
        best = int(np.argmin(distance_m))
        if distance_m[best] > max_m:
            return None
        return (float(centres[best, 0]), float(centres[best, 1]))

    def reachable(self, x_m: float, y_m: float) -> BoolArray:
        """The free cells connected to the point's (8-connected, as the planner moves; its
        nearest free cell within a robot radius where the point's own is not free): where
        the base can drive from there. All False if there is no such cell."""
        from scipy import ndimage

        start = self.nearest_free(x_m, y_m, self.robot_radius_m)
        if start is None:
            return np.zeros_like(self.free)
        labels, _ = ndimage.label(self.free, structure=np.ones((3, 3), dtype=bool))
        rows, cols = self.spec.cells([start])
        out: BoolArray = labels == labels[rows[0], cols[0]]
        return out

    def cell_free(self, x_m: float, y_m: float) -> bool:
        """Whether the point's cell is free (the planner's test for a start or a goal)."""
        rows, cols = self.spec.cells([(x_m, y_m)])
        return bool(self.spec.inside(rows, cols)[0] and self.free[rows[0], cols[0]])

    @cached_property
    def _obstacle_centres(self) -> FloatArray:
        rows, cols = np.nonzero(self.obstacle)
        return self.spec.centres(rows, cols).reshape(-1, 2)

    @cached_property
    def _tree(self) -> Any:
        from scipy.spatial import cKDTree

        return cKDTree(self._obstacle_centres)

    def _inflation_cost(self) -> FloatArray:
        from scipy import ndimage

        res = self.spec.resolution_m
        pad = 1
        # Distance from each cell's centre to the nearest obstacle cell's centre (beyond
        # the grid counts as obstacle), less a cell: near enough the square-to-square gap.
        open_floor = np.pad(~self.obstacle, pad, constant_values=False)
        centre_m = np.asarray(ndimage.distance_transform_edt(open_floor),
                              dtype=np.float64)[pad:-pad, pad:-pad] * res
        gap_m = np.maximum(centre_m - res, 0.0)
        if self.inflation_m > 0.0:
            share = np.clip(1.0 - (gap_m - self.robot_radius_m) / self.inflation_m, 0.0, 1.0)
        else:
            share = np.zeros_like(gap_m)
        return np.where(self.free, INFLATION_COST * share, np.inf)


def footprint_kernel(resolution_m: float, robot_radius_m: float) -> npt.NDArray[np.uint8]:
    """Offsets (rows, cols about the centre) of the cells whose square comes nearer than
    ``robot_radius_m`` to the centre cell's square."""
    n = math.ceil(robot_radius_m / resolution_m) + 1
    steps = np.arange(-n, n + 1)
    gap = np.maximum(np.abs(steps) - 1, 0).astype(np.float64)
    gap_cells_sq = gap[:, None] ** 2 + gap[None, :] ** 2
    # Touching (a gap of exactly the radius) is allowed: a hair of slack for rounding.
    limit_sq = (robot_radius_m / resolution_m) ** 2 * (1.0 - 1e-9)
    kernel: npt.NDArray[np.uint8] = (gap_cells_sq < limit_sq).astype(np.uint8)
    return kernel


def _free_cells(obstacle: BoolArray, resolution_m: float, robot_radius_m: float) -> BoolArray:
    import cv2

    kernel = footprint_kernel(resolution_m, robot_radius_m)
    n = kernel.shape[0] // 2
    padded = np.pad(obstacle, n, constant_values=True).astype(np.uint8)  # beyond: unknown
    near = cv2.dilate(padded, kernel, borderType=cv2.BORDER_CONSTANT, borderValue=1)
    out: BoolArray = near[n:-n, n:-n] == 0
    return out
