"""The fast paths of the IK solvers (issue 35) give exactly what the plain forms gave.

``busarm.arm.kinematics`` multiplies by the radians/degrees constants instead of calling
math.radians/degrees and skips ``check_number`` for plain floats; ``busarm.arm.ik_batch``
wraps angles without np.mod where it can, multiplies instead of np.radians/np.degrees,
and works in chunks. Each is checked here against the plain form, to the last bit.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import busarm.arm.ik_batch as ik_batch
import busarm.arm.kinematics as kinematics
from busarm.arm.chain import LIMIT_TOL_RAD, TAU
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, UnreachableError

Array = npt.NDArray[np.float64]
JETAUTO = load_arm_config("jetauto_pro")
KIN = ArmKinematics.from_config(JETAUTO)
# Limits past +-180, a lower limit above 0, a narrow roll: every wrap case of _into.
ODD = ArmKinematics(
    JETAUTO.geometry, [(-300.0, 200.0), (-250.0, 10.0), (30.0, 300.0), (-400.0, 400.0),
                       (5.0, 15.0)],
    table_z_mm=20.0, base_keepout_mm=(60.0, 150.0),
)
PROPS = settings(max_examples=150, deadline=None, derandomize=True)


def test_angle_constants_are_what_numpy_and_math_multiply_by() -> None:
    rng = np.random.default_rng(5)
    x = np.concatenate([rng.uniform(-1e4, 1e4, 100_000), rng.standard_normal(10_000) * 1e-300,
                        [0.0, -0.0, 1e308, -1e308, np.inf, -np.inf]])
    with np.errstate(over="ignore"):  # 1e308 degrees
        np.testing.assert_array_equal(x * ik_batch._RAD, np.radians(x))
        np.testing.assert_array_equal(x * ik_batch._DEG, np.degrees(x))
    for v in [*x[:2000].tolist(), 0.0, -0.0, 1e308]:
        assert v * kinematics._RAD == math.radians(v)
        assert v * kinematics._DEG == math.degrees(v)


def _into_reference(angle: Array, lo: float, hi: float) -> tuple[Array, npt.NDArray[np.bool_]]:
    """The plain ``_into`` of the batch solver: with np.mod."""
    with np.errstate(invalid="ignore"):
        a = np.mod(angle - (lo - LIMIT_TOL_RAD), TAU)
    a += lo - LIMIT_TOL_RAD
    ok = a <= hi + LIMIT_TOL_RAD
    np.clip(a, lo, hi, out=a)
    return a, ok


def _edge_angles(start: float, rng: np.random.Generator) -> Array:
    """Angles whose difference from ``start`` sits on and around every edge of the fast
    path ([-2 pi, 4 pi) and the multiples of 2 pi), plus the odd values."""
    out = [rng.uniform(-30.0, 30.0, 200)]
    for k in range(-3, 4):
        centre = start + k * TAU
        steps = [centre]
        for direction in (-np.inf, np.inf):
            v = centre
            for _ in range(4):
                v = float(np.nextafter(v, direction))
                steps.append(v)
        out.append(np.asarray(steps))
        out.append(centre + np.array([-1e-9, 1e-9, -1e-15, 1e-15]))
    out.append(np.array([0.0, -0.0, np.nan, np.inf, -np.inf, 1e300, -1e300, 1e17]))
    return np.concatenate(out)


@pytest.mark.parametrize("kin", [KIN, ODD], ids=["jetauto", "odd_limits"])
def test_into_all_equals_the_np_mod_form_on_every_edge(kin: ArmKinematics) -> None:
    rng = np.random.default_rng(6)
    rows: list[Array] = []
    for a, b in ik_batch._GROUPS:
        joint = ik_batch._JOINT_OF_ROW[a]
        start = float(kin._lo[joint]) - LIMIT_TOL_RAD
        rows.extend(_edge_angles(start, rng) for _ in range(b - a))
    m = min(len(r) for r in rows)
    values = np.stack([r[:m] for r in rows])
    work = ik_batch._Work(kin, m + 3)
    work.use(m)  # a short chunk: the views, not the whole arrays
    work.u[:14] = values
    with np.errstate(invalid="ignore"):  # np.mod of an infinity
        ok = ik_batch._into_all(work).copy()
    for row in range(14):
        joint = ik_batch._JOINT_OF_ROW[row]
        want, want_ok = _into_reference(values[row], float(kin._lo[joint]), float(kin._hi[joint]))
        np.testing.assert_array_equal(work.u[row], want, err_msg=f"row {row}")
        np.testing.assert_array_equal(ok[row], want_ok, err_msg=f"row {row}")


def _targets(rng: np.random.Generator, n: int) -> Array:
    q = rng.uniform([-120, -180, -120, -200, -120], [120, 0, 120, 20, 120], size=(n, 5))
    poses = KIN.fk_batch(q)
    box = np.column_stack([rng.uniform(-400, 400, n), rng.uniform(-400, 400, n),
                           rng.uniform(-50, 500, n), rng.uniform(-400, 400, n),
                           rng.uniform(-400, 400, n)])
    out = np.concatenate([poses, box])
    out[::5, 4] = np.nan  # free roll
    out[::17, :2] = 0.0  # on the base axis
    out[3::29, 2] = np.inf
    return out


@pytest.mark.parametrize("kin", [KIN, ODD], ids=["jetauto", "odd_limits"])
def test_chunks_do_not_change_the_batch_results(
    kin: ArmKinematics, monkeypatch: pytest.MonkeyPatch,
) -> None:
    rng = np.random.default_rng(7)
    targets = _targets(rng, 150)
    refs = rng.uniform(-200, 200, size=(len(targets), 5))
    whole = [kin.ik_batch(targets, r) for r in (None, refs[0], refs)]
    monkeypatch.setattr(ik_batch, "BATCH_CHUNK", 7)  # 43 chunks, the last one short
    for (joints, ok), r in zip(whole, (None, refs[0], refs), strict=True):
        j7, ok7 = kin.ik_batch(targets, r)
        np.testing.assert_array_equal(j7, joints)
        np.testing.assert_array_equal(ok7, ok)


def test_an_empty_batch_is_empty() -> None:
    joints, ok = KIN.ik_batch(np.zeros((0, 4)))
    assert joints.shape == (0, 5) and ok.shape == (0,)
    joints, ok = KIN.ik_batch(np.zeros((0, 5)), np.zeros((0, 5)))
    assert joints.shape == (0, 5) and ok.shape == (0,)


coords = st.floats(-450, 450, allow_nan=False)
angles = st.floats(-400, 400, allow_nan=False)


@PROPS
@given(x=coords, y=coords, z=st.floats(-50, 600), pitch=angles, roll=st.none() | angles,
       current=st.none() | st.tuples(*[st.floats(-200, 200)] * 5))
def test_numbers_of_any_type_give_what_plain_floats_give(
    x: float, y: float, z: float, pitch: float, roll: float | None,
    current: tuple[float, ...] | None,
) -> None:
    """The check_number fast path (plain floats) and the slow one agree exactly."""
    for kin in (KIN, ODD):
        _same_with_other_types(kin, (x, y, z, pitch, roll), current)


def _same_with_other_types(
    kin: ArmKinematics, plain: tuple[float, float, float, float, float | None],
    current: tuple[float, ...] | None,
) -> None:
    x, y, z, pitch, roll = plain
    other = (np.float64(x), y, np.float64(z), pitch, None if roll is None else np.float64(roll))
    cur_other = None if current is None else np.asarray(current)
    sols = kin.ik(*plain, current_deg=current)
    assert kin.ik(*other, current_deg=cur_other) == sols  # type: ignore[arg-type]
    try:
        best = kin.ik_best(*plain, current_deg=current)
    except UnreachableError as exc:
        assert not sols
        with pytest.raises(UnreachableError) as again:
            kin.ik_best(*other, current_deg=cur_other)  # type: ignore[arg-type]
        assert str(again.value) == str(exc) and again.value.reason == exc.reason
        return
    assert best == sols[0]
    assert kin.ik_best(*other, current_deg=cur_other) == best  # type: ignore[arg-type]


@PROPS
@given(x=coords, y=coords, z=st.floats(-50, 600), pitch=angles, roll=st.none() | angles,
       ref=st.none() | st.tuples(*[st.floats(-200, 200)] * 5))
def test_the_batch_finds_a_solution_exactly_when_ik_does(
    x: float, y: float, z: float, pitch: float, roll: float | None,
    ref: tuple[float, ...] | None,
) -> None:
    for kin in (KIN, ODD):
        row = [x, y, z, pitch, math.nan if roll is None else roll]
        joints, ok = kin.ik_batch([row], ref)
        sols = kin.ik(x, y, z, pitch, roll, current_deg=ref)
        assert bool(ok[0]) == bool(sols)
        if sols:
            # The batch computes the back branch's cos(pi - p) as -cos(p): rounding apart.
            # A free roll kept outside the roll limits is clamped to the near limit by ik
            # and to the one past the wrap by ik_batch (as before issue 35): roll aside.
            n = 5 if roll is not None else 4
            assert any(joints[0][:n] == pytest.approx(s[:n], abs=1e-7) for s in sols)
        else:
            assert np.isnan(joints[0]).all()


def test_bad_numbers_still_name_the_argument() -> None:
    for args, fragment in [((math.nan, 0.0, 100.0, -90.0), "x_mm"),
                           ((100.0, 0.0, 100.0, -90.0, math.inf), "roll_deg"),
                           ((100.0, 0.0, 100.0, -90.0, "1"), "roll_deg"),
                           ((1e308, 1e308, 100.0, -90.0), None)]:
        for f in (KIN.ik, KIN.ik_best):
            if fragment is None:  # the sum overflows, the numbers are fine: slow path
                with pytest.raises(UnreachableError):
                    KIN.ik_best(*args)  # type: ignore[arg-type]
                assert KIN.ik(*args) == []  # type: ignore[arg-type]
                continue
            with pytest.raises(ConfigError, match=fragment):
                f(*args)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="joint angle"):
        KIN.ik_best(200.0, 0.0, 50.0, -90.0, current_deg=[0.0, 0.0, 0.0, math.nan, 0.0])
    with pytest.raises(ConfigError, match="5 joint angles"):
        KIN.ik_best(200.0, 0.0, 50.0, -90.0, current_deg=(0.0, 0.0, 0.0, 0.0))
