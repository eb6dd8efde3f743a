"""Properties of pick-and-sort's grasp plans (pure geometry, no bus).

Every plan can be carried out (every point of its straight moves solves at its pitch and
roll), a top-down plan squares the fingers to the block, a tilted plan closes near level
and near square, its approach runs back along the tool's axis; where straight down
reaches, the plan is straight down; everywhere the benchmark places blocks, a plan exists.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import (
    MAX_CLOSING_TILT_DEG,
    MAX_TILTED_TURN_DEG,
    GraspPlan,
    GraspPlanner,
    NoClearGrasp,
)
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, UnreachableError
from busarm.twin.scene import PLACE_BEARING_DEG, PLACE_RADIUS_MM, REACH_RADIUS_MM

CONFIG = load_arm_config()
KIN = ArmKinematics.from_config(CONFIG)
PLANNER = GraspPlanner(KIN, CONFIG.table_z_mm, 30.0, approach_mm=60.0, carry_mm=75.0)
PROPS = settings(max_examples=120, deadline=None, derandomize=True)


def _off_square_deg(plan: GraspPlan, yaw_deg: float) -> tuple[float, float]:
    """(how far the closing axis is from level, from square to the block), degrees."""
    m = KIN.fk_matrix(KIN.ik_best(*plan.grasp, plan.pitch_deg, plan.roll_deg))
    tilt = math.degrees(math.asin(min(1.0, abs(m[2, 1]))))
    across = math.degrees(math.atan2(m[1, 1], m[0, 1]))
    return tilt, abs((yaw_deg - across + 45.0) % 90.0 - 45.0)


def _check(plan: GraspPlan, x: float, y: float, yaw: float) -> None:
    assert plan.grasp == pytest.approx((x, y, PLANNER.grasp_z_mm))
    assert plan.lift == pytest.approx((x, y, CONFIG.table_z_mm + 75.0))
    for a, b in ((plan.above, plan.grasp), (plan.grasp, plan.lift)):
        for t in np.linspace(0.0, 1.0, 11):
            point = [p + (q - p) * t for p, q in zip(a, b, strict=True)]
            KIN.ik_best(point[0], point[1], point[2], plan.pitch_deg, plan.roll_deg)
    tilt, turn = _off_square_deg(plan, yaw)
    if plan.pitch_deg == -90.0:
        assert plan.above == pytest.approx((x, y, CONFIG.table_z_mm + 60.0))
        assert turn < 1e-6
    else:
        assert tilt <= MAX_CLOSING_TILT_DEG + 1e-9
        assert turn <= MAX_TILTED_TURN_DEG + 1e-9
        back = np.subtract(plan.grasp, plan.above)
        assert float(np.linalg.norm(back)) == pytest.approx(60.0)
        m = KIN.fk_matrix(KIN.ik_best(*plan.grasp, plan.pitch_deg, plan.roll_deg))
        np.testing.assert_allclose(back / 60.0, m[:3, 2], atol=1e-9)


@PROPS
@given(r=st.floats(60.0, 340.0), bearing=st.floats(-120.0, 120.0), yaw=st.floats(-90.0, 90.0))
def test_every_plan_can_be_carried_out(r: float, bearing: float, yaw: float) -> None:
    x, y = r * math.cos(math.radians(bearing)), r * math.sin(math.radians(bearing))
    try:
        plan = PLANNER.plan(x, y, yaw)
    except UnreachableError as exc:
        assert "no grasp reaches it" in str(exc)
        return
    _check(plan, x, y, yaw)


@PROPS
@given(r=st.floats(*PLACE_RADIUS_MM), bearing=st.floats(*PLACE_BEARING_DEG),
       yaw=st.floats(-45.0, 45.0))
def test_where_straight_down_reaches_the_plan_is_straight_down(
        r: float, bearing: float, yaw: float) -> None:
    x, y = r * math.cos(math.radians(bearing)), r * math.sin(math.radians(bearing))
    plan = PLANNER.plan(x, y, yaw)
    assert plan.pitch_deg == -90.0
    _check(plan, x, y, yaw)


@PROPS
@given(r=st.floats(*REACH_RADIUS_MM), bearing=st.floats(*PLACE_BEARING_DEG),
       yaw=st.floats(-45.0, 45.0))
def test_every_block_the_benchmark_places_has_a_grasp(r: float, bearing: float,
                                                      yaw: float) -> None:
    x, y = r * math.cos(math.radians(bearing)), r * math.sin(math.radians(bearing))
    _check(PLANNER.plan(x, y, yaw), x, y, yaw)


def test_tilted_grasps_lean_out_far_and_back_near() -> None:
    far = PLANNER.plan(285.0, 0.0, 10.0)
    near = PLANNER.plan(105.0, 0.0, 10.0)
    assert -90.0 < far.pitch_deg < 0.0
    assert near.pitch_deg < -90.0
    assert math.hypot(*far.above[:2]) < 285.0  # it comes in from the base's side
    assert math.hypot(*near.above[:2]) > 105.0  # ... and here from beyond the block


def test_out_of_reach_says_why() -> None:
    with pytest.raises(UnreachableError, match="no grasp reaches it: straight down"):
        PLANNER.plan(400.0, 0.0, 0.0)


def test_bad_planner_arguments_are_refused() -> None:
    with pytest.raises(ConfigError, match="block_mm"):
        GraspPlanner(KIN, 0.0, 0.0, approach_mm=60.0, carry_mm=75.0)
    with pytest.raises(ConfigError, match="carry_mm"):
        GraspPlanner(KIN, 0.0, 30.0, approach_mm=60.0, carry_mm=10.0)
    with pytest.raises(ConfigError, match="approach_mm"):
        GraspPlanner(KIN, 0.0, 30.0, approach_mm=math.nan, carry_mm=75.0)


@PROPS
@given(r=st.floats(275.0, 295.0), bearing=st.floats(-60.0, 60.0), yaw=st.floats(-90.0, 90.0))
def test_a_tilted_grasp_blocked_on_one_face_pair_takes_the_other(
    r: float, bearing: float, yaw: float
) -> None:
    # Far out only tilted grasps reach; a neighbour against the faces the first plan's
    # fingers would close on leaves the other pair, squared as well as the wrist allows.
    x, y = r * math.cos(math.radians(bearing)), r * math.sin(math.radians(bearing))
    try:
        first = PLANNER.plan(x, y, yaw)
    except UnreachableError:
        return
    assert first.pitch_deg != -90.0
    m = KIN.fk_matrix(KIN.ik_best(*first.grasp, first.pitch_deg, first.roll_deg))
    axis = np.asarray(m[:2, 1]) / np.linalg.norm(m[:2, 1])
    wall = [Footprint.rectangle(x + s * 32.0 * axis[0], y + s * 32.0 * axis[1], 4.0, 120.0,
                                math.degrees(math.atan2(axis[1], axis[0])))
            for s in (-1.0, 1.0)]
    try:
        other = PLANNER.plan(x, y, yaw, wall)
    except NoClearGrasp:
        return  # the other pair is too far off square to take tilted here
    m2 = KIN.fk_matrix(KIN.ik_best(*other.grasp, other.pitch_deg, other.roll_deg))
    turned = math.degrees(math.atan2(m2[1, 1], m2[0, 1]) - math.atan2(m[1, 1], m[0, 1]))
    assert abs((turned + 90.0) % 180.0 - 90.0) > 45.0, (first, other)
    _check(other, x, y, yaw)


def test_far_blocks_can_be_taken_by_either_face_pair() -> None:
    # Not only somewhere: at the far edge most blocks have both pairs within reach.
    ways = []
    for bearing in range(-50, 51, 10):
        x, y = 285.0 * math.cos(math.radians(bearing)), 285.0 * math.sin(math.radians(bearing))
        yaw = bearing + 90.0  # squared to the bearing: one pair radial, one across
        rolls = {round(p.roll_deg) for p in PLANNER._reaching(x, y, yaw) if p.pitch_deg == -75.0}
        ways.append(len(rolls))
    assert sum(n >= 2 for n in ways) >= len(ways) - 2, ways


@PROPS
@given(r=st.floats(*REACH_RADIUS_MM), bearing=st.floats(*PLACE_BEARING_DEG),
       yaw=st.floats(-90.0, 90.0))
def test_opened_as_planned_the_pads_keep_their_clearance_to_the_whole_block(
        r: float, bearing: float, yaw: float) -> None:
    """A tilted grasp's pads close along an axis up to MAX_CLOSING_TILT_DEG from level, and
    a little off square: they lean in over the block's top edge. Opened as the plan says,
    each keeps the clearance asked for (3 mm a side, the least a sorter offers) from the
    block's corners at the top as well as at the fingertips' height."""
    x, y = r * math.cos(math.radians(bearing)), r * math.sin(math.radians(bearing))
    try:
        plan = PLANNER.plan(x, y, yaw, gaps_mm=[30.0 + 2 * 3.0])
    except UnreachableError:
        return
    m = KIN.fk_matrix(KIN.ik_best(*plan.grasp, plan.pitch_deg, plan.roll_deg))
    a = math.radians(yaw)
    corners = np.array([(x + 15.0 * (su * math.cos(a) - sv * math.sin(a)),
                         y + 15.0 * (su * math.sin(a) + sv * math.cos(a)), z)
                        for su in (-1.0, 1.0) for sv in (-1.0, 1.0)
                        for z in (PLANNER.grasp_z_mm, CONFIG.table_z_mm + 30.0)])
    along_closing = (corners - np.asarray(plan.grasp)) @ m[:3, 1]
    assert float(np.abs(along_closing).max()) <= plan.gap_mm / 2 - 3.0 + 1e-6, plan


def test_a_near_block_is_taken_tilted_with_the_pads_flat_on_its_faces() -> None:
    # The clutter bench's seed 1021: a block boxed in near the base, taken leaning back.
    # Of its two face pairs, one let the pads close 15 deg from level (off square 0.1
    # deg), the other 1 deg (off square 0.4 deg): the flatter is taken.
    plan = PLANNER.plan(111.8, -52.8, -21.0)
    tilt, turn = _off_square_deg(plan, -21.0)
    assert plan.pitch_deg < -90.0 and tilt < 3.0 and turn < 3.0, (plan, tilt, turn)
