"""The Lidar's scans with the odometry's pose at each scan's middle.

A revolution takes about 0.1 s; a base moving at 0.25 m/s covers 2.5 cm meanwhile and one
turning at 1 rad/s turns 6 degrees: each beam is measured from a different pose. Every
scan is placed at the middle of its revolution (the odometry's poses when it began and
ended, by the scan's own times: ``Base.pose_at``) and each beam is moved to where it
would have been measured from there (de-skewed: the beam's time within the revolution
follows from its angle, the A1 turning clockwise at a steady rate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.base.base import Base
from busarm.base.config import Mount
from busarm.base.odometry import Pose2D
from busarm.errors import BusTimeoutError, ConfigError, NavigationError
from busarm.lidar.scan import LaserScan, LidarSource
from busarm.nav.mapping import compose, inverse
from busarm.robot import Robot

__all__ = [
    "CAUGHT_UP_S",
    "MAX_SKIPPED",
    "PAUSE_S",
    "SCAN_TIMEOUT_S",
    "FloatArray",
    "ScanReader",
    "SensedScan",
    "deskewed",
]


FloatArray = npt.NDArray[np.float64]

SCAN_TIMEOUT_S = 1.0
"""A Lidar that sends no full revolution for this long is taken as lost (the A1 sends 10
a second)."""
PAUSE_S = 0.3
"""Nobody read scans for this long: the ones queued meanwhile are old, and skipped."""
CAUGHT_UP_S = 0.02
"""A read that had to wait at least this long for its revolution is a fresh one."""
MAX_SKIPPED = 100


@dataclass(frozen=True)
class SensedScan:
    scan: LaserScan
    odometry: Pose2D
    """The base's odometry pose at the middle of the revolution."""
    odometry_now: Pose2D
    """The odometry's pose when the scan was read (its end)."""
    at_s: float
    bearings_rad: FloatArray
    """The beams' bearings de-skewed to the Lidar's pose at ``odometry`` (its frame)."""
    ranges_m: FloatArray
    """Their ranges from there (NaN: no return)."""


def deskewed(scan: LaserScan, start: Pose2D, end: Pose2D, mount: Mount
             ) -> tuple[FloatArray, FloatArray]:
    """Each beam as if measured from the Lidar at the middle of the revolution, the base
    moving from ``start`` to ``end`` (odometry poses) over it: (bearings, ranges)."""
    angles = np.asarray(scan.angles_rad, dtype=np.float64)
    ranges = np.asarray(scan.ranges_m, dtype=np.float64)
    # The A1 turns clockwise: its bearings fall with time from the revolution's start.
    fraction = np.mod(-angles, 2 * math.pi) / (2 * math.pi)
    mid = start.interpolated(end, 0.5)
    sensor = Pose2D(mount.x_m, mount.y_m, mount.yaw_rad)
    rel = compose(inverse(compose(mid, sensor)), compose(start, sensor))
    moved = compose(inverse(compose(start, sensor)), compose(end, sensor))
    # The sensor's pose at each beam, in the mid-revolution sensor frame (linear in time).
    yaw = rel.yaw_rad + fraction * moved.yaw_rad
    c0, s0 = math.cos(rel.yaw_rad), math.sin(rel.yaw_rad)
    px = rel.x_m + fraction * (c0 * moved.x_m - s0 * moved.y_m)
    py = rel.y_m + fraction * (s0 * moved.x_m + c0 * moved.y_m)
    x = px + ranges * np.cos(angles + yaw)
    y = py + ranges * np.sin(angles + yaw)
    out_ranges = np.where(np.isfinite(ranges), np.hypot(x, y), np.nan)
    out_bearings = np.where(np.isfinite(ranges), np.arctan2(y, x), angles + yaw)
    return out_bearings, out_ranges


class ScanReader:
    """Reads ``robot``'s Lidar scan after scan, each with its odometry pose."""

    def __init__(self, robot: Robot, timeout_s: float = SCAN_TIMEOUT_S) -> None:
        if robot.base is None or robot.lidar is None:
            missing = " and no ".join(n for n, p in (("base", robot.base),
                                                     ("Lidar", robot.lidar)) if p is None)
            raise ConfigError(f"{robot!r} has no {missing}: a mobile job needs both "
                              "(board://twin?family=arena&seed=N, or --chassis and --lidar)")
        self.base: Base = robot.base
        self.lidar: LidarSource = robot.lidar
        self.clock = robot.clock
        self.timeout_s = timeout_s
        self._last = self.base.odometry().pose
        self._read_at_s = -float("inf")
        self.scans = 0
        self.skipped = 0

    def read(self) -> SensedScan:
        """The next scan; a NavigationError (the wheels stopped) if the Lidar is silent.
        After a pause (an arm move, a ``move_by``), the revolutions queued meanwhile are
        skipped: the scan returned is one that ended after this call."""
        if self.clock.now() - self._read_at_s > PAUSE_S:
            self._catch_up()
        scan = self._read_one()
        now = self.base.odometry().pose
        start, end = self._span(scan)
        bearings, ranges = deskewed(scan, start, end, self.base.config.lidar)
        sensed = SensedScan(scan, start.interpolated(end, 0.5), now, self.clock.now(),
                            bearings, ranges)
        self._last = now
        self._read_at_s = self.clock.now()
        self.scans += 1
        return sensed

    def _span(self, scan: LaserScan) -> tuple[Pose2D, Pose2D]:
        """The odometry's poses when the revolution began and ended (by the scan's own
        times, when it has them; else when the last scan and this one were read)."""
        if not math.isfinite(scan.scan_time_s):
            return self._last, self.base.odometry().pose
        return (self.base.pose_at(scan.stamp_s),
                self.base.pose_at(scan.stamp_s + scan.scan_time_s))

    def _read_one(self) -> LaserScan:
        try:
            return self.lidar.read_scan(self.timeout_s)
        except BusTimeoutError as exc:
            self.base.stop()
            raise NavigationError(f"the Lidar sent no scan for {self.timeout_s:g} s ({exc}):"
                                  " the base is stopped") from exc

    def _catch_up(self) -> None:
        for _ in range(MAX_SKIPPED):
            started = self.clock.now()
            self._read_one()
            if self.clock.now() - started >= CAUGHT_UP_S:
                break  # that one had to be waited for: the queue is empty
            self.skipped += 1
        self._last = self.base.odometry().pose
