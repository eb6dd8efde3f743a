"""The gyro's bias is learnt while the base stands; a robot turned by hand is turned."""

from __future__ import annotations

import math

import pytest

from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics
from busarm.base.odometry import MAX_BIAS_RAD_S, GyroTurn, Odometry


def still(odometry: Odometry, rate_rad_s: float, seconds: float, t0: float = 0.0) -> float:
    """The wheels standing, the gyro reading ``rate_rad_s`` every 10 ms; returns the end."""
    t = t0
    for _ in range(round(seconds / 0.01)):
        t += 0.01
        odometry.update((0.0, 0.0, 0.0, 0.0), t, GyroTurn(rate_rad_s * 0.01, 0.01),
                        at_rest=True)
    return t


def test_a_small_rate_at_rest_is_learnt_as_bias_and_drifts_nothing() -> None:
    odometry = Odometry(MecanumKinematics(load_chassis_config()))
    odometry.update((0.0, 0.0, 0.0, 0.0), 0.0)
    t = still(odometry, 0.003, 5.0)
    assert odometry.gyro_bias_rad_s == pytest.approx(0.003, rel=0.01)
    before = odometry.pose.yaw_rad
    still(odometry, 0.003, 5.0, t)
    assert abs(odometry.pose.yaw_rad - before) < 1e-3


def test_a_robot_turned_by_hand_is_turned_not_biased() -> None:
    odometry = Odometry(MecanumKinematics(load_chassis_config()))
    odometry.update((0.0, 0.0, 0.0, 0.0), 0.0)
    t = still(odometry, 0.003, 5.0)
    bias, before = odometry.gyro_bias_rad_s, odometry.pose.yaw_rad
    t = still(odometry, 1.0, 0.5, t)  # carried round by half a radian, wheels off the floor
    assert odometry.gyro_bias_rad_s == bias
    assert odometry.pose.yaw_rad - before == pytest.approx(0.5 - 0.5 * bias, abs=1e-6)
    still(odometry, 2 * MAX_BIAS_RAD_S, 1.0, t)
    assert odometry.gyro_bias_rad_s == bias
    assert math.isfinite(odometry.pose.yaw_rad)
