"""Inverse kinematics of the 5-joint arm, in closed form. Pure: no bus, no I/O.

``ArmKinematics`` is the chain of ``busarm.arm.chain`` (the model, its forward kinematics
and the pose convention) with its solvers; the vectorized one is ``busarm.arm.ik_batch``.

Every target has up to four solutions: facing the target or reaching over the back
(q1 + 180, pitch mirrored, q5 + 180), each elbow up (q3 > 0) or down. ``ik`` returns all
that respect the joint limits and keep the tool point and the wrist above the table and
the tool point out of the base (a cylinder round the base axis, from the arm config).

The free-pitch solver finds, for each of the four branches, the pitches at which a
constraint becomes active (reach, each joint limit, the table): each is a root of
``cos(pitch - a) = b`` and so has a closed form. Between consecutive roots feasibility
cannot change, so one test per arc gives the feasible pitch intervals exactly.

Speed (issue 35, ``busarm bench ik``): the scalar solver is plain float math on
constants computed once in ``__init__``, with ``_into`` written out inline; plain finite
floats skip ``check_number``; ``ik_best`` without a current pose stops at the first
solution, and the reasons for failing are only gathered (by solving again) when there is
no solution. Results are those of the straightforward form, to the last bit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

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
    Joints,
    Pose,
    check_number,
    wrap_deg,
    wrap_rad,
)
from busarm.arm.config import ArmConfig, Geometry
from busarm.arm.ik_batch import solve_batch
from busarm.errors import UnreachableError

# math.radians and math.degrees multiply by these very constants (CPython's mathmodule);
# a plain multiply is the same number without the call.
_RAD = math.pi / 180.0
_DEG = 180.0 / math.pi


@dataclass(frozen=True)
class _Failure:
    """Why one branch failed; the message is only built if every branch fails."""

    reason: str
    joint: int = -1
    value: float = 0.0
    extra: float = 0.0


class ArmKinematics(ArmChain):
    """FK and closed-form IK of one arm geometry with its joint limits.

    ``table_z_mm`` None switches the table check off (pure geometry); ``base_keepout_mm``
    (radius, top z) is the cylinder round the base axis the tool point keeps out of (None:
    none). Degrees and millimetres in and out.
    """

    @classmethod
    def from_config(cls, config: ArmConfig, *, check_table: bool = True) -> ArmKinematics:
        """The arm of ``config``; ``check_table`` False: pure geometry (no table, no base)."""
        return cls(
            config.geometry, config.limits_deg,
            table_z_mm=config.table_z_mm if check_table else None,
            base_keepout_mm=config.base_keepout_mm if check_table else None,
            joint_names=[j.name for j in config.joints],
        )

    def __init__(
        self,
        geometry: Geometry,
        limits_deg: Sequence[tuple[float, float]],
        *,
        table_z_mm: float | None = 0.0,
        base_keepout_mm: tuple[float, float] | None = None,
        joint_names: Sequence[str] = ("joint1", "joint2", "joint3", "joint4", "joint5"),
    ) -> None:
        super().__init__(
            geometry, limits_deg, table_z_mm=table_z_mm, base_keepout_mm=base_keepout_mm,
            joint_names=joint_names,
        )
        # The scalar solver's constants, computed once: the same values (same float
        # operations) as the per-call expressions they replace. _branch_k: reach, then
        # (lo, hi, hi + tolerance) of each joint, for _into written out inline.
        a2, a3 = self._a2, self._a3
        self._solve_k = (self._L, self._table - 1e-9, self._keep_top, self._keep_r - 1e-9,
                         self._h)
        self._branch_k = (
            self._L, a2, a3, a2 * a2, a3 * a3, 2.0 * a2 * a3,
            *(v for lo, hi in self._lim for v in (lo, hi, hi + LIMIT_TOL_RAD)),
        )
        lo5, hi5 = self._lim[4]
        roll0 = _into(0.0, lo5, hi5)  # a free roll without a current pose keeps 0
        self._roll0 = min(max(0.0, lo5), hi5) if roll0 is None else roll0

    # ------------------------------------------------------------------ inverse

    def ik(
        self, x_mm: float, y_mm: float, z_mm: float, pitch_deg: float,
        roll_deg: float | None = None, *, current_deg: Sequence[float] | None = None,
    ) -> list[Joints]:
        """Every joint solution (degrees) within limits for a tool pose; may be empty.

        ``roll_deg`` None keeps the wrist roll at ``current_deg``'s (or 0). Solutions are
        ordered by the motion from ``current_deg`` (largest joint change, then the sum),
        or facing the target and elbow up first when no current pose is given.
        """
        x, y, z, pd, rd = _pose_args(x_mm, y_mm, z_mm, pitch_deg, roll_deg)
        roll = None if rd is None else rd * _RAD
        current = None if current_deg is None else _joint_args(self, current_deg)
        sols = self._solve(x, y, z, pd * _RAD, roll, current, None, False)
        return self._ordered(sols, current)

    def ik_best(
        self, x_mm: float, y_mm: float, z_mm: float, pitch_deg: float,
        roll_deg: float | None = None, *, current_deg: Sequence[float] | None = None,
    ) -> Joints:
        """The solution nearest ``current_deg``; raises UnreachableError saying why if none."""
        x, y, z, pd, rd = _pose_args(x_mm, y_mm, z_mm, pitch_deg, roll_deg)
        roll = None if rd is None else rd * _RAD
        current = None if current_deg is None else _joint_args(self, current_deg)
        p = pd * _RAD
        # Without a current pose the first solution found is the best (the order of
        # ``ik``); with one, min() keeps the first of equal costs, as the stable sort did.
        sols = self._solve(x, y, z, p, roll, current, None, current is None)
        if not sols:
            _, failures = self._ik(x, y, z, p, roll, current)  # only now: why
            raise self._unreachable((x, y, z), f"pitch {pd:g} deg", failures)
        s = sols[0]
        if current is not None and len(sols) > 1:
            now = current
            s = min(sols, key=lambda c: _motion_cost(c, now))
        return s[0] * _DEG, s[1] * _DEG, s[2] * _DEG, s[3] * _DEG, s[4] * _DEG

    def reaches(self, x_mm: float, y_mm: float, z_mm: float, pitch_deg: float) -> bool:
        """Whether ``ik_best`` has a solution for this pose (free roll), without
        building the reason why not: a sorter asks this of every block it sees."""
        x, y, z, pd, _ = _pose_args(x_mm, y_mm, z_mm, pitch_deg, None)
        return bool(self._solve(x, y, z, pd * _RAD, None, None, None, True))

    def _ik(
        self, x: float, y: float, z: float, p: float, roll: float | None,
        current: tuple[float, ...] | None,
    ) -> tuple[list[tuple[float, ...]], list[_Failure]]:
        """Every solution (radians) and, per failed branch, why it failed."""
        failures: list[_Failure] = []
        return self._solve(x, y, z, p, roll, current, failures, False), failures

    def _solve(
        self, x: float, y: float, z: float, p: float, roll: float | None,
        current: tuple[float, ...] | None, failures: list[_Failure] | None, first: bool,
    ) -> list[tuple[float, ...]]:
        """The solutions (radians) in ``ik``'s order, only the first if ``first``; each
        failure is appended to ``failures`` unless it is None (the fast path)."""
        L, table, keep_top, keep_r, h = self._solve_k
        if z < table:
            if failures is not None:
                failures.append(_Failure("table", value=z))
            return []
        wrist_z = z - L * math.sin(p)
        if wrist_z < table:
            if failures is not None:
                failures.append(_Failure("wrist_table", value=wrist_z))
            return []
        r = math.hypot(x, y)
        if z < keep_top and r < keep_r:  # in_base
            if failures is not None:
                failures.append(_Failure("base", value=r))
            return []
        # On the base axis the target has no bearing: keep the current one.
        psi = math.atan2(y, x) if r >= AXIS_EPS_MM else (current[0] if current else 0.0)
        zeta = z - h
        # A free roll keeps the current one (or 0), within the limits, in both branches.
        kept = 0.0 if roll is not None else (
            self._roll0 if current is None else self._kept_roll(current[4]))
        sols: list[tuple[float, ...]] = []
        self._ik_branch(psi, r, zeta, p, roll, kept, sols, failures, first)
        if not (first and sols):
            self._ik_branch(
                psi + math.pi, -r, zeta, math.pi - p, None if roll is None else roll + math.pi,
                kept, sols, failures, first,
            )
        return sols

    def _kept_roll(self, keep: float) -> float:
        """A free roll's value: ``keep`` within the roll limits (clamped if need be)."""
        lo5, hi5 = self._lim[4]
        t5w = _into(keep, lo5, hi5)
        return min(max(keep, lo5), hi5) if t5w is None else t5w

    def _ik_branch(
        self, t1: float, rho: float, zeta: float, q: float, r5: float | None, kept: float,
        sols: list[tuple[float, ...]], failures: list[_Failure] | None, first: bool,
    ) -> None:
        """One branch, both elbows (base yaw t1; the tool point at (rho, zeta) from the
        shoulder axis, plane pitch q; roll r5, None: free, ``kept``); appends solutions
        and failures. ``_into`` is written out inline: calls cost a third of the time."""
        (L, a2, a3, a2sq, a3sq, two_a2a3, lo1, hi1, top1, lo2, hi2, top2, lo3, hi3, top3,
         lo4, hi4, top4, lo5, hi5, top5) = self._branch_k
        tol = LIMIT_TOL_RAD
        a = lo1 + (t1 - lo1 + tol) % TAU - tol
        if a > top1:
            if failures is not None:
                failures.append(_Failure("joint", 0, t1))
            return
        t1w = lo1 if a < lo1 else (hi1 if a > hi1 else a)
        t5w = kept
        if r5 is not None:
            a = lo5 + (r5 - lo5 + tol) % TAU - tol
            if a > top5:
                if failures is not None:
                    failures.append(_Failure("joint", 4, r5))
                return
            t5w = lo5 if a < lo5 else (hi5 if a > hi5 else a)
        wr = rho - L * math.cos(q)
        wz = zeta - L * math.sin(q)
        d2 = wr * wr + wz * wz
        c3 = (d2 - a2sq - a3sq) / two_a2a3
        if c3 > 1.0 + REACH_TOL or c3 < -1.0 - REACH_TOL:
            if failures is not None:
                failures.append(
                    _Failure("reach", value=math.sqrt(d2), extra=a2 + a3) if c3 > 0 else
                    _Failure("reach_min", value=math.sqrt(d2), extra=abs(a2 - a3))
                )
            return
        c3 = min(max(c3, -1.0), 1.0)  # within REACH_TOL of full stretch (or fold)
        s3 = math.sqrt(1.0 - c3 * c3)
        gamma = math.atan2(wz, wr)
        base3 = math.acos(c3)
        ys, xs = a3 * s3, a2 + a3 * c3
        q4 = -(q + HALF_PI)
        # Fully stretched or folded (s3 == 0): both elbows are the same solution.
        for t3, y3 in ((base3, ys),) if s3 == 0.0 else ((base3, ys), (-base3, -ys)):
            t2 = -(gamma + math.atan2(y3, xs))
            a = lo2 + (t2 - lo2 + tol) % TAU - tol
            if a > top2:
                if failures is not None:
                    failures.append(_Failure("joint", 1, t2))
                continue
            t2w = lo2 if a < lo2 else (hi2 if a > hi2 else a)
            a = lo3 + (t3 - lo3 + tol) % TAU - tol
            if a > top3:
                if failures is not None:
                    failures.append(_Failure("joint", 2, t3))
                continue
            t3w = lo3 if a < lo3 else (hi3 if a > hi3 else a)
            t4 = q4 - t2 - t3
            a = lo4 + (t4 - lo4 + tol) % TAU - tol
            if a > top4:
                if failures is not None:
                    failures.append(_Failure("joint", 3, t4))
                continue
            sols.append((t1w, t2w, t3w, lo4 if a < lo4 else (hi4 if a > hi4 else a), t5w))
            if first:
                return

    def _ordered(
        self, sols: list[tuple[float, ...]], current: tuple[float, ...] | None
    ) -> list[Joints]:
        if current is not None and len(sols) > 1:
            sols = sorted(sols, key=lambda s: _motion_cost(s, current))
        return [(a * _DEG, b * _DEG, c * _DEG, d * _DEG, e * _DEG) for a, b, c, d, e in sols]

    def _unreachable(
        self, target: tuple[float, float, float], what: str, failures: list[_Failure]
    ) -> UnreachableError:
        x, y, z = target
        where = f"({x:.1f}, {y:.1f}, {z:.1f}) mm at {what}"
        kinds = {f.reason for f in failures}
        if "table" in kinds:
            return UnreachableError(
                f"target {where} is below the table (z must be >= {self._table:g} mm)", "table"
            )
        if "wrist_table" in kinds:
            f = next(f for f in failures if f.reason == "wrist_table")
            return UnreachableError(
                f"target {where} would put the wrist below the table (wrist z {f.value:.1f} mm "
                f"< {self._table:g} mm): raise the target or tilt the tool up", "table",
            )
        if "base" in kinds:
            f = next(f for f in failures if f.reason == "base")
            return UnreachableError(
                f"target {where} is inside the arm's base: {f.value:.1f} mm from its axis; "
                f"below z {self._keep_top:g} mm the tool point must stay {self._keep_r:g} mm "
                "or more from the axis", "base",
            )
        # Shoulder, elbow and wrist limits are met only after the reach check passed, so
        # they are the real reason; base yaw and roll fail before reach is known.
        joint_fail = [f for f in failures if f.reason == "joint" and 1 <= f.joint <= 3]
        reach = [f for f in failures if f.reason in ("reach", "reach_min")]
        if not joint_fail and not reach:
            joint_fail = [f for f in failures if f.reason == "joint"]
        if joint_fail:
            f = joint_fail[0]
            lo, hi = self.limits_deg[f.joint]
            name = self.joint_names[f.joint]
            return UnreachableError(
                f"target {where} needs {name} = {wrap_deg(math.degrees(f.value)):.1f} deg, "
                f"outside its limits {lo:g}..{hi:g} deg", "joint_limit", name,
            )
        if reach:
            f = reach[0]
            if f.reason == "reach":
                return UnreachableError(
                    f"target {where} is beyond reach: the wrist would be {f.value:.1f} mm from "
                    f"the shoulder axis, the links reach {f.extra:.1f} mm", "reach",
                )
            return UnreachableError(
                f"target {where} is too close: the wrist would be {f.value:.1f} mm from the "
                f"shoulder axis, the links fold to {f.extra:.1f} mm at least", "reach",
            )
        return UnreachableError(f"target {where} has no solution", "reach")

    # ------------------------------------------------------------------ free pitch

    def pitch_intervals(
        self, x_mm: float, y_mm: float, z_mm: float, roll_deg: float | None = None,
        *, current_deg: Sequence[float] | None = None,
    ) -> list[tuple[float, float]]:
        """The pitches (degrees) at which the tool point is reachable, as closed intervals.

        Intervals lie on the circle: ``lo`` is in [-180, 180) and ``hi`` may exceed 180
        when an interval wraps; they are merged across branches and sorted.
        """
        x = check_number("x_mm", x_mm)
        y = check_number("y_mm", y_mm)
        z = check_number("z_mm", z_mm)
        roll = None if roll_deg is None else math.radians(check_number("roll_deg", roll_deg))
        current = None if current_deg is None else self._radians(current_deg)
        arcs = [a for _, _, a in self._branch_arcs(x, y, z, roll, current)]
        return [(math.degrees(lo), math.degrees(hi)) for lo, hi in _merge_arcs(arcs)]

    def ik_free_pitch(
        self, x_mm: float, y_mm: float, z_mm: float, roll_deg: float | None = None, *,
        preferred_pitch_deg: float = -90.0, current_deg: Sequence[float] | None = None,
    ) -> tuple[Joints, float]:
        """Joints and pitch (deg) for a tool point, choosing the pitch by a fixed rule.

        The rule: the feasible pitch nearest ``preferred_pitch_deg`` (on the circle);
        among solutions at that pitch, the smallest motion from ``current_deg`` (the
        *measured* pose: largest joint change first, then the sum). A pitch on the edge
        of a feasible interval is moved 1e-6 deg inside it. Raises UnreachableError
        saying why when no pitch works.
        """
        x = check_number("x_mm", x_mm)
        y = check_number("y_mm", y_mm)
        z = check_number("z_mm", z_mm)
        pref = math.radians(check_number("preferred_pitch_deg", preferred_pitch_deg))
        roll = None if roll_deg is None else math.radians(check_number("roll_deg", roll_deg))
        current = None if current_deg is None else self._radians(current_deg)
        best: list[tuple[float, float]] = []  # (distance, world pitch)
        inset = math.radians(1e-6)
        for _, _, (lo, hi) in self._branch_arcs(x, y, z, roll, current):
            d_lo = wrap_rad(pref - lo)
            if 0.0 <= (pref - lo) % TAU <= hi - lo:
                best.append((0.0, pref))
                continue
            width = hi - lo
            d_hi = wrap_rad(pref - hi)
            edge = min(inset, width / 2)
            best.extend([(abs(d_lo), lo + edge), (abs(d_hi), hi - edge)])
        if not best:
            failures = self._ik(x, y, z, pref, roll, current)[1]
            raise self._unreachable(
                (x, y, z), "any pitch", failures or [_Failure("reach")],
            )
        dmin = min(d for d, _ in best)
        solutions: list[tuple[tuple[float, ...], float]] = []
        for d, pitch in best:
            if d <= dmin + 1e-9:
                for s in self._solve(x, y, z, pitch, roll, current, None, False):
                    solutions.append((s, pitch))
        if not solutions:  # pragma: no cover - guarded by the inset
            raise UnreachableError(f"target ({x:.1f}, {y:.1f}, {z:.1f}) mm: no solution")
        if current is not None:
            now = current
            solutions.sort(key=lambda item: _motion_cost(item[0], now))
        s, pitch = solutions[0]
        joints = self._ordered([s], None)[0]
        return joints, wrap_deg(math.degrees(pitch))

    def _branch_arcs(
        self, x: float, y: float, z: float, roll: float | None,
        current: tuple[float, ...] | None,
    ) -> list[tuple[bool, float, tuple[float, float]]]:
        """(back, elbow sign, world-pitch arc) for every feasible arc of every branch."""
        L, a2, a3, h = self._L, self._a2, self._a3, self._h
        if z < self._table - 1e-9 or self.in_base(x, y, z):
            return []
        r = math.hypot(x, y)
        zeta = z - h
        lim = self._lim
        # Roots in the plane pitch q shared by the branches with the same rho sign are
        # computed per branch; every constraint is cos(q - a) = b.
        out: list[tuple[bool, float, tuple[float, float]]] = []
        for back in (False, True):
            rho = -r if back else r
            roots: list[float] = []
            d = math.hypot(rho, zeta)
            phi = math.atan2(zeta, rho)
            # Reach and elbow limits: |W|^2 = d^2 + L^2 - 2 L d cos(q - phi) = R^2.
            radii = [a2 + a3, abs(a2 - a3)]
            for lim3 in lim[2]:
                if -math.pi < lim3 < math.pi:
                    radii.append(math.sqrt(max(0.0, a2 * a2 + a3 * a3
                                               + 2 * a2 * a3 * math.cos(lim3))))
            for radius in radii:
                _cos_roots(roots, phi, d * d + L * L - radius * radius, 2 * L * d)
            # Shoulder limit c: the elbow sits at E; |P - E - L u(q)| = a3.
            for c in lim[1]:
                ex, ez = a2 * math.cos(c), -a2 * math.sin(c)
                px, pz = rho - ex, zeta - ez
                pd = math.hypot(px, pz)
                _cos_roots(roots, math.atan2(pz, px), pd * pd + L * L - a3 * a3, 2 * L * pd)
            # Wrist pitch limit c: |P - m u(q)| = a2 with m = L + a3 e^{i(pi/2 + c)}.
            for c in lim[3]:
                mx, mz = L + a3 * math.cos(HALF_PI + c), a3 * math.sin(HALF_PI + c)
                m = math.hypot(mx, mz)
                _cos_roots(
                    roots, phi - math.atan2(mz, mx), d * d + m * m - a2 * a2, 2 * d * m
                )
            # Wrist above the table: z - L sin(p) >= table, and sin(q) = sin(p).
            if math.isfinite(self._table):
                k = (z - self._table) / L
                if -1.0 < k < 1.0:
                    roots.extend((math.asin(k), math.pi - math.asin(k)))
            roots = sorted({wrap_rad(q) for q in roots})
            # Each arc's solutions at its middle, found once for both elbows.
            arcs = []
            for lo, hi in _arcs_between(roots):
                mid = 0.5 * (lo + hi)
                p_mid = wrap_rad(math.pi - mid) if back else mid
                arcs.append((lo, hi, self._solve(x, y, z, p_mid, roll, current, None, False)))
            for sign in (1.0, -1.0):
                for lo, hi, sols in arcs:
                    if _branch_ok(sols, x, y, back, sign):
                        arc = (math.pi - hi, math.pi - lo) if back else (lo, hi)
                        out.append((back, sign, arc))
        return out

    # ------------------------------------------------------------------ batch

    def ik_batch(
        self, targets: npt.ArrayLike, reference_deg: npt.ArrayLike | None = None,
    ) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Vectorized IK for an (N, 4) or (N, 5) array of (x, y, z, pitch[, roll]).

        Returns (joints (N, 5) in degrees, NaN where unreachable; ok (N,) booleans). Per
        row, the solution nearest ``reference_deg`` (a (5,) or (N, 5) array; default:
        facing the target, elbow up). A NaN roll keeps the reference's wrist roll (or 0).
        """
        return solve_batch(self, targets, reference_deg)


def _pose_args(
    x: object, y: object, z: object, pitch: object, roll: object,
) -> tuple[float, float, float, float, float | None]:
    """The pose numbers checked (``check_number``; roll None stays None): plain finite
    floats pass at once."""
    if (
        type(x) is float and type(y) is float and type(z) is float and type(pitch) is float
        and math.isfinite(x + y + z + pitch)  # a NaN or an infinity makes the sum one
        and (roll is None or (type(roll) is float and math.isfinite(roll)))
    ):
        return x, y, z, pitch, roll
    return (check_number("x_mm", x), check_number("y_mm", y), check_number("z_mm", z),
            check_number("pitch_deg", pitch),
            None if roll is None else check_number("roll_deg", roll))


def _joint_args(chain: ArmChain, joints_deg: Sequence[float]) -> tuple[float, ...]:
    """``chain._radians(joints_deg)``: five plain finite floats in a tuple or list pass
    at once (the common case: a measured pose), anything else is checked there."""
    if (type(joints_deg) is tuple or type(joints_deg) is list) and len(joints_deg) == 5:
        a, b, c, d, e = joints_deg
        if (
            type(a) is float and type(b) is float and type(c) is float
            and type(d) is float and type(e) is float and math.isfinite(a + b + c + d + e)
        ):
            return a * _RAD, b * _RAD, c * _RAD, d * _RAD, e * _RAD
    return chain._radians(joints_deg)


def _motion_cost(s: Sequence[float], current: Sequence[float]) -> tuple[float, float]:
    """The largest joint change (ties within TIE_RAD), then the sum of changes."""
    d = [abs(a - b) for a, b in zip(s, current, strict=True)]
    return (round(max(d) / TIE_RAD) * TIE_RAD, sum(d))


def _into(angle: float, lo: float, hi: float) -> float | None:
    """The representative of ``angle`` (mod 2 pi) within [lo, hi], clamped; or None."""
    a = lo + (angle - lo + LIMIT_TOL_RAD) % TAU - LIMIT_TOL_RAD
    if a > hi + LIMIT_TOL_RAD:
        return None
    return lo if a < lo else (hi if a > hi else a)


def _branch_ok(sols: list[tuple[float, ...]], x: float, y: float, back: bool,
               sign: float) -> bool:
    """Whether the branch (``back``, elbow ``sign``) is among solutions ``sols``."""
    # Identify the branch of each solution from its (wrapped) joint values.
    for s in sols:
        if _is_back(s[0], x, y) == back and (s[2] >= 0) == (sign > 0):
            return True
        if s[2] == 0.0:
            return True  # the two elbows coincide
    return False


def _is_back(t1: float, x: float, y: float) -> bool:
    """Whether base yaw ``t1`` faces away from the target's bearing."""
    if math.hypot(x, y) < AXIS_EPS_MM:
        return False
    return abs(wrap_rad(t1 - math.atan2(y, x))) > HALF_PI


def _cos_roots(roots: list[float], a: float, num: float, den: float) -> None:
    """Append the solutions q of ``den * cos(q - a) = num`` (none if |num/den| > 1)."""
    if den <= 0.0:
        return
    k = num / den
    if -1.0 <= k <= 1.0:
        b = math.acos(k)
        roots.extend((a + b, a - b))


def _arcs_between(roots: list[float]) -> list[tuple[float, float]]:
    """The arcs of the circle between consecutive sorted roots (the whole circle if none)."""
    if not roots:
        return [(-math.pi, math.pi)]
    arcs = [(roots[i], roots[i + 1]) for i in range(len(roots) - 1)]
    arcs.append((roots[-1], roots[0] + TAU))
    return [(lo, hi) for lo, hi in arcs if hi - lo > 1e-12]


def _merge_arcs(arcs: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Union of arcs on the circle, each as (lo in [-pi, pi), hi >= lo)."""
    if not arcs:
        return []
    norm = []
    for lo, hi in arcs:
        width = hi - lo
        if width >= TAU - 1e-12:
            return [(-math.pi, math.pi)]
        start = (lo + math.pi) % TAU - math.pi
        norm.append((start, start + width))
    norm.sort()
    merged: list[list[float]] = []
    for lo, hi in norm:
        if merged and lo <= merged[-1][1] + 1e-12:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    # An arc past +pi may join the first one.
    if len(merged) > 1 and merged[-1][1] >= merged[0][0] + TAU - 1e-12:
        last = merged.pop()
        merged[0] = [last[0], max(merged[0][1] + TAU, last[1])]
        if merged[0][1] - merged[0][0] >= TAU - 1e-12:
            return [(-math.pi, math.pi)]
        merged.sort()
    return [(lo, hi) for lo, hi in merged]


# Pose, Joints, wrap_deg and AXIS_EPS_MM are busarm.arm.chain's; they stay importable from
# here, where they have always been public.
__all__ = ["AXIS_EPS_MM", "ArmKinematics", "Joints", "Pose", "wrap_deg"]
