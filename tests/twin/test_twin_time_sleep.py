"""A twin in this process keeps simulated time: a program that waits with ``time.sleep``
and then reads it is told once (busarm.clock.FrozenClockWarning), at its own line; a
program that waits on the robot's clock, or computes, is told nothing."""

from __future__ import annotations

import time
import warnings
from collections.abc import Iterator

import pytest

from busarm import CameraSpec, FrozenClockWarning, Robot, RobotConfig

ARENA = "board://twin?family=arena&seed=3"


@pytest.fixture
def arena() -> Iterator[Robot]:
    config = RobotConfig.from_port(ARENA, camera=CameraSpec(calibrate=False))
    with Robot.open(config) as robot:
        yield robot


@pytest.mark.wallclock("the subject is time.sleep, which a twin's clock does not see")
def test_time_sleep_then_a_read_is_told_once_at_the_programs_line(arena: Robot) -> None:
    assert arena.base is not None
    arena.base.drive(0.1, 0.0, 0.0)
    time.sleep(0.6)
    with pytest.warns(FrozenClockWarning, match=r"the twin keeps simulated time.*"
                                                r"Wait with robot\.clock\.sleep") as caught:
        odometry = arena.base.odometry()
    assert caught[0].filename == __file__
    assert odometry.pose.x_m < 0.001  # what the warning is about: nothing moved
    time.sleep(0.6)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FrozenClockWarning)
        arena.get_observation()  # once


@pytest.mark.wallclock("the subject is wall time that passes while the twin's clock does not")
def test_a_program_that_waits_on_the_robots_clock_or_computes_is_told_nothing(
        arena: Robot) -> None:
    assert arena.base is not None
    with warnings.catch_warnings():
        warnings.simplefilter("error", FrozenClockWarning)
        for _ in range(20):
            arena.send_action({"base.vx": 0.2})
            arena.clock.sleep(0.05)
            arena.get_observation(cameras=["wrist"])
        end = time.monotonic() + 0.6
        while time.monotonic() < end:  # a long computation: busy, not waiting
            sum(range(1000))
        arena.get_observation()
        arena.clock.sleep(2.0)
        assert arena.base.odometry().pose.x_m > 0.1
