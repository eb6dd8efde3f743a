"""Frontiers: where the known free floor meets the unknown (where to look next).

A frontier cell is a free cell with an unknown neighbour (4-connected); touching frontier
cells (8-connected) make one frontier. Exploring drives to frontiers until none is left
that is long enough to matter (Yamauchi's frontier-based exploration).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.nav.grid import OccupancyGrid
from busarm.units import check_range

__all__ = [
    "FREE_LOG_ODDS",
    "GAP_CELLS",
    "MIN_FRONTIER_M",
    "PLAN_GAP_CELLS",
    "SEEN_FREE_P",
    "FloatArray",
    "Frontier",
    "find_frontiers",
    "gaps_filled",
    "known_free",
    "unknown",
]


FloatArray = npt.NDArray[np.float64]
FREE_LOG_ODDS = -0.2
"""A cell below this is free (one beam through it puts it at -0.4)."""
MIN_FRONTIER_M = 0.25
GAP_CELLS = 2
SEEN_FREE_P = 0.45
"""A map made now (not read from a file): a cell a beam crossed and none ended in is
floor to plan over (``Costmap.from_grid``'s ``free_below_p``), as it was to the explorer
that stopped there; a saved map asks more of it (map_server's free threshold)."""
PLAN_GAP_CELLS = 6
"""Planning, unseen gaps up to this many cells wide between free cells are floor: a few
metres off, the A1's beams (1.8 deg apart) leave gaps wider than a frontier's closing
(which would make them walls on the costmap, cutting a big room in two), and a path
across them is watched by every scan's guard anyway."""


@dataclass(frozen=True)
class Frontier:
    x_m: float
    y_m: float
    """The frontier's centroid (it may lie in the unknown: go to a free point near it)."""
    length_m: float
    """How much boundary it is: its cells times the cell size."""
    points_m: FloatArray
    """Its cells' centres, (N, 2)."""


def known_free(grid: OccupancyGrid) -> npt.NDArray[np.bool_]:
    return np.asarray(grid.log_odds < FREE_LOG_ODDS)


def unknown(grid: OccupancyGrid) -> npt.NDArray[np.bool_]:
    return np.asarray(grid.log_odds == 0.0)


def gaps_filled(grid: OccupancyGrid, gap_cells: int = GAP_CELLS) -> OccupancyGrid:
    """The grid with unknown gaps between free cells up to ``gap_cells`` wide taken as
    free: far from the Lidar its beams fan out wider than a cell, leaving unseen cells
    between them that are no frontier and no obstacle (a morphological closing of the
    free floor)."""
    import cv2

    free = known_free(grid).astype(np.uint8)
    size = 2 * gap_cells + 1
    closed = cv2.morphologyEx(free, cv2.MORPH_CLOSE, np.ones((size, size), np.uint8)) > 0
    log_odds = grid.log_odds.copy()
    log_odds[closed & unknown(grid)] = 2 * FREE_LOG_ODDS
    return OccupancyGrid(grid.spec, log_odds)


def find_frontiers(grid: OccupancyGrid, min_length_m: float = MIN_FRONTIER_M) -> list[Frontier]:
    """The grid's frontiers at least ``min_length_m`` long, longest first (narrow gaps
    between beams closed first: ``gaps_filled``)."""
    import cv2

    check_range("min_length_m", min_length_m, 0.0, 100.0, "m")
    grid = gaps_filled(grid)
    free, unseen = known_free(grid), unknown(grid)
    near_unknown = np.zeros_like(unseen)
    near_unknown[1:, :] |= unseen[:-1, :]
    near_unknown[:-1, :] |= unseen[1:, :]
    near_unknown[:, 1:] |= unseen[:, :-1]
    near_unknown[:, :-1] |= unseen[:, 1:]
    edge = (free & near_unknown).astype(np.uint8)
    count, labels = cv2.connectedComponents(edge, connectivity=8)
    res = grid.spec.resolution_m
    out = []
    for label in range(1, count):
        rows, cols = np.nonzero(labels == label)
        if len(rows) * res < min_length_m:
            continue
        points = grid.spec.centres(rows, cols)
        cx, cy = points.mean(axis=0)
        out.append(Frontier(float(cx), float(cy), len(rows) * res, points))
    return sorted(out, key=lambda f: -f.length_m)
