"""The twin's A1 is the simulated A1 (one firmware model): it lists the same scan modes
and sample rate, and busarm's driver reads its express scan (4 kHz) as well as its
standard one, against the twin's ground truth."""

from __future__ import annotations

import numpy as np

from busarm.lidar.rplidar import RplidarA1
from busarm.protocol.rplidar import SampleRate
from busarm.sim.rplidar import SimRplidar
from busarm.twin.arena_gen import random_arena
from busarm.twin.lidar import LidarNoise, TwinLidarWorld, lidar_for_twin
from busarm.twin.transport import TwinTransport
from busarm.twin.twin import Twin


def test_the_twins_a1_reads_its_express_scan() -> None:
    with Twin(arena=random_arena(3), realtime=False) as twin:
        device = lidar_for_twin(twin, noise=LidarNoise.none())
        assert isinstance(device, SimRplidar) and isinstance(device.world, TwinLidarWorld)
        with RplidarA1(TwinTransport(twin, name="twin A1", line=device), express=True) as lidar:
            assert lidar.sample_rate() == device.sample_rate == SampleRate(500, 250)
            modes, _typical = lidar.scan_modes()
            assert [m.name for m in modes] == ["Standard", "Express"]
            express = [lidar.read_scan() for _ in range(3)]
            lidar.use_express(False)
            standard = lidar.read_scan()
        assert [len(s.angles_rad) for s in express] == [400] * 3
        assert len(standard.angles_rad) == 200
        truth = device.world.true_ranges(express[-1].angles_rad)
        both = np.isfinite(truth) & np.isfinite(express[-1].ranges_m)
        assert both.sum() > 300
        assert np.median(np.abs(express[-1].ranges_m[both] - truth[both])) < 0.003
