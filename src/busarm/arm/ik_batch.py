"""The vectorized closed-form IK behind ``ArmKinematics.ik_batch``. Pure: no bus, no I/O.

The scalar solver's four branches (facing the target or reaching over the back, each
elbow up or down) are solved for every row at once; per row the solution nearest the
reference is kept, by the scalar rule (the largest joint change, then the sum of changes).

Speed (``busarm bench ik``): rows go in chunks of ``BATCH_CHUNK`` through scratch
arrays allocated once per call, mostly with in-place operations. The two branches share
the law-of-cosines part (their wrist points differ only in sign), the distinct values of
each joint over the four candidates are rows of one array (so that wrapping them into
their limits is a few whole-array operations, without the slow np.mod), and the winner's
joints are gathered straight into the output. Every value comes from the same
floating-point operations as the per-branch form had, so the results are bit-identical.
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
IntArray = npt.NDArray[np.intp]

BATCH_CHUNK = 8192
"""Rows per pass of the vectorized IK: enough to spread numpy's cost per call (about a
hundred calls a pass), few enough that the scratch arrays (about 3 MB) stay in cache."""

# np.radians and np.degrees multiply by these very constants (numpy's npy_math); a plain
# multiply is the same number, several times faster.
_RAD = math.pi / 180.0
_DEG = 180.0 / math.pi
_NONE = 4
"""The candidate index of a row without a solution: its joints are NaN."""


# The rows of the (row, target) array of joint values: each joint's distinct values over
# the four candidates (front elbow up, front down, back up, back down), then a NaN row.
_GROUPS = ((0, 2), (2, 6), (6, 8), (8, 12), (12, 14))
"""Rows of joints 1..5: base yaw (front, back), shoulder (per candidate), elbow (up,
down), wrist pitch (per candidate), roll (front, back)."""
_NAN_ROW = 14
_JOINT_OF_ROW = np.array([0, 0, 1, 1, 1, 1, 2, 2, 3, 3, 3, 3, 4, 4], dtype=np.intp)
_ROW_OF = np.array([  # [joint, candidate]: the row holding that joint's value
    [0, 0, 1, 1, _NAN_ROW],
    [2, 3, 4, 5, _NAN_ROW],
    [6, 7, 6, 7, _NAN_ROW],
    [8, 9, 10, 11, _NAN_ROW],
    [12, 12, 13, 13, _NAN_ROW],
], dtype=np.intp)


class _Work:
    """Scratch arrays for chunks of up to ``size`` rows of one arm, allocated once per
    call; ``use(m)`` points the working views at the first ``m`` rows."""

    def __init__(self, chain: ArmChain, size: int) -> None:
        self.u_full = np.empty((_NAN_ROW + 1, size))  # joint values, rows as in _GROUPS
        self.u_full[_NAN_ROW] = np.nan
        self._d = np.empty((_NAN_ROW, size))
        self._v = np.empty((_NAN_ROW, size))
        self._ok = np.empty((_NAN_ROW, size), dtype=np.bool_)
        self._cols = np.empty((5, size))  # the targets, one contiguous row per column
        # Flat index into u_full of [candidate, joint] for target 0, and the target to
        # add, (size, 5): the gather then writes the output's (row, joint) layout.
        self.offsets = np.ascontiguousarray(_ROW_OF.T * size)
        self._rows = np.repeat(np.arange(size), 5).reshape(size, 5)
        # _into's constants per row of u (broadcast along the targets).
        self.start = np.empty((_NAN_ROW, 1))
        self.top = np.empty((_NAN_ROW, 1))
        self.limits: list[tuple[int, int, float, float]] = []
        for j, (a, b) in enumerate(_GROUPS):
            lo, hi = float(chain._lo[j]), float(chain._hi[j])
            self.start[a:b] = lo - LIMIT_TOL_RAD
            self.top[a:b] = hi + LIMIT_TOL_RAD
            self.limits.append((a, b, lo, hi))
        self.use(size)

    def use(self, m: int) -> None:
        """Work on the first ``m`` targets (the last chunk may be short)."""
        self.m = m
        self.u = self.u_full[:, :m]
        self.d = self._d[:, :m]
        self.v = self._v[:, :m]
        self.ok = self._ok[:, :m]
        self.cols = self._cols[:, :m]
        self.rows = self._rows[:m]


def solve_batch(
    chain: ArmChain, targets: npt.ArrayLike, reference_deg: npt.ArrayLike | None = None,
) -> tuple[FloatArray, BoolArray]:
    """``ArmKinematics.ik_batch``: (joints (N, 5) in degrees, NaN where unreachable; ok)."""
    t = float_array(targets, "targets")
    if t.ndim != 2 or t.shape[1] not in (4, 5):
        raise ConfigError(f"targets must be an (N, 4) or (N, 5) array, got shape {t.shape}")
    n = t.shape[0]
    r = None
    if reference_deg is not None:
        r = float_array(reference_deg, "reference_deg")
        if r.shape not in ((5,), (n, 5)):
            raise ConfigError(f"reference_deg must be (5,) or ({n}, 5), got shape {r.shape}")
    joints = np.empty((n, 5))
    ok = np.empty(n, dtype=np.bool_)
    # A one-row reference is the same for every chunk: (5, 1), broadcast along the rows.
    ref_all = None if r is None or r.ndim == 2 else (r * _RAD)[:, None]
    work = _Work(chain, min(n, BATCH_CHUNK))
    for i in range(0, n, BATCH_CHUNK):
        m = min(BATCH_CHUNK, n - i)
        work.use(m)
        ref = ref_all
        if r is not None and r.ndim == 2:
            ref = np.multiply(r[i:i + m].T, _RAD, out=np.empty((5, m)))
        _solve_chunk(chain, t[i:i + m], ref, work, joints[i:i + m], ok[i:i + m])
    return joints, ok


class _Rows(NamedTuple):
    """What the candidates need of one chunk's targets (radians, mm): rows with a finite
    target above the table and outside the base, and within reach, are ``ok``."""

    p: FloatArray
    free_roll: BoolArray
    wr: FloatArray  # the wrist in the arm plane, front branch (the back one: -wr)
    wz: FloatArray
    a3s3: FloatArray
    a2c: FloatArray
    ok: BoolArray


def _solve_chunk(
    chain: ArmChain, t: FloatArray, ref: FloatArray | None, w: _Work,
    joints: FloatArray, ok: BoolArray,
) -> None:
    """Solve ``t`` (m, 4|5) into ``joints`` (m, 5, degrees) and ``ok`` (m,)."""
    rows = _rows(chain, t, ref, w)
    _candidates(rows, w)
    oku = _into_all(w)
    oku[12:14] |= rows.free_roll  # a free roll is kept, clamped into the limits
    # Candidate k = 2 back + elbow: its five joints' rows are _ROW_OF[:, k].
    ok4 = oku[2:6] & oku[8:12]
    by_branch = ok4.reshape(2, 2, w.m)
    by_branch &= oku[6:8]
    by_branch &= (oku[0:2] & oku[12:14])[:, None]
    ok4 &= rows.ok
    choice = _pick_first(ok4) if ref is None else _pick_nearest(w, ok4, ref)
    np.less(choice, _NONE, out=ok)
    # Gather each joint of the chosen candidate (none: the NaN row), then degrees.
    index = w.offsets.take(choice, axis=0)
    index += w.rows
    w.u_full.take(index, out=joints)
    joints *= _DEG


def _rows(chain: ArmChain, t: FloatArray, ref: FloatArray | None, w: _Work) -> _Rows:
    """The per-row quantities both branches share; base yaw and elbow go into ``w.u``
    (raw, before ``_into``).

    A row with a NaN or an infinity among x, y, z and pitch fails the reach test (c3 is
    then NaN or infinite), so it needs no test of its own; for the same reason the table
    and base tests are skipped when there is no table or no base keep-out."""
    L, a2, a3, table = chain._L, chain._a2, chain._a3, chain._table
    cols, u = w.cols, w.u
    np.copyto(cols[: t.shape[1]], t.T)
    x, y, z = cols[0], cols[1], cols[2]
    p = np.multiply(cols[3], _RAD, out=cols[3])
    r = np.hypot(x, y)
    psi = np.arctan2(y, x, out=u[0])
    on_axis = r < AXIS_EPS_MM
    if on_axis.any():  # no bearing of its own: the reference's (or 0)
        psi[...] = np.where(on_axis, ref[0] if ref is not None else 0.0, psi)
    np.add(psi, math.pi, out=u[1])
    lsp = np.sin(p)
    lsp *= L
    wz = z - chain._h  # zeta - L sin(p)
    wz -= lsp
    wr = np.cos(p)
    np.subtract(r, np.multiply(wr, L, out=wr), out=wr)  # r - L cos(p)
    c3 = wr * wr
    c3 += wz * wz
    c3 -= a2 * a2 + a3 * a3
    c3 *= 0.5 / (a2 * a3)
    ok = np.abs(c3) <= 1.0 + REACH_TOL
    if table > -math.inf:
        ok &= z >= table - 1e-9
        ok &= np.subtract(z, lsp, out=lsp) >= table - 1e-9  # the wrist above the table
    if chain._keep_top > -math.inf:  # outside the base
        ok &= (z >= chain._keep_top) | (r >= chain._keep_r - 1e-9)
    # Clip into [-1, 1] (np.clip's result; its bounds are not zeros, so signs agree).
    np.minimum(np.maximum(c3, -1.0, out=c3), 1.0, out=c3)
    s3 = np.multiply(c3, c3)
    np.subtract(1.0, s3, out=s3)
    np.sqrt(s3, out=s3)
    s3 *= a3
    np.arccos(c3, out=u[6])
    np.negative(u[6], out=u[7])
    c3 *= a3
    c3 += a2
    return _Rows(p, _rolls(t, ref, w), wr, wz, s3, c3, ok)


def _rolls(t: FloatArray, ref: FloatArray | None, w: _Work) -> BoolArray:
    """The raw roll of both branches into ``w.u``: the target's (behind: + pi), or where
    it is NaN (free) the reference's (or 0); returns where it is free."""
    u = w.u
    default = ref[4] if ref is not None else 0.0
    if t.shape[1] == 4:
        u[12:14] = default
        return np.ones(w.m, dtype=np.bool_)
    roll = np.multiply(w.cols[4], _RAD, out=u[12])
    np.add(roll, math.pi, out=u[13])
    free_roll: BoolArray = np.isnan(roll)
    if free_roll.any():
        np.copyto(u[12:14], default, where=free_roll)
    return free_roll


def _candidates(rows: _Rows, w: _Work) -> None:
    """Shoulder and wrist pitch of the four candidates into ``w.u`` (raw), by the scalar
    solver's operations."""
    u = w.u
    up = np.arctan2(rows.a3s3, rows.a2c)
    down = np.arctan2(-rows.a3s3, rows.a2c)
    for back in (False, True):
        # Plane pitch q = p (front) or pi - p (back); the back wrist is at -wr.
        gamma = np.arctan2(rows.wz, -rows.wr if back else rows.wr)
        q4 = -((math.pi - rows.p) + HALF_PI) if back else -(rows.p + HALF_PI)
        for elbow, beta in ((0, up), (1, down)):
            k = 2 * back + elbow
            t2 = np.add(gamma, beta, out=u[2 + k])
            np.negative(t2, out=t2)  # t2 = -(gamma + beta)
            t4 = np.subtract(q4, t2, out=u[8 + k])
            t4 -= u[6 + elbow]  # t4 = q4 - t2 - t3


def _into_all(w: _Work) -> BoolArray:
    """``_into`` of every joint value in ``w.u``, in place; where each is within limits.

    The representative of an angle in [start, start + 2 pi) is ``start + (angle - start)
    mod 2 pi``. np.mod is slow; for a difference d in [-2 pi, 4 pi) it equals d + 2 pi,
    d or d - 2 pi (exactly), which floor(d / 2 pi) picks. Values that leave [0, 2 pi)
    (the quotient rounded at an edge) or come from outside that range go through np.mod.
    """
    u = w.u[:_NAN_ROW]
    d, v = w.d, w.v
    np.subtract(u, w.start, out=d)
    with np.errstate(invalid="ignore"):  # an infinite angle warns in np.mod below, as before
        np.multiply(d, 1.0 / TAU, out=v)
        np.floor(v, out=v)
        v *= TAU
        np.subtract(d, v, out=v)  # d - k 2 pi: exactly d + 2 pi, d or d - 2 pi for k -1, 0, 1
    lowest, highest = np.minimum.reduce, np.maximum.reduce
    exact = (  # False if there is a NaN
        lowest(d, axis=None) >= -TAU and highest(d, axis=None) < 2.0 * TAU
        and lowest(v, axis=None) >= 0.0 and highest(v, axis=None) < TAU
    )
    if not exact:
        flag = (d < -TAU) | (d >= 2.0 * TAU) | (v < 0.0) | (v >= TAU) | np.isnan(d)
        v[flag] = np.mod(d[flag], TAU)
    v += w.start
    np.less_equal(v, w.top, out=w.ok)
    for a, b, lo, hi in w.limits:
        np.clip(v[a:b], lo, hi, out=u[a:b])
    return w.ok


def _pick_first(ok4: BoolArray) -> IntArray:
    """Without a reference: the first candidate with a solution (facing, elbow up first),
    counted as the run of candidates without one before it (4: none has one)."""
    run = ~ok4[0]
    choice: IntArray = run.astype(np.intp)
    for k in range(1, _NONE):
        run &= ~ok4[k]
        choice += run
    return choice


def _pick_nearest(w: _Work, ok4: BoolArray, ref: FloatArray) -> IntArray:
    """The candidate nearest ``ref``: the largest joint change (ties within TIE_RAD),
    then the sum of changes; candidates are taken in order, as the scalar rule does."""
    u, m = w.u, w.m
    dist = np.subtract(u[:_NAN_ROW], ref.take(_JOINT_OF_ROW, axis=0), out=w.d)
    np.abs(dist, out=dist)
    # Per joint, shaped (back, elbow, row) so that the candidates broadcast.
    d0, d1, d2 = dist[0:2, None], dist[2:6].reshape(2, 2, m), dist[6:8]
    d3, d4 = dist[8:12].reshape(2, 2, m), dist[12:14, None]
    worst = np.maximum(d0, d1)
    total = d0 + d1  # summed in joint order, like the scalar rule
    for dj in (d2, d3, d4):
        np.maximum(worst, dj, out=worst)
        total += dj
    cost = np.where(ok4, worst.reshape(_NONE, m), np.inf)
    totals = total.reshape(_NONE, m)
    choice: IntArray = np.full(m, _NONE, dtype=np.intp)
    best_cost: FloatArray = np.full(m, np.inf)
    best_total: FloatArray = np.full(m, np.inf)
    for k in range(_NONE):
        with np.errstate(invalid="ignore"):  # inf - inf: not a tie
            tie = np.abs(cost[k] - best_cost) <= TIE_RAD
        better = cost[k] < best_cost - TIE_RAD
        better |= tie & (totals[k] < best_total)
        better &= ok4[k]
        choice = np.where(better, k, choice)
        best_cost = np.where(better, cost[k], best_cost)
        best_total = np.where(better, totals[k], best_total)
    return choice


__all__ = ["BATCH_CHUNK", "solve_batch"]
