"""2D Lidars: the ``LaserScan`` every source produces, scan geometry, the Slamtec
RPLIDAR A1 driver (``open_lidar``), and the sources by model (``open_lidar_source``)."""

from busarm.lidar.scan import LaserScan, LidarSource, to_points
from busarm.lidar.sources import LIDARS, open_lidar_source
from busarm.lidar.tap import ScanTap

__all__ = ["LIDARS", "LaserScan", "LidarSource", "ScanTap", "open_lidar_source", "to_points"]
