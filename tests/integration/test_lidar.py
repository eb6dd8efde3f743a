"""The RPLIDAR A1 driver against the simulated A1 on a pty (bytes through a real
pseudo-terminal, in wall-clock time: those tests are marked ``wallclock``) and in this
process (``SimLidarSpec``, simulated time); ``busarm lidar`` in this process, and once as
real programs (``lidar serve`` and a ``lidar scan`` of it)."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner, Result

from busarm.base.config import Mount
from busarm.cli.main import cli
from busarm.clock import WALL_CLOCK
from busarm.errors import BusTimeoutError, LidarFaultError, NotALidarError
from busarm.lidar import to_points
from busarm.lidar.rplidar import RplidarA1, open_lidar
from busarm.lidar.scan import FloatArray
from busarm.protocol.rplidar import Cmd
from busarm.sim.bus import SimBus
from busarm.sim.pty import PtyServer
from busarm.sim.rplidar import SimRplidar, rectangular_room
from busarm.sim.spec import SimLidarSpec
from conftest import wait_for

PTY_LIDAR = "a simulated A1 served on a real pty by a thread, scanning in wall-clock time"
SCAN_TIMEOUT_S = 5.0
"""How long a read of a scan through the pty may wait where its timeout is not the
subject: a revolution takes 0.1 s, a loaded machine may stall this process for seconds."""
on_the_pty = pytest.mark.wallclock(PTY_LIDAR)


@pytest.fixture
def served() -> Iterator[tuple[SimRplidar, str]]:
    """A simulated A1 at 10 Hz on a pty, and the pty's path."""
    sim = SimRplidar(clock=WALL_CLOCK, scan_hz=10.0)
    with PtyServer(sim) as server:
        yield sim, server.path


@pytest.fixture
def device(served: tuple[SimRplidar, str]) -> SimRplidar:
    return served[0]


@pytest.fixture
def lidar(served: tuple[SimRplidar, str]) -> Iterator[RplidarA1]:
    # Its identification's 0.5 s timeout is test_a_servo_port_is_not_a_lidar's subject;
    # here a loaded machine may answer later.
    with open_lidar(served[1], timeout_s=SCAN_TIMEOUT_S) as opened:
        yield opened


def expected(device: SimRplidar) -> tuple[FloatArray, FloatArray]:
    """Every beam of one revolution as the simulated world defines it (bearing, range)."""
    nodes = [device.node(k) for k in range(device.nodes_per_rev)]
    angles = np.radians((-np.array([n.angle_q6 for n in nodes]) / 64.0) % 360.0)
    order = np.argsort(angles)
    return angles[order], np.array([device.world(a) for a in angles[order]])


@on_the_pty
def test_scans_are_the_worlds_ranges_at_the_wires_angles(
    device: SimRplidar, lidar: RplidarA1
) -> None:
    assert lidar.info.model == 0x18 and lidar.info.firmware == (1, 29)
    angles, ranges = expected(device)
    rates = []
    for _ in range(3):
        scan = lidar.read_scan(SCAN_TIMEOUT_S)
        np.testing.assert_array_equal(scan.angles_rad, angles)
        # The wire carries quarter millimetres: each range within half of one.
        assert np.max(np.abs(scan.ranges_m - ranges)) <= 0.000125 + 1e-12
        # A revolution is dated by its nodes' line time even when read late in one go:
        # never faster than the line carries 200 nodes (11.5 Hz), read promptly or not.
        assert scan.rate_hz < 20.0
        rates.append(scan.rate_hz)
    # Stamped when read, so a busy host's scheduling shows in the rate (a loaded machine
    # stalled this process 3 s once): roughly 10 Hz for most revolutions. The exact rate
    # is test_the_in_process_sim_scans_a_room's, on the simulated clock.
    assert 5.0 < float(np.median(rates)) < 20.0, rates
    nearest = scan.nearest()
    assert nearest is not None
    assert nearest[0] == pytest.approx(1.0, abs=0.000125)  # the wall at y = -1 m
    assert math.degrees(nearest[1]) == pytest.approx(-90.0, abs=1.0)


@on_the_pty
def test_points_in_the_base_frame(device: SimRplidar, lidar: RplidarA1) -> None:
    # Mounted 0.1 m ahead, turned left 90 deg: the Lidar's forward wall (x = 2.5 m in its
    # frame) is on the base's left, at y = 2.5 m, straight out from the Lidar (x = 0.1 m).
    mount = Mount(x_m=0.1, y_m=0.0, z_m=0.2, yaw_rad=math.pi / 2)
    points = to_points(lidar.read_scan(SCAN_TIMEOUT_S), mount)
    # Its backward wall (x = -1.5 m) is on the base's right, at y = -1.5 m.
    across = points[np.abs(points[:, 0] - 0.1) < 0.01]
    assert sorted(np.round(across[:, 1], 3).tolist()) == [-1.5, 2.5]


@on_the_pty
def test_the_driver_resyncs_after_noise(device: SimRplidar, lidar: RplidarA1) -> None:
    angles, ranges = expected(device)
    lidar.read_scan(SCAN_TIMEOUT_S)
    # Every byte's two low bits are equal: no node can start in this noise.
    noise = bytes([0x00, 0xA4, 0x5B, 0xFF, 0x13 & 0xFC, 0x00, 0x03, 0xFC, 0x00])
    for _ in range(3):
        device.inject_garbage(noise)
        time.sleep(0.03)  # spread over the scan (not a wait for anything)
    for _ in range(3):
        scan = lidar.read_scan(SCAN_TIMEOUT_S)
        np.testing.assert_array_equal(scan.angles_rad, angles)
        assert np.max(np.abs(scan.ranges_m - ranges)) <= 0.000125 + 1e-12
    assert lidar.noise_bytes == 3 * len(noise)


@pytest.mark.wallclock("a silent A1 on a real pty: the scan's timeout is waited out in "
                        "wall time (a loaded machine may end it late: 0.3 s of slack)")
def test_a_silent_lidar_times_out_within_its_budget_and_is_stopped(
    device: SimRplidar, lidar: RplidarA1
) -> None:
    lidar.read_scan(SCAN_TIMEOUT_S)
    device.go_silent()
    start = time.monotonic()
    with pytest.raises(BusTimeoutError, match=r"no complete scan .* in 0\.3 s"):
        lidar.read_scan(0.3)
    assert 0.3 <= time.monotonic() - start < 0.6
    # The server thread reads the pty on its own time: wait for it to hear STOP.
    assert wait_for(lambda: device.requests[-1].cmd == Cmd.STOP)


@on_the_pty
def test_close_sends_stop(served: tuple[SimRplidar, str]) -> None:
    device, path = served
    with open_lidar(path, timeout_s=SCAN_TIMEOUT_S) as opened:
        opened.read_scan(SCAN_TIMEOUT_S)
        assert device.scanning
    # The server thread reads the pty on its own time: wait for it to hear STOP.
    assert wait_for(lambda: not device.scanning)
    assert device.requests[-1].cmd == Cmd.STOP
    assert not device.scanning


@pytest.mark.wallclock("a servo simulator on a real pty: the A1's 0.5 s wait for a health "
                        "reply is waited out in wall time")
def test_a_servo_port_is_not_a_lidar() -> None:
    bus = SimBus.with_ids([1], clock=WALL_CLOCK)
    with PtyServer(bus) as server:
        start = time.monotonic()
        with pytest.raises(NotALidarError, match="does not answer like an RPLIDAR: to "
                                                 "GET_HEALTH nothing in 0.5 s"):
            open_lidar(server.path)
        assert time.monotonic() - start < 1.5
    assert bus.frames_received == 0  # nothing a servo could take for a command


def test_a_lidar_in_error_says_so() -> None:
    with pytest.raises(LidarFaultError, match="health ERROR .*0x8001"):
        open_lidar(SimLidarSpec(health=2).open())


def test_the_in_process_sim_scans_a_room() -> None:
    with open_lidar(SimLidarSpec(hz=10).open()) as opened:
        scans = [opened.read_scan(1.0) for _ in range(3)]
    room = rectangular_room()
    scan = scans[-1]
    assert len(scan) == 200
    # On the simulated clock: 10 Hz to within the delivery's 8 ms batches.
    assert all(9.0 < s.rate_hz < 11.0 for s in scans[1:])
    assert np.allclose(scan.ranges_m, [room(a) for a in scan.angles_rad], atol=0.000125)


# ---------------------------------------------------------------------- CLI

def busarm(*args: str) -> Result:
    """The command line in this process (``lidar://sim`` is on simulated time there)."""
    return CliRunner(mix_stderr=False).invoke(cli, list(args))


@pytest.fixture
def lidar_server() -> Iterator[str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "lidar", "serve", "--hz", "10"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        assert proc.stdout is not None
        yield proc.stdout.readline().strip()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 0, err
    assert "simulated Lidar stopped" in err


@pytest.mark.wallclock("real programs: `lidar serve` on a pty, scanning in wall-clock "
                        "time, and a `lidar scan` of it")
def test_cli_scan_of_a_served_lidar(lidar_server: str, tmp_path: Path) -> None:
    png = tmp_path / "scan.png"
    result = subprocess.run(
        [sys.executable, "-m", "busarm", "lidar", "scan", "--lidar", lidar_server, "--json",
         "--png", str(png)], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["beams"] == report["returns"] == 200
    assert report["nearest_m"] == pytest.approx(1.0, abs=0.000125)
    assert report["nearest_bearing_deg"] == pytest.approx(-90.0, abs=1.0)
    assert report["model"] == 0x18 and report["health"] == "GOOD"
    picture = cv2.imread(str(png))
    assert picture is not None and picture.shape[1] == 640


def test_cli_scan_summary_of_the_default_sim() -> None:
    result = busarm("lidar", "scan")
    assert result.exit_code == 0, result.stderr
    assert "on lidar://sim" in result.stdout
    assert "nearest return 1.000 m at bearing -90.0 deg" in result.stdout


@pytest.mark.wallclock("a servo simulator on a real pty: the A1's 0.5 s wait for a health "
                        "reply is waited out in wall time")
def test_cli_scan_of_a_servo_port_is_one_error() -> None:
    # The servos served on a pty in this process, as `busarm sim serve` serves them.
    with PtyServer(SimBus.with_ids([1], clock=WALL_CLOCK)) as server:
        path = server.path
        result = busarm("lidar", "scan", "--lidar", path)
    assert result.exit_code == 1, (result.stdout, result.stderr)
    assert result.stderr.count("\n") == 1
    assert result.stderr.startswith(f"error: {path} does not answer like an RPLIDAR")


def test_cli_refuses_the_servo_simulator_as_a_lidar() -> None:
    result = busarm("lidar", "scan", "--lidar", "sim")
    assert result.exit_code == 2
    assert result.stderr == ("error: Lidar port 'sim' is the servo simulator, twin or "
                             "controller board, not a Lidar; give the Lidar's device or "
                             "lidar://sim\n")
