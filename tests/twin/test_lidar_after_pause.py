"""A scan read after a pause in the reading is a whole revolution of now, never one
spliced across the pause (issue 29's review: a 3 s pause gave a "revolution" of 2.5 s)."""

from __future__ import annotations

import pytest

from busarm import BoardSettings, CameraSpec, Robot, RobotConfig, TwinSpec
from busarm.lidar.rplidar import MAX_REVOLUTION_S, open_lidar
from busarm.sim.spec import SimLidarSpec


@pytest.mark.parametrize("pause_s", [0.4, 1.0, 3.0, 10.0])
def test_the_simulated_a1_never_gives_a_revolution_across_a_pause(pause_s: float) -> None:
    with open_lidar(SimLidarSpec(hz=5.5).open()) as lidar:
        lidar.read_scan()
        lidar.read_scan()
        lidar.clock.sleep(pause_s)
        spans = [lidar.read_scan().scan_time_s for _ in range(6)]
        # A turn takes 1/5.5 s; the revolutions queued during the pause arrive at once,
        # so their stamps are closer together, never farther apart.
        assert max(spans) <= min(MAX_REVOLUTION_S, 1.3 / 5.5)
        assert spans[-1] == pytest.approx(1 / 5.5, rel=0.2)


def test_an_observation_after_a_pause_has_a_scan_of_now() -> None:
    world = TwinSpec(family="arena", seed=3, controller=BoardSettings())
    with Robot.open(RobotConfig(world, camera=CameraSpec(calibrate=False))) as robot:
        assert robot.lidar is not None
        robot.lidar.read_scan()
        robot.clock.sleep(3.0)
        seen = robot.get_observation(cameras=False)
        assert seen.scan is not None
        assert seen.scan.scan_time_s <= MAX_REVOLUTION_S
        assert seen.t_s - seen.scan.stamp_s < 3 * seen.scan.scan_time_s
