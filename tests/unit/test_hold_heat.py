"""The light hold and the heat it is watched for: ``Arm.grip`` closing on a block then
easing to a hold (on the servo simulator: an obstacle on the gripper servo is the block),
``Arm.hold_lighter``, the thermal model's sums (``busarm.arm.heat.HeatModel``, with
hypothesis), ``HeatWatch`` over a simulated servo's readings on a hand-turned clock, and
the rest before a carry (``CarryGuard.before_carry``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from types import SimpleNamespace
from typing import cast

import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm.apps.transport.carry import CarryGuard
from busarm.arm.arm import Arm
from busarm.arm.config import load_arm_config
from busarm.arm.gripper import HOLD_MIN_PULSES, HOLD_SQUEEZE_PULSES
from busarm.arm.heat import GRIPPER_HEAT, HeatAction, HeatModel, HeatWatch
from busarm.bus.driver import ServoBus
from busarm.clock import SimClock
from busarm.errors import ConfigError
from busarm.protocol import AlarmFlag, Command, Request
from busarm.robot import Robot
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import PARAMS_20KG
from busarm.sim.transport import SimTransport

CONFIG = load_arm_config()
GRIPPER = CONFIG.gripper.servo_id


@pytest.fixture
def rig() -> Iterator[tuple[Arm, SimBus]]:
    clock = SimClock(step_s=0.002)
    sim = SimBus.with_ids(timing=WireTiming(enabled=False), clock=clock)
    bus = ServoBus(SimTransport(sim))
    yield Arm(bus, CONFIG), sim
    bus.close()


def _told(arm: Arm) -> int | None:
    """Where the gripper servo was last told to go (MOVE_TIME_READ)."""
    return arm.read_gripper_state().target_pulses


def test_a_grip_closes_on_the_block_then_eases_to_a_light_hold(
        rig: tuple[Arm, SimBus]) -> None:
    arm, sim = rig
    nothing = arm.grip()  # closes on nothing: stays told closed, no hold
    assert not nothing.is_holding and nothing.hold_pulses is None
    assert _told(arm) == CONFIG.gripper.closed_pulses
    arm.open_gripper()
    sim.servo(GRIPPER).set_obstacle(max_pulses=540)  # a 30 mm block between the fingers
    held = arm.grip()
    assert held.is_holding and held.closed_pulses == CONFIG.gripper.closed_pulses
    assert held.position_pulses == 540
    assert held.hold_pulses == 540 + HOLD_SQUEEZE_PULSES == _told(arm)
    assert arm.read_gripper_state().is_holding  # the one rule still says so
    # Eased further: the lightest hold the rule still reads, then no lighter.
    assert arm.hold_lighter() == 540 + HOLD_MIN_PULSES == _told(arm)
    assert arm.hold_lighter() == 540 + HOLD_MIN_PULSES
    assert arm.read_gripper_state().is_holding
    # Told a grip lighter than the hold: it keeps what it was told.
    arm.open_gripper()
    light = arm.grip(541)
    assert light.is_holding is False and light.hold_pulses is None  # 1 pulse: accuracy
    arm.open_gripper()
    assert arm.grip(542).hold_pulses == 542 == _told(arm)
    sim.servo(GRIPPER).set_obstacle()
    arm.open_gripper()
    assert arm.hold_lighter() is None  # holds nothing: nothing sent


# ---------------------------------------------------------------------- the model

temps = st.floats(0.0, 120.0)
efforts = st.floats(0.0, 1.0)
models = st.builds(HeatModel, st.floats(5.0, 200.0), st.floats(20.0, 200.0),
                   st.floats(0.0, 40.0))


@given(models, temps, efforts, st.floats(40.0, 100.0))
def test_the_time_to_a_limit_lands_on_it(model: HeatModel, temp_c: float, effort: float,
                                         limit_c: float) -> None:
    eta = model.time_to_c(temp_c, effort, limit_c)
    if temp_c >= limit_c:
        assert eta == 0.0
    elif model.steady_c(effort) <= limit_c:
        assert eta == math.inf
        assert model.temp_after_c(temp_c, effort, 1e4) <= limit_c + 1e-9
    else:
        assert model.temp_after_c(temp_c, effort, eta) == pytest.approx(limit_c, abs=1e-6)
        sooner = model.temp_after_c(temp_c, effort, 0.99 * eta)
        assert sooner <= limit_c  # never there before its time
        if limit_c - temp_c > 1e-9:  # (a float step short of it, 0.99 of the time is none)
            assert sooner < limit_c


@given(models, temps, efforts, st.floats(1.0, 300.0))
def test_the_goal_is_found_from_two_readings(model: HeatModel, temp_c: float, effort: float,
                                             dt_s: float) -> None:
    later = model.temp_after_c(temp_c, effort, dt_s)
    assert model.steady_from_c(temp_c, later, dt_s) == pytest.approx(
        model.steady_c(effort), abs=1e-6 * max(1.0, math.exp(dt_s / model.time_constant_s)))


@given(models, temps, st.floats(50.0, 100.0), st.floats(0.0, 600.0), efforts)
def test_a_rest_first_lets_the_hold_end_below_the_limit(
        model: HeatModel, temp_c: float, limit_c: float, hold_s: float, effort: float) -> None:
    rest = model.rest_before_s(temp_c, limit_c, hold_s, effort)
    if rest == math.inf:  # the hold alone passes the limit even from a cold servo
        assert model.temp_after_c(model.ambient_c, effort, hold_s) > limit_c - 1e-6
        return
    rested = model.temp_after_c(temp_c, 0.0, rest)
    assert model.temp_after_c(rested, effort, hold_s) <= limit_c + 1e-6
    if rest > 0:  # no longer than needed
        assert model.temp_after_c(rested, effort, hold_s) == pytest.approx(limit_c, abs=1e-6)


def test_bad_figures_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"effort = 1\.5 is out of range 0\.\.1"):
        GRIPPER_HEAT.steady_c(1.5)
    with pytest.raises(ConfigError, match="time_constant_s"):
        HeatModel(0.0, 100.0)
    with pytest.raises(ConfigError, match="before the last one"):
        watch = HeatWatch(GRIPPER_HEAT, 85.0)
        watch.update(5.0, 40.0)
        watch.update(4.0, 40.0)


# ---------------------------------------------------------------------- the watch


def _watch_a_servo(effort: float, seconds: float
                   ) -> tuple[list[tuple[float, HeatAction]], float]:
    """A gripper servo loaded at ``effort`` from cold, read in whole degrees every
    second on a hand-turned clock: (each time the watch's advice changed, when the servo
    tripped or inf)."""
    servo = SimServo(GRIPPER, params=PARAMS_20KG, position_pulses=540.0, now=0.0)
    servo.handle(Request(GRIPPER, Command.MOVE_TIME_WRITE, (540, 0)), 0.0)  # loaded
    servo.external_effort = effort
    watch, tripped = HeatWatch(GRIPPER_HEAT, 85.0), math.inf
    changes: list[tuple[float, HeatAction]] = []
    t = 0.0
    while t < seconds:
        t += 1.0
        servo.advance(t)
        if AlarmFlag.OVER_TEMPERATURE in servo.active_faults:
            tripped = min(tripped, t)
        advice = watch.update(t, float(round(servo.temperature_c)))
        if not changes or changes[-1][1] != advice:
            changes.append((t, advice))
    return changes, tripped


def test_a_stalled_gripper_is_rested_before_it_trips() -> None:
    changes, tripped = _watch_a_servo(1.0, 60.0)
    assert [a for _, a in changes] == ["ok", "rest"]
    assert changes[1][0] + 5.0 <= tripped < 60.0  # at least 5 s of warning before 85 C


def test_a_hard_squeeze_is_eased_then_rested_well_before_it_trips() -> None:
    changes, tripped = _watch_a_servo(0.65, 120.0)  # heads for 92 C
    assert [a for _, a in changes] == ["ok", "ease", "rest"]
    (_, _), (eased, _), (rest, _) = changes
    assert eased + 30.0 < rest and rest + 15.0 <= tripped < 120.0


def test_a_light_hold_is_left_alone_for_ten_minutes() -> None:
    changes, tripped = _watch_a_servo(0.27, 600.0)
    assert changes == [(1.0, "ok")] and tripped == math.inf


def test_a_carry_is_not_started_with_a_gripper_too_hot_to_finish_it(
        rig: tuple[Arm, SimBus]) -> None:
    arm, sim = rig
    robot = cast(Robot, SimpleNamespace(arm=arm, clock=arm.clock, base=None))
    said: list[str] = []
    guard = CarryGuard(robot, said.append)
    assert guard.before_carry(120.0) == 0.0 and said == []  # cool: goes at once
    sim.servo(GRIPPER).temperature_c = 84.0  # hot from earlier work
    began = arm.clock.now()
    rested = guard.before_carry(120.0)
    # Idle, it cools toward 27 C: from 84 C to the 73 C the watch would ease at.
    expected = GRIPPER_HEAT.time_constant_s * math.log((84.0 - 27.0) / (73.0 - 27.0))
    assert rested == pytest.approx(expected, rel=0.02)
    assert arm.clock.now() - began == pytest.approx(rested, abs=0.1)
    assert sim.servo(GRIPPER).temperature_c <= 73.5 and guard.rested_s == rested
    assert said == [f"gripper at 84 C: resting {rested:.0f} s so that a 120 s carry starts "
                    "cool and ends below 79 C"]
