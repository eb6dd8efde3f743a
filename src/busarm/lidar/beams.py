"""A revolution at evenly spaced bearings, as ROS's and Foxglove's laser scans have it.

The A1 gives about 400 returns a turn at uneven bearings; a LaserScan message has one
range per step of a fixed increment. Each return goes to its nearest step, the nearest
return kept; a step no return fell into is +inf (REP 117's "nothing seen").
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from busarm.lidar.scan import LaserScan

__all__ = [
    "SCAN_BEAMS",
    "even_beams",
]


SCAN_BEAMS = 360
"""One beam a degree, from -180 deg."""

FloatArray = npt.NDArray[np.float32]


def even_beams(scan: LaserScan, beams: int = SCAN_BEAMS) -> tuple[FloatArray, FloatArray]:
    """(ranges m, intensities) at ``beams`` bearings from -pi, ``2 pi / beams`` apart."""
    increment = 2 * math.pi / beams
    ranges = np.full(beams, np.inf, dtype=np.float32)
    intensities = np.zeros(beams, dtype=np.float32)
    seen = np.isfinite(scan.ranges_m)
    bins = np.round(np.mod(scan.angles_rad[seen] + math.pi, 2 * math.pi) / increment)
    bins = bins.astype(int) % beams
    for b, r, i in zip(bins, scan.ranges_m[seen], scan.intensities[seen], strict=True):
        if r < ranges[b]:
            ranges[b], intensities[b] = r, i
    return ranges, intensities
