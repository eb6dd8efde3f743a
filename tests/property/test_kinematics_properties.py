"""Properties of the arm's kinematics (hypothesis, derandomized so every run is the same).

For both the shipped JetAuto Pro arm and the ArmPi-style test arm (tests/data):
IK(FK(q)) contains q's pose exactly (4x4 within 1e-4 mm / 1e-4 deg), every IK solution
respects the limits and reproduces the target, targets just beyond the links' reach are
refused by every solver, and the batch FK equals the scalar FK.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from busarm.arm.config import ArmConfig, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import UnreachableError

ARMS = {
    "jetauto_pro": load_arm_config("jetauto_pro"),
    "armpi_style": load_arm_config(
        Path(__file__).resolve().parent.parent / "data" / "armpi_style.toml"
    ),
}
# Near full stretch the elbow angle is only determined to ~sqrt(machine epsilon) by a
# pose (the singularity), which costs a few 1e-6 mm; the issue asks for 1e-3.
POS_TOL_MM = 1e-4
ROT_TOL_DEG = 1e-4
BEYOND_MM = 0.01

Array = npt.NDArray[np.float64]
PROPS = settings(max_examples=150, deadline=None, derandomize=True)


def rotation_error_deg(a: Array, b: Array) -> float:
    chord = np.linalg.norm(a[:3, :3] - b[:3, :3]) / (2.0 * math.sqrt(2.0))
    return math.degrees(2.0 * math.asin(min(1.0, chord)))


def transform_error(a: Array, b: Array) -> tuple[float, float]:
    return float(np.linalg.norm(a[:3, 3] - b[:3, 3])), rotation_error_deg(a, b)


def within_limits(cfg: ArmConfig, q: tuple[float, ...]) -> bool:
    return all(
        j.min_deg - 1e-9 <= v <= j.max_deg + 1e-9 for j, v in zip(cfg.joints, q, strict=True)
    )


@st.composite
def joint_vectors(draw: st.DrawFn, cfg: ArmConfig) -> tuple[float, ...]:
    return tuple(
        draw(st.floats(j.min_deg, j.max_deg, allow_nan=False, allow_infinity=False))
        for j in cfg.joints
    )


def check_round_trip(cfg: ArmConfig, kin: ArmKinematics, q: tuple[float, ...]) -> None:
    target = kin.fk_matrix(q)
    pose = kin.fk(q)
    sols = kin.ik(*pose, current_deg=q)
    assert sols, f"{cfg.name}: no solution for FK({q}) = {pose}"
    for s in sols:
        assert within_limits(cfg, s), f"solution {s} outside the limits"
        pos, rot = transform_error(kin.fk_matrix(s), target)
        assert pos <= POS_TOL_MM and rot <= ROT_TOL_DEG, (
            f"{cfg.name}: q={q} solution {s}: off by {pos:.3g} mm, {rot:.3g} deg"
        )
    best = kin.ik_best(*pose, current_deg=q)
    assert best == sols[0]


@pytest.mark.parametrize("check_table", [False, True], ids=["pure_geometry", "above_the_table"])
@pytest.mark.parametrize("arm", sorted(ARMS))
@PROPS
@given(data=st.data())
def test_ik_of_fk_reproduces_the_pose(arm: str, check_table: bool, data: st.DataObject) -> None:
    cfg = ARMS[arm]
    q = data.draw(joint_vectors(cfg))
    kin = ArmKinematics.from_config(cfg, check_table=check_table)
    if check_table:  # only poses that keep the tool point and the wrist above the table
        pose = kin.fk(q)  # and the tool point out of the base
        wrist_z = pose.z_mm - cfg.geometry.wrist_to_tip_mm * math.sin(math.radians(pose.pitch_deg))
        assume(pose.z_mm >= cfg.table_z_mm + 1e-6 and wrist_z >= cfg.table_z_mm + 1e-6)
        assume(not kin.in_base(pose.x_mm, pose.y_mm, pose.z_mm))
    check_round_trip(cfg, kin, q)


@pytest.mark.parametrize("arm", sorted(ARMS))
@PROPS
@given(
    x=st.floats(-600, 600), y=st.floats(-600, 600), z=st.floats(-100, 700),
    pitch=st.floats(-180, 180), roll=st.none() | st.floats(-180, 180),
)
def test_every_ik_solution_is_within_limits_and_on_target(
    arm: str, x: float, y: float, z: float, pitch: float, roll: float | None,
) -> None:
    cfg = ARMS[arm]
    kin = ArmKinematics.from_config(cfg)
    sols = kin.ik(x, y, z, pitch, roll)
    for s in sols:
        assert within_limits(cfg, s)
        got = kin.fk(s)
        assert got[:3] == pytest.approx((x, y, z), abs=POS_TOL_MM)
        on_axis = math.hypot(x, y) < 1e-3
        if not on_axis:
            assert abs((got.pitch_deg - pitch + 180) % 360 - 180) <= ROT_TOL_DEG
            if roll is not None:
                assert abs((got.roll_deg - roll + 180) % 360 - 180) <= ROT_TOL_DEG
    if sols:
        assert kin.ik_best(x, y, z, pitch, roll) == sols[0]
    else:
        with pytest.raises(UnreachableError):
            kin.ik_best(x, y, z, pitch, roll)


def _target(
    cfg: ArmConfig, bearing: float, wrist_dir: float, pitch: float, beyond_mm: float,
) -> tuple[float, float, float, float]:
    """A tool point whose wrist is ``beyond_mm`` past the links' reach from the shoulder.

    In the arm plane (rho outward, zeta up from the shoulder axis) the wrist is at
    distance upper_arm + forearm + beyond_mm in direction ``wrist_dir``; the tool points at
    ``pitch`` in that plane. Returned in the base frame, with the pitch measured facing
    away from the base as the pose convention has it.
    """
    g = cfg.geometry
    reach = g.upper_arm_mm + g.forearm_mm + beyond_mm
    w = math.radians(wrist_dir)
    p = math.radians(pitch)
    rho = reach * math.cos(w) + g.wrist_to_tip_mm * math.cos(p)
    zeta = reach * math.sin(w) + g.wrist_to_tip_mm * math.sin(p)
    b = math.radians(bearing)
    world_pitch = pitch if rho >= 0 else 180.0 - pitch  # behind: seen from the other side
    return rho * math.cos(b), rho * math.sin(b), g.base_height_mm + zeta, world_pitch


angles = st.floats(-180, 180, allow_nan=False)


@pytest.mark.parametrize("arm", sorted(ARMS))
@PROPS
@given(bearing=angles, wrist_dir=angles, pitch=angles, roll=st.none() | angles)
def test_just_beyond_reach_is_refused_at_that_pitch(
    arm: str, bearing: float, wrist_dir: float, pitch: float, roll: float | None,
) -> None:
    cfg = ARMS[arm]
    x, y, z, p = _target(cfg, bearing, wrist_dir, pitch, BEYOND_MM)
    for kin in (ArmKinematics.from_config(cfg, check_table=False),
                ArmKinematics.from_config(cfg)):
        assert kin.ik(x, y, z, p, roll) == []
        with pytest.raises(UnreachableError) as info:
            kin.ik_best(x, y, z, p, roll)
        reasons = {"reach"} if roll is None else {"reach", "joint_limit"}
        if kin.table_z_mm is not None:
            reasons |= {"table", "base"}
        assert info.value.reason in reasons, str(info.value)
        row = [x, y, z, p] if roll is None else [x, y, z, p, roll]
        joints, ok = kin.ik_batch([row])
        assert not ok[0] and np.isnan(joints[0]).all()
    # The same construction 0.01 mm inside is not refused for lack of reach.
    x, y, z, p = _target(cfg, bearing, wrist_dir, pitch, -BEYOND_MM)
    try:
        ArmKinematics.from_config(cfg, check_table=False).ik_best(x, y, z, p)
    except UnreachableError as exc:
        assert exc.reason != "reach", str(exc)


@pytest.mark.parametrize("arm", sorted(ARMS))
@PROPS
@given(bearing=angles, direction=angles, roll=st.none() | angles)
def test_just_beyond_full_stretch_is_refused_at_every_pitch(
    arm: str, bearing: float, direction: float, roll: float | None,
) -> None:
    # Tool axis along the wrist's direction: the tip is max_reach + 0.01 mm from the shoulder.
    cfg = ARMS[arm]
    x, y, z, p = _target(cfg, bearing, direction, direction, BEYOND_MM)
    for kin in (ArmKinematics.from_config(cfg, check_table=False),
                ArmKinematics.from_config(cfg)):
        assert kin.pitch_intervals(x, y, z, roll) == []
        assert kin.ik(x, y, z, p, roll) == []
        joints, ok = kin.ik_batch([[x, y, z, p]])
        assert not ok[0]
        with pytest.raises(UnreachableError) as info:
            kin.ik_free_pitch(x, y, z)
        if kin.table_z_mm is None:
            assert info.value.reason == "reach", str(info.value)


@pytest.mark.parametrize("arm", sorted(ARMS))
@settings(max_examples=100, deadline=None, derandomize=True)
@given(
    q=hnp.arrays(
        np.float64, st.tuples(st.integers(0, 20), st.just(5)),
        elements=st.floats(-720, 720, allow_nan=False, allow_infinity=False),
    )
)
def test_fk_batch_equals_fk_row_by_row(arm: str, q: Array) -> None:
    kin = ArmKinematics.from_config(ARMS[arm])
    poses = kin.fk_batch(q)
    mats = kin.fk_matrix_batch(q)
    assert poses.shape == (len(q), 5) and mats.shape == (len(q), 4, 4)
    for row, pose, mat in zip(q, poses, mats, strict=True):
        want = kin.fk(row)
        assert pose[:3] == pytest.approx(want[:3], abs=1e-9)
        for got_angle, want_angle in zip(pose[3:], want[3:], strict=True):
            assert abs((got_angle - want_angle + 180) % 360 - 180) <= 1e-9
        np.testing.assert_allclose(mat, kin.fk_matrix(row), atol=1e-12)


@pytest.mark.parametrize("arm", sorted(ARMS))
@PROPS
@given(x=st.floats(-400.0, 400.0), y=st.floats(-400.0, 400.0), z=st.floats(-100.0, 450.0),
       pitch=st.sampled_from([-90.0, -75.0, -45.0, 0.0, 30.0]))
def test_reaches_says_whether_ik_best_has_a_solution(arm: str, x: float, y: float, z: float,
                                                     pitch: float) -> None:
    kin = ArmKinematics.from_config(ARMS[arm])
    try:
        kin.ik_best(x, y, z, pitch)
        solved = True
    except UnreachableError:
        solved = False
    assert kin.reaches(x, y, z, pitch) == solved


@pytest.mark.parametrize("arm", sorted(ARMS))
@PROPS
@given(data=st.data())
def test_reaches_every_pose_the_arm_takes(arm: str, data: st.DataObject) -> None:
    cfg = ARMS[arm]
    kin = ArmKinematics.from_config(cfg, check_table=False)
    pose = kin.fk(data.draw(joint_vectors(cfg)))
    assert kin.reaches(pose.x_mm, pose.y_mm, pose.z_mm, pose.pitch_deg)
