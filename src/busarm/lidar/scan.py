"""One 360-degree Lidar scan, the interface of every Lidar source, and scan geometry.

Conventions (REP-103, as ROS's LaserScan): angles are counter-clockwise from the Lidar's
forward axis, viewed from above, in rad; a scan's angles ascend in [0, 2 pi). A beam
with no valid return (none reported, or outside ``range_min_m..range_max_m``) has range
NaN (never inf: "nothing seen" and "too far" are not told apart by the A1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.base.config import Mount

__all__ = [
    "FloatArray",
    "LaserScan",
    "LidarSource",
    "at_returns",
    "to_points",
]


FloatArray = npt.NDArray[np.float64]


def _frozen(name: str, values: object) -> FloatArray:
    array = np.array(values, dtype=np.float64)
    if array.ndim != 1:
        raise ConfigError(f"LaserScan {name} must be one-dimensional, got shape {array.shape}")
    array.flags.writeable = False
    return array


@dataclass(frozen=True, eq=False)
class LaserScan:
    """One revolution: per beam its bearing, range (NaN: no return) and intensity."""

    angles_rad: FloatArray
    ranges_m: FloatArray
    intensities: FloatArray
    """The source's own scale (the A1's quality, 0..63); 0 where there is no return."""
    stamp_s: float
    """When the revolution began, on the source's clock."""
    range_min_m: float
    range_max_m: float
    scan_time_s: float = math.nan
    """How long the revolution took (NaN when unknown)."""

    def __post_init__(self) -> None:
        for name in ("angles_rad", "ranges_m", "intensities"):
            object.__setattr__(self, name, _frozen(name, getattr(self, name)))
        sizes = {len(self.angles_rad), len(self.ranges_m), len(self.intensities)}
        if len(sizes) != 1:
            raise ConfigError(f"LaserScan arrays differ in length: angles "
                              f"{len(self.angles_rad)}, ranges {len(self.ranges_m)}, "
                              f"intensities {len(self.intensities)}")
        if not 0 <= self.range_min_m < self.range_max_m:
            raise ConfigError(f"LaserScan range_min_m {self.range_min_m:g} and range_max_m "
                              f"{self.range_max_m:g}: need 0 <= min < max")
        if np.any(self.ranges_m <= 0):
            raise ConfigError("LaserScan ranges must be > 0 or NaN (no return)")

    def __len__(self) -> int:
        return len(self.angles_rad)

    def __repr__(self) -> str:
        rate = "" if math.isnan(self.rate_hz) else f", {self.rate_hz:.1f} Hz"
        return (f"LaserScan({len(self)} beams, {int(self.valid.sum())} returns, "
                f"{self.range_min_m:g}..{self.range_max_m:g} m, at {self.stamp_s:.3f} s{rate})")

    @property
    def valid(self) -> npt.NDArray[np.bool_]:
        """Which beams have a return."""
        return np.isfinite(self.ranges_m)

    @property
    def rate_hz(self) -> float:
        """Revolutions a second (NaN when the scan time is unknown)."""
        return 1.0 / self.scan_time_s if self.scan_time_s > 0 else math.nan

    def nearest(self) -> tuple[float, float] | None:
        """The nearest return as (range m, bearing rad in -pi..pi), or None if none."""
        valid = self.valid
        if not valid.any():
            return None
        i = int(np.nanargmin(np.where(valid, self.ranges_m, np.inf)))
        bearing = math.remainder(float(self.angles_rad[i]), 2 * math.pi)
        return float(self.ranges_m[i]), bearing


def to_points(scan: LaserScan, mount: Mount) -> FloatArray:
    """The scan's returns as base-frame x, y points (m), shape (N, 2), for a Lidar
    mounted at ``mount`` (its x_m, y_m and yaw_rad on the base; z is ignored). Beams
    without a return give no point."""
    valid = scan.valid
    bearing = scan.angles_rad[valid] + mount.yaw_rad
    ranges = scan.ranges_m[valid]
    points = np.empty((len(ranges), 2), dtype=np.float64)
    points[:, 0] = mount.x_m + ranges * np.cos(bearing)
    points[:, 1] = mount.y_m + ranges * np.sin(bearing)
    return points


def at_returns(points_base_m: npt.ArrayLike, scan: LaserScan, mount: Mount, *,
               within_m: float = 0.03, beam_rad: float = math.radians(2.0)
               ) -> npt.NDArray[np.bool_]:
    """Which base-frame points lie at or behind what the Lidar sees on their bearing:
    farther from it than the return of the beam within ``beam_rad`` of them, less
    ``within_m`` (floor a camera "sees" there is a wall's foot or face)."""
    p = np.asarray(points_base_m, dtype=np.float64).reshape(-1, 2)
    valid = scan.valid
    if not len(p) or not np.any(valid):
        return np.zeros(len(p), dtype=bool)
    dx, dy = p[:, 0] - mount.x_m, p[:, 1] - mount.y_m
    bearing = np.arctan2(dy, dx) - mount.yaw_rad
    off = np.abs(np.angle(np.exp(1j * (bearing[:, None] - scan.angles_rad[valid][None, :]))))
    k = np.argmin(off, axis=1)
    ranges = scan.ranges_m[valid][k]
    return np.asarray((off[np.arange(len(p)), k] <= beam_rad)
                      & (np.hypot(dx, dy) > ranges - within_m))


@runtime_checkable
class LidarSource(Protocol):
    """Anything that delivers scans: the A1 driver, the twin's ray-cast Lidar (by model:
    busarm.lidar.sources)."""

    def read_scan(self, timeout_s: float) -> LaserScan:
        """The next complete revolution; BusTimeoutError if none comes in ``timeout_s``."""
        ...

    def close(self) -> None:
        """Stop the Lidar and release its port."""
        ...
