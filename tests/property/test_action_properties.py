"""An action's values against their limits, as properties: any action whose every value
is within its limit is accepted as it is, and any one value beyond its limit (or not a
number) is refused by a ConfigError that names its key, whatever the rest of it holds."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from busarm import Action, Arm, CameraSpec, ConfigError, Robot, RobotConfig, Twist
from busarm.arm.config import load_arm_config
from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics
from busarm.robot.observation import BASE_KEYS, check_action

ARM = load_arm_config()
CHASSIS = load_chassis_config()
KIN = MecanumKinematics(CHASSIS)
WIDEST_MM = ARM.gripper.widest_gap_mm


@pytest.fixture(scope="module")
def arm() -> Iterator[Arm]:
    """The twin's arm (the shipped config's, on its servos with their own limits); the
    checks send nothing, so one serves every example."""
    config = RobotConfig.from_port("twin://?blocks=0", camera=CameraSpec(calibrate=False))
    with Robot.open(config) as robot:
        assert robot.config.joints == ARM.joints
        yield robot.arm


def _within(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi, allow_nan=False)


@st.composite
def twists(draw: st.DrawFn) -> Twist:
    """A twist within every limit: each component's and the wheels' together."""
    v, w = CHASSIS.max_speed_m_s, CHASSIS.max_yaw_rate_rad_s
    twist = Twist(draw(_within(-v, v)), draw(_within(-v, v)), draw(_within(-w, w)))
    fastest = max(abs(s) for s in KIN.wheel_speeds_m_s(twist)) / CHASSIS.max_wheel_m_s
    return twist if fastest <= 1.0 else twist.scaled((1.0 - 1e-12) / fastest)


@st.composite
def valid_actions(draw: st.DrawFn) -> Action:
    joints = ({j.name: draw(_within(math.radians(j.min_deg), math.radians(j.max_deg)))
               for j in ARM.joints} if draw(st.booleans()) else None)
    gap = draw(st.none() | _within(0.0, WIDEST_MM))
    duration = draw(_within(0.0, 30.0)) if joints is not None and draw(st.booleans()) else None
    base = draw(st.none() | twists())
    if joints is None and gap is None and base is None:
        gap = WIDEST_MM
    return Action(joints, gap, duration, base)


BAD = st.sampled_from([math.nan, math.inf, -math.inf])
BEYOND = st.floats(1e-6, 1e3)


@st.composite
def one_bad_value(draw: st.DrawFn) -> tuple[str, float]:
    """A key of the flat form and a value beyond its limit (or no finite number)."""
    limits = {f"{j.name}.pos": (math.radians(j.min_deg), math.radians(j.max_deg))
              for j in ARM.joints}
    limits.update({"gripper.gap_mm": (0.0, WIDEST_MM), "duration_s": (0.0, 30.0),
                   "base.vx": (-CHASSIS.max_speed_m_s, CHASSIS.max_speed_m_s),
                   "base.vy": (-CHASSIS.max_speed_m_s, CHASSIS.max_speed_m_s),
                   "base.wz": (-CHASSIS.max_yaw_rate_rad_s, CHASSIS.max_yaw_rate_rad_s)})
    key = draw(st.sampled_from(sorted(limits)))
    lo, hi = limits[key]
    value = draw(BAD | BEYOND.map(lambda d: hi + d) | BEYOND.map(lambda d: lo - d))
    return key, value


@given(action=valid_actions())
def test_an_action_within_every_limit_is_accepted_as_it_is(arm: Arm, action: Action) -> None:
    checked = check_action(action, arm, CHASSIS)
    if action.joints_rad is None:
        assert checked.joints_deg is None
    else:
        assert checked.joints_deg == pytest.approx(
            [math.degrees(action.joints_rad[j.name]) for j in ARM.joints])
    assert (checked.gripper_gap_mm, checked.duration_s, checked.twist) == (
        action.gripper_gap_mm, action.duration_s, action.base)
    assert Action.from_dict(action.as_dict()) == action


@given(action=valid_actions(), bad=one_bad_value())
def test_any_one_value_beyond_its_limit_is_refused_by_name(
        arm: Arm, action: Action, bad: tuple[str, float]) -> None:
    key, value = bad
    flat = action.as_dict()
    if key.endswith(".pos") or key == "duration_s":  # with every joint's target (0 is
        for j in ARM.joints:                          # within each joint's limits)
            flat.setdefault(f"{j.name}.pos", 0.0)
    flat[key] = value
    with pytest.raises(ConfigError) as refused:
        check_action(Action.from_dict(flat), arm, CHASSIS)
    said = str(refused.value)
    assert said.startswith(key), said
    assert " is out of range " in said or " must be a number" in said, said


def test_the_base_keys_are_the_twists_parts() -> None:
    assert Action(base=Twist(0.1, -0.2, 0.3)).as_dict() == dict(
        zip(BASE_KEYS, (0.1, -0.2, 0.3), strict=True))
