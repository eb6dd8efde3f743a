"""Building a map while driving: each scan placed where it fits what is mapped so far.

``MapBuilder.add(bearings, ranges, odometry)`` predicts the base's pose from the last
corrected pose and the odometry's motion since the last scan, corrects it by matching the
scan against the map (busarm.nav.scan_match), and folds the scan in at the corrected
pose: the odometry's drift stops at the map. A match that fits too few returns (a scan
of an unmapped place) is not trusted: the prediction stands.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from busarm.base.config import Mount
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.nav.grid import GridSpec, OccupancyGrid, cropped
from busarm.nav.scan_match import LikelihoodField, match_scan

__all__ = [
    "FIELD_MARGIN_M",
    "INSERT_MOVED_M",
    "INSERT_TURNED_RAD",
    "MAP_RANGE_M",
    "MATCH_SIGMA_M",
    "MIN_MATCHED_SHARE",
    "ODOMETRY_SIGMA_M",
    "MapBuilder",
    "compose",
    "inverse",
    "transform_points",
]


MIN_MATCHED_SHARE = 0.5
MAP_RANGE_M = 5.0
"""A wall is mapped only from within this range: the A1's noise grows with range (about
2 cm at 5 m, 3.5 cm at 8 m), so a far wall would be drawn thick; exploring goes nearer."""
ODOMETRY_SIGMA_M = 0.05
"""How far off the odometry's step between two scans may be (wheel slip included): the
match's prior, so that along a corridor whose ends are out of reach the map does not
pull the robot back to where it was."""
"""A correction is taken only if at least this share of the returns lands on the map."""
FIELD_MARGIN_M = 0.5
MATCH_SIGMA_M = 0.025
"""The matching field's spread: narrow, so that its peak is sharp (a scan's yaw wobbled by
half a degree with 5 cm)."""
INSERT_MOVED_M = 0.05
INSERT_TURNED_RAD = math.radians(2.0)
"""A scan is folded into the map only when the base has moved or turned this much since
the last one that was (each fold of a slightly misplaced scan blurs the map a little;
standing still adds nothing new). Every scan still corrects the pose."""


def compose(a: Pose2D, b: Pose2D) -> Pose2D:
    """``b`` (given in ``a``'s frame) in the frame ``a`` is given in."""
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return Pose2D(a.x_m + c * b.x_m - s * b.y_m, a.y_m + s * b.x_m + c * b.y_m,
                  wrap_rad(a.yaw_rad + b.yaw_rad))


def inverse(a: Pose2D) -> Pose2D:
    c, s = math.cos(a.yaw_rad), math.sin(a.yaw_rad)
    return Pose2D(-(c * a.x_m + s * a.y_m), s * a.x_m - c * a.y_m, wrap_rad(-a.yaw_rad))


def transform_points(pose: Pose2D, points_xy: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Points (x, y rows, m) given in ``pose``'s frame, in the frame ``pose`` is given in
    (rotated by its yaw, then moved to its x, y): e.g. a scan's points in the base frame
    to the map frame, at the base's pose on the map. An (n, 2) array."""
    p = np.asarray(points_xy, dtype=np.float64).reshape(-1, 2)
    c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
    return np.column_stack([pose.x_m + c * p[:, 0] - s * p[:, 1],
                            pose.y_m + s * p[:, 0] + c * p[:, 1]])


@dataclass
class MapBuilder:
    """A map grown scan by scan; poses in the map's frame (where the base started, unless
    ``start`` says where that is)."""

    spec: GridSpec
    lidar: Mount
    start: Pose2D = field(default_factory=Pose2D)
    min_matched_share: float = MIN_MATCHED_SHARE
    max_range_m: float = MAP_RANGE_M
    """Returns farther than this mark no wall (they clear the floor up to it)."""

    def __post_init__(self) -> None:
        self.grid = OccupancyGrid(self.spec)
        self.poses: list[Pose2D] = []
        """The base's corrected pose at each scan."""
        self.corrections = 0
        self._last_odometry: Pose2D | None = None
        self._inserted: Pose2D | None = None

    @property
    def mount(self) -> Pose2D:
        return Pose2D(self.lidar.x_m, self.lidar.y_m, self.lidar.yaw_rad)

    def add(self, bearings_rad: npt.ArrayLike, ranges_m: npt.ArrayLike,
            odometry: Pose2D) -> Pose2D:
        """Fold in one scan taken where the odometry says ``odometry``; returns the base's
        corrected pose (map frame)."""
        if self._last_odometry is None:
            self._last_odometry = odometry
            base = compose(self.start, odometry)
        else:
            moved = compose(inverse(self._last_odometry), odometry)
            self._last_odometry = odometry
            predicted = compose(self.poses[-1], moved)
            base = self._corrected(predicted, bearings_rad, ranges_m)
        if self._inserted is None or _moved(self._inserted, base):
            self.grid.insert(compose(base, self.mount), bearings_rad, ranges_m,
                             max_range_m=self.max_range_m)
            self._inserted = base
        self.poses.append(base)
        return base

    def _corrected(self, predicted: Pose2D, bearings_rad: npt.ArrayLike,
                   ranges_m: npt.ArrayLike) -> Pose2D:
        sensor = compose(predicted, self.mount)
        # The field of what is mapped so far only (the canvas is mostly unknown).
        field = LikelihoodField(cropped(self.grid, FIELD_MARGIN_M), sigma_m=MATCH_SIGMA_M)
        found = match_scan(field, bearings_rad, ranges_m, sensor,
                           prior_sigma_m=ODOMETRY_SIGMA_M)
        if found.matched_share < self.min_matched_share:
            return predicted
        self.corrections += 1
        return compose(found.pose, inverse(self.mount))


def _moved(a: Pose2D, b: Pose2D) -> bool:
    return (math.hypot(b.x_m - a.x_m, b.y_m - a.y_m) >= INSERT_MOVED_M
            or abs(wrap_rad(b.yaw_rad - a.yaw_rad)) >= INSERT_TURNED_RAD)
