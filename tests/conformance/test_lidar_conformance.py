"""The Lidar source contract (busarm.lidar.scan.LidarSource), tested alike on every
source of ``backends.LIDAR_BACKENDS``: the simulated RPLIDAR A1 on a pty and the twin's
ray-cast Lidar, each opened by model (``open_lidar_source``). The scans are checked
against what the simulated world really has, never only against themselves."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from busarm.errors import BusTimeoutError, ConfigError, TransportError
from busarm.lidar.scan import LaserScan, LidarSource
from busarm.lidar.sources import LIDARS, lidar_models, open_lidar_source
from conformance.backends import LidarBackend


def test_it_is_a_lidar_source(lidar: LidarBackend) -> None:
    assert isinstance(lidar.source, LidarSource)
    assert lidar.is_scanning()


def test_a_scan_is_one_revolution_in_the_ros_convention(lidar: LidarBackend) -> None:
    scan = lidar.source.read_scan(timeout_s=2.0)
    assert isinstance(scan, LaserScan) and len(scan) > 150
    angles = scan.angles_rad
    assert np.all(np.diff(angles) > 0) and angles[0] >= 0.0 and angles[-1] < 2 * math.pi
    assert angles[-1] - angles[0] > 2 * math.pi * 0.95  # the whole circle
    valid = scan.valid
    assert valid.mean() > 0.8
    assert np.all((scan.ranges_m[valid] >= scan.range_min_m)
                  & (scan.ranges_m[valid] <= scan.range_max_m))
    assert np.all(np.isnan(scan.ranges_m[~valid]))


def test_the_ranges_are_the_worlds(lidar: LidarBackend) -> None:
    scan = lidar.source.read_scan(timeout_s=2.0)
    truth = np.asarray(lidar.true_ranges(scan.angles_rad), dtype=np.float64)
    both = scan.valid & np.isfinite(truth)
    error = np.abs(scan.ranges_m[both] - truth[both])
    assert both.mean() > 0.7
    # The A1 reports quarter millimetres; the twin adds a few mm of noise, more far off.
    assert np.median(error) < (0.02 if lidar.noisy else 0.002)
    assert np.mean(error < 0.05 + 0.03 * truth[both]) > 0.95


def test_scans_follow_one_another_at_the_scan_rate(lidar: LidarBackend) -> None:
    first = lidar.source.read_scan(timeout_s=2.0)
    second = lidar.source.read_scan(timeout_s=2.0)
    period = 1.0 / lidar.scan_hz
    assert second.stamp_s - first.stamp_s == pytest.approx(period, rel=0.3)
    assert first.scan_time_s == pytest.approx(period, rel=0.3)


def test_a_silent_lidar_is_a_typed_timeout_not_a_hang(lidar: LidarBackend) -> None:
    lidar.source.read_scan(timeout_s=2.0)
    lidar.silence()
    began = time.monotonic()
    with pytest.raises(BusTimeoutError):
        for _ in range(3):  # what was already on its way may complete one more
            lidar.source.read_scan(timeout_s=0.5)
    assert time.monotonic() - began < 10.0


def test_closing_stops_the_device(lidar: LidarBackend) -> None:
    lidar.source.read_scan(timeout_s=2.0)
    lidar.source.close()
    deadline = time.monotonic() + 2.0  # the pty carries the STOP in wall-clock time
    while lidar.is_scanning() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not lidar.is_scanning()
    with pytest.raises(TransportError):
        lidar.source.read_scan(timeout_s=0.5)
    lidar.source.close()  # twice is fine


def test_a_model_is_named_from_the_table() -> None:
    assert set(LIDARS) <= set(lidar_models()) and {"rplidar-a1", "twin"} <= set(LIDARS)
    with pytest.raises(ConfigError, match="Lidar model 'a2' is not known; known: .*rplidar-a1"):
        open_lidar_source("a2", "/dev/null")
