"""Revolutions split only where the angle wraps (hypothesis): 1-4 stray bytes before 1%
of the simulated A1's measurements (its nodes, or its express capsules) make nodes with
invented S flags and angles; busarm's driver, reading the byte stream through its
transport, still returns whole revolutions."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.lidar.rplidar import RplidarA1
from busarm.sim.rplidar import SimRplidar
from busarm.sim.transport import SimTransport


@settings(max_examples=12)
@given(seed=st.integers(0, 2**32 - 1), scan_hz=st.sampled_from([5.5, 7.0, 10.0]),
       express=st.booleans())
def test_stray_bytes_do_not_split_revolutions(seed: int, scan_hz: float,
                                              express: bool) -> None:
    device = SimRplidar(scan_hz=scan_hz, garbage_rate=0.01, garbage_max_bytes=4, seed=seed)
    beams = device.express_per_rev if express else device.nodes_per_rev
    with RplidarA1(SimTransport(device, name="noisy A1"), express=express) as lidar:
        counts = [len(lidar.read_scan(2.0).angles_rad) for _ in range(12)]
        assert lidar.noise_bytes > 0  # the stray bytes were there, and skipped
    assert all(abs(n - beams) <= 0.1 * beams for n in counts), (beams, counts)
