"""The vectorized closed-form IK behind ``ArmKinematics.ik_batch``. Pure: no bus, no I/O.

The scalar solver's four branches (facing the target or reaching over the back, each
elbow up or down) are solved for every row at once; per row the solution nearest the
reference is kept, by the scalar rule (the largest joint change, then the sum of changes).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import (
    AXIS_EPS_MM,
    HALF_PI,
    LIMIT_TOL_RAD,
    REACH_TOL,
    TAU,
    TIE_RAD,
    ArmChain,
    FloatArray,
    float_array,
)
from busarm.errors import ConfigError

BoolArray = npt.NDArray[np.bool_]

BATCH_CHUNK = 16384
"""Rows per pass of the vectorized IK."""


def solve_batch(
    chain: ArmChain, targets: npt.ArrayLike, reference_deg: npt.ArrayLike | None = None,
) -> tuple[FloatArray, BoolArray]:
    """``ArmKinematics.ik_batch``: (joints (N, 5) in degrees, NaN where unreachable; ok)."""
    t = float_array(targets, "targets")
    if t.ndim != 2 or t.shape[1] not in (4, 5):
        raise ConfigError(f"targets must be an (N, 4) or (N, 5) array, got shape {t.shape}")
    n = t.shape[0]
    ref = None
    if reference_deg is not None:
        r = float_array(reference_deg, "reference_deg")
        if r.shape not in ((5,), (n, 5)):
            raise ConfigError(f"reference_deg must be (5,) or ({n}, 5), got shape {r.shape}")
        ref = np.radians(np.broadcast_to(r, (n, 5)))
    joints = np.empty((n, 5))
    ok = np.empty(n, dtype=np.bool_)
    # Chunks that stay in the CPU cache run about a quarter faster than one huge pass.
    for i in range(0, n, BATCH_CHUNK):
        sl = slice(i, i + BATCH_CHUNK)
        joints[sl], ok[sl] = _solve_chunk(chain, t[sl], None if ref is None else ref[sl])
    return joints, ok


class _Rows(NamedTuple):
    """What every branch needs of the targets (radians, mm)."""

    p: FloatArray
    roll: FloatArray
    free_roll: BoolArray
    default_roll: FloatArray
    r: FloatArray
    psi: FloatArray
    zeta: FloatArray
    sp: FloatArray
    cp: FloatArray
    valid: BoolArray


class _Branch(NamedTuple):
    """One branch (front or back) solved up to the elbow's sign."""

    t1w: FloatArray
    t5w: FloatArray
    ok: BoolArray
    base3: FloatArray
    gamma: FloatArray
    q4: FloatArray
    a3s3: FloatArray
    a2c: FloatArray


def _solve_chunk(
    chain: ArmChain, t: FloatArray, ref: FloatArray | None
) -> tuple[FloatArray, BoolArray]:
    n = t.shape[0]
    rows = _rows(chain, t, ref)
    best = np.full((5, n), np.nan)  # joint-major: each column write is contiguous
    best_cost = np.full(n, np.inf)
    best_total = np.full(n, np.inf)
    for back in (False, True):
        branch = _branch(chain, rows, back)
        for sign in (1.0, -1.0):
            cols, ok = _elbow(chain, branch, sign)
            cost, total = _cost(cols, ok, ref, back, sign)
            with np.errstate(invalid="ignore"):  # inf - inf: not a tie
                tie = np.abs(cost - best_cost) <= TIE_RAD
            better = (cost < best_cost - TIE_RAD) | (tie & (total < best_total))
            better &= ok
            for j in range(5):
                np.copyto(best[j], cols[j], where=better)
            np.copyto(best_cost, cost, where=better)
            np.copyto(best_total, total, where=better)
    ok_rows = np.isfinite(best_cost)
    joints: FloatArray = np.degrees(np.ascontiguousarray(best.T))
    return joints, ok_rows


def _rows(chain: ArmChain, t: FloatArray, ref: FloatArray | None) -> _Rows:
    n = t.shape[0]
    x, y, z = t[:, 0], t[:, 1], t[:, 2]
    p = np.radians(t[:, 3])
    roll = np.radians(t[:, 4]) if t.shape[1] == 5 else np.full(n, np.nan)
    default_roll = ref[:, 4] if ref is not None else np.zeros(n)
    free_roll = np.isnan(roll)
    L = chain._L
    r = np.hypot(x, y)
    on_axis = r < AXIS_EPS_MM
    psi = np.where(on_axis, ref[:, 0] if ref is not None else 0.0, np.arctan2(y, x))
    zeta = z - chain._h
    sp, cp = np.sin(p), np.cos(p)
    table = chain._table
    above = (z >= table - 1e-9) & (z - L * sp >= table - 1e-9)
    above &= (z >= chain._keep_top) | (r >= chain._keep_r - 1e-9)  # outside the base
    finite = np.isfinite(t[:, :4]).all(axis=1)
    valid = above & finite
    return _Rows(p, roll, free_roll, default_roll, r, psi, zeta, sp, cp, valid)


def _branch(chain: ArmChain, rows: _Rows, back: bool) -> _Branch:
    L, a2, a3 = chain._L, chain._a2, chain._a3
    lo, hi = chain._lo, chain._hi
    sgn = -1.0 if back else 1.0
    t1 = rows.psi + math.pi if back else rows.psi
    # Plane pitch q = p (front) or pi - p (back): cos q = sgn cos p, sin q = sin p.
    wr = sgn * (rows.r - L * rows.cp)
    wz = rows.zeta - L * rows.sp
    c3 = (wr * wr + wz * wz - (a2 * a2 + a3 * a3)) * (0.5 / (a2 * a3))
    reach_ok = np.abs(c3) <= 1.0 + REACH_TOL
    np.clip(c3, -1.0, 1.0, out=c3)
    s3 = np.sqrt(1.0 - c3 * c3)
    gamma = np.arctan2(wz, wr)
    base3 = np.arccos(c3)
    q = (math.pi - rows.p) if back else rows.p
    r5 = np.where(rows.free_roll, rows.default_roll, rows.roll + math.pi if back else rows.roll)
    t1w, ok1 = _into_vec(t1, lo[0], hi[0])
    t5w, ok5 = _into_vec(r5, lo[4], hi[4])
    ok5 |= rows.free_roll
    branch_ok = reach_ok & ok1 & ok5 & rows.valid
    return _Branch(t1w, t5w, branch_ok, base3, gamma, -(q + HALF_PI), a3 * s3, a2 + a3 * c3)


def _elbow(
    chain: ArmChain, b: _Branch, sign: float
) -> tuple[tuple[FloatArray, ...], BoolArray]:
    """The five joints of elbow up (``sign`` 1) or down, and where they are within limits."""
    lo, hi = chain._lo, chain._hi
    t3 = b.base3 if sign > 0 else -b.base3
    t2 = -(b.gamma + np.arctan2(b.a3s3 if sign > 0 else -b.a3s3, b.a2c))
    t4 = b.q4 - t2 - t3
    t2w, ok2 = _into_vec(t2, lo[1], hi[1])
    t3w, ok3 = _into_vec(t3, lo[2], hi[2])
    t4w, ok4 = _into_vec(t4, lo[3], hi[3])
    ok = b.ok & ok2 & ok3 & ok4
    return (b.t1w, t2w, t3w, t4w, b.t5w), ok


def _cost(
    cols: tuple[FloatArray, ...], ok: BoolArray, ref: FloatArray | None, back: bool,
    sign: float,
) -> tuple[FloatArray, FloatArray]:
    """(cost, tie-breaker) of a branch's solutions: inf where it has none."""
    if ref is None:
        rank = (1.0 if back else 0.0) + (0.0 if sign > 0 else 0.5)
        cost = np.where(ok, rank, np.inf)
        return cost, cost
    # The scalar rule: the largest joint change, then the sum of changes.
    worst = np.abs(cols[0] - ref[:, 0])
    total = worst.copy()
    for j in range(1, 5):
        dj = np.abs(cols[j] - ref[:, j])
        np.maximum(worst, dj, out=worst)
        total += dj
    return np.where(ok, worst, np.inf), total


def _into_vec(
    angle: FloatArray, lo: float, hi: float
) -> tuple[FloatArray, BoolArray]:
    a = np.mod(angle - (lo - LIMIT_TOL_RAD), TAU)
    a += lo - LIMIT_TOL_RAD
    ok = a <= hi + LIMIT_TOL_RAD
    np.clip(a, lo, hi, out=a)
    return a, ok


__all__ = ["BATCH_CHUNK", "solve_batch"]
