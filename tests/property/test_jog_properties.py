"""The jog planner (busarm.dashboard.jog): whatever the arm's pose, direction and speed,
a step never leaves the joint limits, never moves a joint faster than its limit allows
in a period, moves only the jogged joint (a joint jog), and does not wind up ahead of an
arm that is held back."""

from __future__ import annotations

from hypothesis import assume, given
from hypothesis import strategies as st

from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.dashboard.jog import MAX_LEAD_S, JogPlan

CONFIG = load_arm_config()
KIN = ArmKinematics.from_config(CONFIG)
PERIOD_S = 0.04
joints = st.tuples(*(st.floats(j.min_deg, j.max_deg) for j in CONFIG.joints))
names = st.sampled_from([j.name for j in CONFIG.joints])


@given(joints, names, st.sampled_from([1, -1]), st.floats(0.05, 1.0))
def test_a_joint_jog_moves_that_joint_within_its_limits_and_speed(
        pose: tuple[float, ...], name: str, direction: int, speed: float) -> None:
    plan = JogPlan(CONFIG, KIN, joint=name, axis=None, direction=direction, speed=speed)
    step = plan.step(pose, pose, PERIOD_S)
    k = [j.name for j in CONFIG.joints].index(name)
    j = CONFIG.joints[k]
    if step.joints_deg is None:  # only at the limit it was going toward
        assert step.blocked and abs(pose[k] - (j.max_deg if direction > 0 else j.min_deg)) < 1e-6
        return
    moved = [b - a for a, b in zip(pose, step.joints_deg, strict=True)]
    assert all(abs(m) < 1e-12 for i, m in enumerate(moved) if i != k)
    assert j.min_deg <= step.joints_deg[k] <= j.max_deg
    assert moved[k] * direction >= 0
    assert abs(moved[k]) <= min(30.0, j.max_speed_deg_s) * speed * PERIOD_S + 1e-9


@given(joints, names, st.sampled_from([1, -1]), st.floats(0.05, 1.0))
def test_a_joint_jog_waits_for_an_arm_held_back(
        pose: tuple[float, ...], name: str, direction: int, speed: float) -> None:
    plan = JogPlan(CONFIG, KIN, joint=name, axis=None, direction=direction, speed=speed)
    k = [j.name for j in CONFIG.joints].index(name)
    ahead = list(pose)
    ahead[k] += direction * (plan.rate() * MAX_LEAD_S + 1.0)  # the target ran ahead
    step = plan.step(ahead, pose, PERIOD_S)
    assert step.joints_deg is None or step.joints_deg[k] == ahead[k] or not (
        CONFIG.joints[k].min_deg <= ahead[k] <= CONFIG.joints[k].max_deg)


@given(joints, st.sampled_from(["x", "y", "z", "pitch"]), st.sampled_from([1, -1]),
       st.floats(0.05, 1.0))
def test_a_tool_jog_stays_in_limits_and_speeds_or_stops(
        pose: tuple[float, ...], axis: str, direction: int, speed: float) -> None:
    assume(KIN.fk(pose).z_mm > CONFIG.table_z_mm + 5)
    plan = JogPlan(CONFIG, KIN, joint=None, axis=axis, direction=direction, speed=speed)
    step = plan.step(pose, pose, PERIOD_S)
    if step.joints_deg is None:
        assert step.blocked  # says why: the edge of the reach, a limit, a singular leap
        return
    CONFIG.check_joints(step.joints_deg)
    for j, a, b in zip(CONFIG.joints, pose, step.joints_deg, strict=True):
        assert abs(b - a) <= j.max_speed_deg_s * PERIOD_S * 1.5 + 1e-6
