"""A small world for the nav tests: an L-shaped room and a Lidar simulator in it.

The room has no symmetry to fool a matcher or a particle filter; walls are segments in
metres. ``scan_from`` casts every beam against every wall at once (numpy), so that tests
driving many scans stay fast.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from busarm.base.odometry import Pose2D
from busarm.nav.grid import GridSpec, OccupancyGrid

Segment = tuple[tuple[float, float], tuple[float, float]]

WALLS: list[Segment] = [
    ((-2.0, -1.5), (2.0, -1.5)), ((2.0, -1.5), (2.0, 0.5)), ((2.0, 0.5), (0.5, 0.5)),
    ((0.5, 0.5), (0.5, 1.5)), ((0.5, 1.5), (-2.0, 1.5)), ((-2.0, 1.5), (-2.0, -1.5)),
    ((-1.0, -0.3), (-0.6, -0.3)), ((-0.6, -0.3), (-0.6, 0.1))]
BEARINGS = np.linspace(0, 2 * math.pi, 200, endpoint=False)
MIN_RANGE_M = 0.05


def box(x_m: float, y_m: float, half_m: float) -> list[Segment]:
    """The four sides of a square box centred at (x_m, y_m)."""
    c = [(x_m - half_m, y_m - half_m), (x_m + half_m, y_m - half_m),
         (x_m + half_m, y_m + half_m), (x_m - half_m, y_m + half_m)]
    return [(c[i], c[(i + 1) % 4]) for i in range(4)]


def scan_from(sensor: Pose2D, walls: Sequence[Segment] = WALLS,
              bearings: np.ndarray = BEARINGS) -> np.ndarray:
    """Ranges of ``bearings`` from ``sensor`` to the nearest wall (NaN: no wall on the beam)."""
    b = np.asarray(bearings, dtype=np.float64) + sensor.yaw_rad
    d = np.stack([np.cos(b), np.sin(b)], axis=1)[:, None, :]  # (B, 1, 2)
    seg = np.asarray(walls, dtype=np.float64)  # (W, 2, 2)
    a, e = seg[:, 0, :], seg[:, 1, :] - seg[:, 0, :]
    w = a - np.array([sensor.x_m, sensor.y_m])
    # Solve sensor + t d = a + u e for every beam and wall (Cramer's rule).
    den = d[..., 1] * e[:, 0] - d[..., 0] * e[:, 1]  # (B, W)
    ok = np.abs(den) > 1e-12
    safe = np.where(ok, den, 1.0)
    t = (w[:, 1] * e[:, 0] - w[:, 0] * e[:, 1]) / safe
    u = (d[..., 0] * w[:, 1] - d[..., 1] * w[:, 0]) / safe
    hit = ok & (t > MIN_RANGE_M) & (u >= 0) & (u <= 1)
    nearest = np.where(hit, t, np.inf).min(axis=1)
    return np.where(np.isfinite(nearest), nearest, np.nan)


def mapped(*sensors: Pose2D, spec: GridSpec | None = None, times: int = 3) -> OccupancyGrid:
    """The room mapped from scans taken at ``sensors``, each folded in ``times`` times
    (by default on 2.5 cm cells whose edges lie on the walls)."""
    grid = OccupancyGrid(spec or GridSpec.covering(-2.5, 2.5, -2.0, 2.0, 0.025))
    for sensor in sensors:
        for _ in range(times):
            grid.insert(sensor, BEARINGS, scan_from(sensor))
    return grid
