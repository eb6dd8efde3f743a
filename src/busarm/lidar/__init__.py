"""2D Lidars: the ``LaserScan`` every source produces, scan geometry, and the Slamtec
RPLIDAR A1 driver (``open_lidar``)."""

from busarm.lidar.scan import LaserScan, LidarSource, to_points

__all__ = ["LaserScan", "LidarSource", "to_points"]
