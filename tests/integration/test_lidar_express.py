"""The simulated A1 answers GET_SAMPLERATE, GET_LIDAR_CONF (its scan modes, as Slamtec's
SDK asks them) and EXPRESS_SCAN; busarm's driver reads them all, switching between the
standard and the express scan (simulated time)."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from busarm.cli.main import cli
from busarm.lidar.rplidar import open_lidar
from busarm.protocol.rplidar import Cmd, SampleRate
from busarm.sim.rplidar import A1_TYPICAL_MODE, SimRplidar
from busarm.sim.transport import SimTransport


def test_scan_modes_sample_rate_and_the_express_scan() -> None:
    device = SimRplidar(scan_hz=10.0)
    with open_lidar(SimTransport(device, name="sim A1")) as lidar:
        assert lidar.sample_rate() == SampleRate(500, 250)
        modes, typical = lidar.scan_modes()
        assert [(m.id, m.name, m.sample_hz, m.max_distance_m, m.answer_type) for m in modes] \
            == [(0, "Standard", 2000.0, 12.0, 0x81), (1, "Express", 4000.0, 12.0, 0x82)]
        assert typical == A1_TYPICAL_MODE
        standard = [lidar.read_scan() for _ in range(3)]
        lidar.use_express(True)
        express = [lidar.read_scan() for _ in range(3)]
        assert device.express and device.requests[-1].cmd == Cmd.EXPRESS_SCAN
        lidar.use_express(False)
        again = lidar.read_scan()
        assert not device.express and device.requests[-1].cmd == Cmd.SCAN
    assert [len(s.angles_rad) for s in standard] == [200] * 3
    assert [len(s.angles_rad) for s in express] == [400] * 3
    assert len(again.angles_rad) == 200
    for scan in express:
        assert scan.scan_time_s == pytest.approx(0.1, rel=0.05)
        # Each beam where the world says, to the wire's millimetre (and the angle's
        # interpolation between capsules).
        truth = np.array([device.world(a) for a in scan.angles_rad])
        assert np.nanmax(np.abs(scan.ranges_m - truth)) < 0.003
        assert np.all(np.diff(scan.angles_rad) > 0)


def test_the_cli_lists_the_modes_and_reads_the_express_scan() -> None:
    runner = CliRunner()
    modes = runner.invoke(cli, ["lidar", "modes", "--lidar", "lidar://sim?hz=10"])
    assert modes.exit_code == 0, modes.output
    assert "standard 500 us, express 250 us" in modes.output
    assert "mode 1 Express: 4,000 samples/s, up to 12 m, answers type 0x82 (typical)" \
        in modes.output
    scan = runner.invoke(cli, ["lidar", "scan", "--express", "--lidar", "lidar://sim?hz=10"])
    assert scan.exit_code == 0, scan.output
    assert "400 beams, 400 returns, 10.0 Hz" in scan.output
