"""An occupancy grid built from Lidar scans: log-odds per cell, rays traced in numpy.

Cells are ``resolution_m`` squares; cell (row, col) covers x from ``origin.x_m + col *
resolution_m`` and y from ``origin.y_m + row * resolution_m`` (row 0 at the lowest y, as
ROS's ``nav_msgs/OccupancyGrid`` stores it; the map files flip it for the picture). A
scan's beams make the cells they cross more likely free and the cell each one ends in
more likely occupied. A beam with no return clears nothing: the A1 also misses surfaces
it meets at a grazing angle or that are dark, and clearing along such a beam would open
holes in walls (``insert(..., no_return_clears_m=...)`` chooses otherwise, for a hall
larger than the Lidar's range). Probabilities are kept as log-odds, clamped so that a
moved obstacle can be unlearnt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.units import check_range

__all__ = [
    "CLAMP_LOG_ODDS",
    "HIT_LOG_ODDS",
    "MAX_CELLS",
    "MISS_LOG_ODDS",
    "FloatArray",
    "GridSpec",
    "OccupancyGrid",
    "cropped",
]


FloatArray = npt.NDArray[np.float64]

HIT_LOG_ODDS = 0.85
MISS_LOG_ODDS = -0.4
CLAMP_LOG_ODDS = 4.0
MAX_CELLS = 4000 * 4000


@dataclass(frozen=True)
class GridSpec:
    """Where a grid lies: its lower-left corner (origin, m; yaw 0) and cell size."""

    origin_x_m: float
    origin_y_m: float
    resolution_m: float
    width: int
    height: int

    def __post_init__(self) -> None:
        check_range("resolution_m", self.resolution_m, 0.005, 1.0, "m")
        if not (self.width >= 1 and self.height >= 1 and self.width * self.height <= MAX_CELLS):
            raise ConfigError(f"a grid of {self.width} x {self.height} cells; allowed: 1.."
                              f"{MAX_CELLS} cells in all")

    @classmethod
    def covering(cls, x_min_m: float, x_max_m: float, y_min_m: float, y_max_m: float,
                 resolution_m: float = 0.05) -> GridSpec:
        """The grid whose cells cover the rectangle."""
        check_range("resolution_m", resolution_m, 0.005, 1.0, "m")
        width = max(1, math.ceil((x_max_m - x_min_m) / resolution_m))
        height = max(1, math.ceil((y_max_m - y_min_m) / resolution_m))
        return cls(x_min_m, y_min_m, resolution_m, width, height)

    def cells(self, points_m: npt.ArrayLike) -> tuple[npt.NDArray[np.int64],
                                                       npt.NDArray[np.int64]]:
        """(rows, cols) of points (N, 2) in metres; outside the grid they are out of range."""
        p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        cols = np.floor((p[:, 0] - self.origin_x_m) / self.resolution_m).astype(np.int64)
        rows = np.floor((p[:, 1] - self.origin_y_m) / self.resolution_m).astype(np.int64)
        return rows, cols

    def inside(self, rows: npt.NDArray[np.int64], cols: npt.NDArray[np.int64]
               ) -> npt.NDArray[np.bool_]:
        return (rows >= 0) & (rows < self.height) & (cols >= 0) & (cols < self.width)

    def centres(self, rows: npt.ArrayLike, cols: npt.ArrayLike) -> FloatArray:
        """The centres (m) of cells."""
        r = np.asarray(rows, dtype=np.float64)
        c = np.asarray(cols, dtype=np.float64)
        return np.stack([self.origin_x_m + (c + 0.5) * self.resolution_m,
                         self.origin_y_m + (r + 0.5) * self.resolution_m], axis=-1)


class OccupancyGrid:
    """Log-odds occupancy over a ``GridSpec``; 0 is unknown."""

    def __init__(self, spec: GridSpec, log_odds: FloatArray | None = None) -> None:
        self.spec = spec
        shape = (spec.height, spec.width)
        self.log_odds = (np.zeros(shape) if log_odds is None
                         else np.asarray(log_odds, dtype=np.float64))
        if self.log_odds.shape != shape:
            raise ConfigError(f"log-odds of shape {self.log_odds.shape}; the grid is {shape}")

    def __repr__(self) -> str:
        g = self.spec
        return (f"OccupancyGrid({g.width} x {g.height} cells of {g.resolution_m * 100:g} cm, "
                f"{g.width * g.resolution_m:.1f} x {g.height * g.resolution_m:.1f} m from "
                f"({g.origin_x_m:.2f}, {g.origin_y_m:.2f}) m)")

    @property
    def probability(self) -> FloatArray:
        """Each cell's probability of being occupied (0.5: unknown)."""
        out: FloatArray = 1.0 / (1.0 + np.exp(-self.log_odds))
        return out

    def insert(self, sensor: Pose2D, bearings_rad: npt.ArrayLike,
               ranges_m: npt.ArrayLike, no_return_clears_m: float = 0.0,
               max_range_m: float = math.inf) -> None:
        """Fold in one scan taken from ``sensor`` (the Lidar's pose in the grid's frame):
        beam bearings in the Lidar's frame, ranges in m (NaN: no return, which clears
        ``no_return_clears_m``). A return beyond ``max_range_m`` marks nothing there
        (its range too uncertain) but clears its beam up to ``max_range_m``."""
        b = np.asarray(bearings_rad, dtype=np.float64).ravel() + sensor.yaw_rad
        r = np.asarray(ranges_m, dtype=np.float64).ravel()
        if b.shape != r.shape:
            raise ConfigError(f"{len(b)} bearings and {len(r)} ranges: one each per beam")
        found = np.isfinite(r)
        hit = found & (r <= max_range_m)
        # Beyond reach: cleared to max_range_m (the beam's end, a cell more, is left out).
        reach = np.where(hit, r, np.where(found, max_range_m + self.spec.resolution_m,
                                          no_return_clears_m))
        step = self.spec.resolution_m / 2.0
        samples = max(1, math.ceil(float(reach.max(initial=0.0)) / step))
        # Points along every beam up to just short of its end (free), then its end (hit).
        t = np.arange(samples) * step
        along = t[None, :] < (reach[:, None] - self.spec.resolution_m)
        xs = sensor.x_m + t[None, :] * np.cos(b)[:, None]
        ys = sensor.y_m + t[None, :] * np.sin(b)[:, None]
        free = np.stack([xs[along], ys[along]], axis=1)
        ends = np.stack([sensor.x_m + r[hit] * np.cos(b[hit]),
                         sensor.y_m + r[hit] * np.sin(b[hit])], axis=1)
        self._add(free, MISS_LOG_ODDS, exclude=ends)
        self._add(ends, HIT_LOG_ODDS)

    def _add(self, points: FloatArray, amount: float, exclude: FloatArray | None = None) -> None:
        rows, cols = self.spec.cells(points)
        keep = self.spec.inside(rows, cols)
        flat = np.unique(rows[keep] * self.spec.width + cols[keep])  # once per scan
        if exclude is not None and len(exclude):
            er, ec = self.spec.cells(exclude)
            ek = self.spec.inside(er, ec)
            flat = np.setdiff1d(flat, er[ek] * self.spec.width + ec[ek], assume_unique=False)
        view = self.log_odds.reshape(-1)
        view[flat] = np.clip(view[flat] + amount, -CLAMP_LOG_ODDS, CLAMP_LOG_ODDS)


def cropped(grid: OccupancyGrid, margin_m: float = 0.25) -> OccupancyGrid:
    """The part of ``grid`` around its known cells (plus ``margin_m``): what to save."""
    known = np.nonzero(grid.log_odds != 0.0)
    if len(known[0]) == 0:
        return grid
    s = grid.spec
    pad = math.ceil(margin_m / s.resolution_m)
    r0, r1 = max(0, known[0].min() - pad), min(s.height, known[0].max() + pad + 1)
    c0, c1 = max(0, known[1].min() - pad), min(s.width, known[1].max() + pad + 1)
    spec = GridSpec(s.origin_x_m + c0 * s.resolution_m, s.origin_y_m + r0 * s.resolution_m,
                    s.resolution_m, int(c1 - c0), int(r1 - r0))
    return OccupancyGrid(spec, grid.log_odds[r0:r1, c0:c1].copy())
