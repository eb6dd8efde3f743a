"""Forward and inverse kinematics of the 5-joint arm, in closed form. Pure: no bus, no I/O.

Model (modified DH, Craig; lengths in mm, the names of ``Geometry``)::

    i  alpha(i-1)  a(i-1)        d(i)          theta(i)
    1      0         0           base_height   q1  base yaw
    2    -90         0           0             q2  shoulder pitch
    3      0         upper_arm   0             q3  elbow pitch
    4      0         forearm     0             q4  wrist pitch
    5    -90         0           wrist         q5  wrist roll
    tool: tool_mm further along z5 (the tool axis); the tool frame is frame 5 moved there.

q = (0, -90, 0, -90, 0) deg points the arm straight up. The base frame has z up
through the base yaw axis, x forward at q1 = 0, and its origin on the base plane.

Poses are ``(x_mm, y_mm, z_mm, pitch_deg, roll_deg)`` of the tool point:

- ``pitch`` is the tool axis' elevation above the horizontal, measured in the vertical
  plane through the base axis and the tool point, facing away from the base:
  -90 points straight down (top-down grasp), 0 horizontal and outward, 90 straight up,
  180 horizontal and pointing back at the base.
- ``roll`` turns the gripper about the tool axis; for a pose reached facing the target
  (base yaw = the target's bearing) it equals q5. For a top-down grasp the gripper's
  x axis points at bearing ``q1 - q5`` on the table.
- On the base axis itself (tool point within 1e-6 mm of it) the bearing is undefined:
  the forward kinematics uses q1, the inverse the current q1 (or 0).

Every target has up to four solutions: facing the target or reaching over the back
(q1 + 180, pitch mirrored, q5 + 180), each elbow up (q3 > 0) or down. ``ik`` returns all
that respect the joint limits and keep the tool point and the wrist above the table and
the tool point out of the base (a cylinder round the base axis, from the arm config).

The free-pitch solver finds, for each of the four branches, the pitches at which a
constraint becomes active (reach, each joint limit, the table): each is a root of
``cos(pitch - a) = b`` and so has a closed form. Between consecutive roots feasibility
cannot change, so one test per arc gives the feasible pitch intervals exactly.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from busarm.arm.config import ArmConfig, Geometry
from busarm.errors import ConfigError, UnreachableError

TAU = 2.0 * math.pi
HALF_PI = 0.5 * math.pi
AXIS_EPS_MM = 1e-6
"""A tool point closer than this to the base axis has no bearing of its own."""
LIMIT_TOL_RAD = 1e-7
"""Joint limits are met up to this (6e-6 deg), and results are clamped into them. Near
full stretch the elbow angle is only known to about sqrt(machine epsilon) ~ 1e-8 rad
from a position (the singularity), so a tighter tolerance would refuse poses that are
exactly at a limit; the clamp moves the tool point by under 3e-5 mm."""
TIE_RAD = 1e-9
"""Motion costs closer than this are a tie (broken by the sum of joint changes)."""
BATCH_CHUNK = 16384
"""Rows per pass of the vectorized IK."""
REACH_TOL = 1e-9
"""Relative slack on the law-of-cosines argument at full stretch."""

FloatArray = npt.NDArray[np.float64]
Joints = tuple[float, float, float, float, float]


class Pose(NamedTuple):
    """The tool point and the tool axis' direction (see the module docstring)."""

    x_mm: float
    y_mm: float
    z_mm: float
    pitch_deg: float
    roll_deg: float


def wrap_deg(angle_deg: float) -> float:
    """An angle in (-180, 180]."""
    a = math.fmod(angle_deg, 360.0)
    if a <= -180.0:
        a += 360.0
    elif a > 180.0:
        a -= 360.0
    return a


def _wrap_rad(a: float) -> float:
    a = math.fmod(a, TAU)
    if a <= -math.pi:
        a += TAU
    elif a > math.pi:
        a -= TAU
    return a


def _check_number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ConfigError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f"{name} = {value!r} must be finite")
    return v


@dataclass(frozen=True)
class _Failure:
    """Why one branch failed; the message is only built if every branch fails."""

    reason: str
    joint: int = -1
    value: float = 0.0
    extra: float = 0.0


class ArmKinematics:
    """FK and closed-form IK of one arm geometry with its joint limits.

    ``table_z_mm`` None switches the table check off (pure geometry); ``base_keepout_mm``
    (radius, top z) is the cylinder round the base axis the tool point keeps out of (None:
    none). Degrees and millimetres in and out.
    """

    def __init__(
        self,
        geometry: Geometry,
        limits_deg: Sequence[tuple[float, float]],
        *,
        table_z_mm: float | None = 0.0,
        base_keepout_mm: tuple[float, float] | None = None,
        joint_names: Sequence[str] = ("joint1", "joint2", "joint3", "joint4", "joint5"),
    ) -> None:
        if len(limits_deg) != 5 or len(joint_names) != 5:
            raise ConfigError("the arm has 5 joints: give 5 limit pairs and 5 names")
        self.geometry = geometry
        self.limits_deg = tuple((float(lo), float(hi)) for lo, hi in limits_deg)
        self.joint_names = tuple(joint_names)
        self.table_z_mm = table_z_mm
        self._h = geometry.base_height_mm
        self._a2 = geometry.upper_arm_mm
        self._a3 = geometry.forearm_mm
        self._d5 = geometry.wrist_mm
        self._tool = geometry.tool_mm
        self._L = geometry.wrist_to_tip_mm
        self._lim = tuple((math.radians(lo), math.radians(hi)) for lo, hi in self.limits_deg)
        self._lo = np.radians(np.array([lo for lo, _ in self.limits_deg]))
        self._hi = np.radians(np.array([hi for _, hi in self.limits_deg]))
        self._table = -math.inf if table_z_mm is None else float(table_z_mm)
        self.base_keepout_mm = base_keepout_mm
        self._keep_r, self._keep_top = (0.0, -math.inf) if base_keepout_mm is None else (
            float(base_keepout_mm[0]), float(base_keepout_mm[1]))
        a2, a3 = self._a2, self._a3
        self.max_reach_mm = a2 + a3 + self._L
        """Farthest tool point from the shoulder axis (any pitch)."""

    @classmethod
    def from_config(cls, config: ArmConfig, *, check_table: bool = True) -> ArmKinematics:
        """The arm of ``config``; ``check_table`` False: pure geometry (no table, no base)."""
        return cls(
            config.geometry, config.limits_deg,
            table_z_mm=config.table_z_mm if check_table else None,
            base_keepout_mm=config.base_keepout_mm if check_table else None,
            joint_names=[j.name for j in config.joints],
        )

    def in_base(self, x_mm: float, y_mm: float, z_mm: float) -> bool:
        """Whether a tool point lies inside the keep-out cylinder round the base axis."""
        return z_mm < self._keep_top and math.hypot(x_mm, y_mm) < self._keep_r - 1e-9

    # ------------------------------------------------------------------ forward

    def fk(self, joints_deg: Sequence[float]) -> Pose:
        """The tool pose for five joint angles (no limit check: any angles)."""
        q1, q2, q3, q4, q5 = self._radians(joints_deg)
        q23 = q2 + q3
        plane_pitch = -(q23 + q4) - HALF_PI
        rho = self._a2 * math.cos(q2) + self._a3 * math.cos(q23) + self._L * math.cos(plane_pitch)
        zeta = -self._a2 * math.sin(q2) - self._a3 * math.sin(q23) + self._L * math.sin(plane_pitch)
        if rho < -AXIS_EPS_MM:  # reaching over the back: the bearing is q1 + 180
            pitch, roll = math.pi - plane_pitch, q5 - math.pi
        else:
            pitch, roll = plane_pitch, q5
        return Pose(
            rho * math.cos(q1), rho * math.sin(q1), self._h + zeta,
            wrap_deg(math.degrees(pitch)), wrap_deg(math.degrees(roll)),
        )

    def fk_matrix(self, joints_deg: Sequence[float]) -> FloatArray:
        """tool2base: the 4x4 homogeneous transform of the tool frame, in mm."""
        out: FloatArray = self.fk_matrix_batch(np.asarray([self._radians_deg_list(joints_deg)]))[0]
        return out

    def frames(self, joints_deg: Sequence[float]) -> list[FloatArray]:
        """The 4x4 transforms of DH frames 1..5 and the tool, in the base frame (mm)."""
        q = self._radians(joints_deg)
        out = []
        t = np.eye(4)
        for i, (alpha, a, d) in enumerate(self.dh_table()):
            t = t @ _mdh(alpha, a, q[i], d)
            out.append(t.copy())
        tool = np.eye(4)
        tool[2, 3] = self._tool
        out.append(t @ tool)
        return out

    def dh_table(self) -> list[tuple[float, float, float]]:
        """(alpha(i-1) rad, a(i-1) mm, d(i) mm) for joints 1..5."""
        return [
            (0.0, 0.0, self._h),
            (-HALF_PI, 0.0, 0.0),
            (0.0, self._a2, 0.0),
            (0.0, self._a3, 0.0),
            (-HALF_PI, 0.0, self._d5),
        ]

    def fk_matrix_batch(self, joints_deg: npt.ArrayLike) -> FloatArray:
        """tool2base for each row of an (N, 5) array of joint angles in degrees: (N, 4, 4)."""
        q = np.radians(self._batch(joints_deg))
        q1, q2, q3, q4, q5 = q.T
        c1, s1 = np.cos(q1), np.sin(q1)
        c5, s5 = np.cos(q5), np.sin(q5)
        q23 = q2 + q3
        a = q23 + q4
        ca, sa = np.cos(a), np.sin(a)
        rho = self._a2 * np.cos(q2) + self._a3 * np.cos(q23) - self._L * sa
        zeta = -self._a2 * np.sin(q2) - self._a3 * np.sin(q23) - self._L * ca
        # In the arm plane (x forward, y = the pitch axis, z up) at q1 = 0:
        #   x5 = (c5 ca, -s5, -c5 sa), y5 = (-s5 ca, -c5, s5 sa), z5 = (-sa, 0, -ca).
        x5 = np.stack([c5 * ca, -s5, -c5 * sa], axis=-1)
        y5 = np.stack([-s5 * ca, -c5, s5 * sa], axis=-1)
        z5 = np.stack([-sa, np.zeros_like(sa), -ca], axis=-1)
        n = q.shape[0]
        out = np.zeros((n, 4, 4))
        for col, v in enumerate((x5, y5, z5)):
            out[:, 0, col] = c1 * v[:, 0] - s1 * v[:, 1]
            out[:, 1, col] = s1 * v[:, 0] + c1 * v[:, 1]
            out[:, 2, col] = v[:, 2]
        out[:, 0, 3] = rho * c1
        out[:, 1, 3] = rho * s1
        out[:, 2, 3] = self._h + zeta
        out[:, 3, 3] = 1.0
        return out

    def fk_batch(self, joints_deg: npt.ArrayLike) -> FloatArray:
        """Poses (N, 5: x, y, z, pitch, roll) for an (N, 5) array of joint angles in degrees."""
        q = np.radians(self._batch(joints_deg))
        q1, q2, q3, q4, q5 = q.T
        q23 = q2 + q3
        plane_pitch = -(q23 + q4) - HALF_PI
        rho = (self._a2 * np.cos(q2) + self._a3 * np.cos(q23)
               + self._L * np.cos(plane_pitch))
        zeta = (-self._a2 * np.sin(q2) - self._a3 * np.sin(q23)
                + self._L * np.sin(plane_pitch))
        back = rho < -AXIS_EPS_MM
        pitch = np.where(back, math.pi - plane_pitch, plane_pitch)
        roll = np.where(back, q5 - math.pi, q5)
        out = np.empty((q.shape[0], 5))
        out[:, 0] = rho * np.cos(q1)
        out[:, 1] = rho * np.sin(q1)
        out[:, 2] = self._h + zeta
        out[:, 3] = np.degrees(np.angle(np.exp(1j * pitch)))
        out[:, 4] = np.degrees(np.angle(np.exp(1j * roll)))
        return out

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
        x = _check_number("x_mm", x_mm)
        y = _check_number("y_mm", y_mm)
        z = _check_number("z_mm", z_mm)
        p = math.radians(_check_number("pitch_deg", pitch_deg))
        roll = None if roll_deg is None else math.radians(_check_number("roll_deg", roll_deg))
        current = None if current_deg is None else self._radians(current_deg)
        sols, _ = self._ik(x, y, z, p, roll, current)
        return self._ordered(sols, current)

    def ik_best(
        self, x_mm: float, y_mm: float, z_mm: float, pitch_deg: float,
        roll_deg: float | None = None, *, current_deg: Sequence[float] | None = None,
    ) -> Joints:
        """The solution nearest ``current_deg``; raises UnreachableError saying why if none."""
        x = _check_number("x_mm", x_mm)
        y = _check_number("y_mm", y_mm)
        z = _check_number("z_mm", z_mm)
        pd = _check_number("pitch_deg", pitch_deg)
        roll = None if roll_deg is None else math.radians(_check_number("roll_deg", roll_deg))
        current = None if current_deg is None else self._radians(current_deg)
        sols, failures = self._ik(x, y, z, math.radians(pd), roll, current)
        if not sols:
            raise self._unreachable((x, y, z), f"pitch {pd:g} deg", failures)
        return self._ordered(sols, current)[0]

    def _ik(
        self, x: float, y: float, z: float, p: float, roll: float | None,
        current: tuple[float, ...] | None,
    ) -> tuple[list[tuple[float, ...]], list[_Failure]]:
        failures: list[_Failure] = []
        L = self._L
        if z < self._table - 1e-9:
            return [], [_Failure("table", value=z)]
        if z - L * math.sin(p) < self._table - 1e-9:
            return [], [_Failure("wrist_table", value=z - L * math.sin(p))]
        r = math.hypot(x, y)
        if self.in_base(x, y, z):
            return [], [_Failure("base", value=r)]
        # On the base axis the target has no bearing: keep the current one.
        psi = math.atan2(y, x) if r >= AXIS_EPS_MM else (current[0] if current else 0.0)
        zeta = z - self._h
        a2, a3 = self._a2, self._a3
        (lo1, hi1), (lo2, hi2), (lo3, hi3), (lo4, hi4), (lo5, hi5) = self._lim
        sols: list[tuple[float, ...]] = []
        for back in (False, True):
            if back:
                t1, rho, q, r5 = psi + math.pi, -r, math.pi - p, None if roll is None else (
                    roll + math.pi)
            else:
                t1, rho, q, r5 = psi, r, p, roll
            t1w = _into(t1, lo1, hi1)
            if t1w is None:
                failures.append(_Failure("joint", 0, t1))
                continue
            if r5 is None:  # free roll: keep the current one, within the limits
                keep = current[4] if current is not None else 0.0
                t5w = _into(keep, lo5, hi5)
                if t5w is None:
                    t5w = min(max(keep, lo5), hi5)
            else:
                t5w = _into(r5, lo5, hi5)
                if t5w is None:
                    failures.append(_Failure("joint", 4, r5))
                    continue
            cq, sq = math.cos(q), math.sin(q)
            wr = rho - L * cq
            wz = zeta - L * sq
            d2 = wr * wr + wz * wz
            c3 = (d2 - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
            if c3 > 1.0:
                if c3 > 1.0 + REACH_TOL:
                    failures.append(_Failure("reach", value=math.sqrt(d2), extra=a2 + a3))
                    continue
                c3 = 1.0
            elif c3 < -1.0:
                if c3 < -1.0 - REACH_TOL:
                    failures.append(_Failure("reach_min", value=math.sqrt(d2), extra=abs(a2 - a3)))
                    continue
                c3 = -1.0
            s3 = math.sqrt(1.0 - c3 * c3)
            gamma = math.atan2(wz, wr)
            base3 = math.acos(c3)
            for sign in (1.0, -1.0):
                if sign < 0 and s3 == 0.0:
                    break  # fully stretched or folded: both elbows are the same solution
                t3 = sign * base3
                t2 = -(gamma + math.atan2(a3 * sign * s3, a2 + a3 * c3))
                t4 = -(q + HALF_PI) - t2 - t3
                t2w = _into(t2, lo2, hi2)
                if t2w is None:
                    failures.append(_Failure("joint", 1, t2))
                    continue
                t3w = _into(t3, lo3, hi3)
                if t3w is None:
                    failures.append(_Failure("joint", 2, t3))
                    continue
                t4w = _into(t4, lo4, hi4)
                if t4w is None:
                    failures.append(_Failure("joint", 3, t4))
                    continue
                sols.append((t1w, t2w, t3w, t4w, t5w))
        return sols, failures

    def _ordered(
        self, sols: list[tuple[float, ...]], current: tuple[float, ...] | None
    ) -> list[Joints]:
        if current is not None and len(sols) > 1:
            sols = sorted(sols, key=lambda s: _motion_cost(s, current))
        return [
            (math.degrees(a), math.degrees(b), math.degrees(c), math.degrees(d), math.degrees(e))
            for a, b, c, d, e in sols
        ]

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
        x = _check_number("x_mm", x_mm)
        y = _check_number("y_mm", y_mm)
        z = _check_number("z_mm", z_mm)
        roll = None if roll_deg is None else math.radians(_check_number("roll_deg", roll_deg))
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
        x = _check_number("x_mm", x_mm)
        y = _check_number("y_mm", y_mm)
        z = _check_number("z_mm", z_mm)
        pref = math.radians(_check_number("preferred_pitch_deg", preferred_pitch_deg))
        roll = None if roll_deg is None else math.radians(_check_number("roll_deg", roll_deg))
        current = None if current_deg is None else self._radians(current_deg)
        best: list[tuple[float, float]] = []  # (distance, world pitch)
        inset = math.radians(1e-6)
        for _, _, (lo, hi) in self._branch_arcs(x, y, z, roll, current):
            d_lo = _wrap_rad(pref - lo)
            if 0.0 <= (pref - lo) % TAU <= hi - lo:
                best.append((0.0, pref))
                continue
            width = hi - lo
            d_hi = _wrap_rad(pref - hi)
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
                for s in self._ik(x, y, z, pitch, roll, current)[0]:
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
            roots = sorted({_wrap_rad(q) for q in roots})
            for sign in (1.0, -1.0):
                for lo, hi in _arcs_between(roots):
                    mid = 0.5 * (lo + hi)
                    p_mid = _wrap_rad(math.pi - mid) if back else mid
                    if self._branch_ok(x, y, z, p_mid, roll, current, back, sign):
                        arc = (math.pi - hi, math.pi - lo) if back else (lo, hi)
                        out.append((back, sign, arc))
        return out

    def _branch_ok(
        self, x: float, y: float, z: float, p: float, roll: float | None,
        current: tuple[float, ...] | None, back: bool, sign: float,
    ) -> bool:
        sols = self._ik(x, y, z, p, roll, current)[0]
        # Identify the branch of each solution from its (wrapped) joint values.
        for s in sols:
            if _is_back(s[0], x, y) == back and (s[2] >= 0) == (sign > 0):
                return True
            if s[2] == 0.0:
                return True  # the two elbows coincide
        return False

    # ------------------------------------------------------------------ batch

    def ik_batch(
        self, targets: npt.ArrayLike, reference_deg: npt.ArrayLike | None = None,
    ) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        """Vectorized IK for an (N, 4) or (N, 5) array of (x, y, z, pitch[, roll]).

        Returns (joints (N, 5) in degrees, NaN where unreachable; ok (N,) booleans). Per
        row, the solution nearest ``reference_deg`` (a (5,) or (N, 5) array; default:
        facing the target, elbow up). A NaN roll keeps the reference's wrist roll (or 0).
        """
        t = _float_array(targets, "targets")
        if t.ndim != 2 or t.shape[1] not in (4, 5):
            raise ConfigError(f"targets must be an (N, 4) or (N, 5) array, got shape {t.shape}")
        n = t.shape[0]
        ref = None
        if reference_deg is not None:
            r = _float_array(reference_deg, "reference_deg")
            if r.shape not in ((5,), (n, 5)):
                raise ConfigError(f"reference_deg must be (5,) or ({n}, 5), got shape {r.shape}")
            ref = np.radians(np.broadcast_to(r, (n, 5)))
        joints = np.empty((n, 5))
        ok = np.empty(n, dtype=np.bool_)
        # Chunks that stay in the CPU cache run about a quarter faster than one huge pass.
        for i in range(0, n, BATCH_CHUNK):
            sl = slice(i, i + BATCH_CHUNK)
            joints[sl], ok[sl] = self._ik_chunk(t[sl], None if ref is None else ref[sl])
        return joints, ok

    def _ik_chunk(
        self, t: FloatArray, ref: FloatArray | None
    ) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
        n = t.shape[0]
        x, y, z = t[:, 0], t[:, 1], t[:, 2]
        p = np.radians(t[:, 3])
        roll = np.radians(t[:, 4]) if t.shape[1] == 5 else np.full(n, np.nan)
        default_roll = ref[:, 4] if ref is not None else np.zeros(n)
        free_roll = np.isnan(roll)
        L, a2, a3 = self._L, self._a2, self._a3
        r = np.hypot(x, y)
        on_axis = r < AXIS_EPS_MM
        psi = np.where(on_axis, ref[:, 0] if ref is not None else 0.0, np.arctan2(y, x))
        zeta = z - self._h
        sp, cp = np.sin(p), np.cos(p)
        above = (z >= self._table - 1e-9) & (z - L * sp >= self._table - 1e-9)
        above &= (z >= self._keep_top) | (r >= self._keep_r - 1e-9)  # outside the base
        finite = np.isfinite(t[:, :4]).all(axis=1)
        lo, hi = self._lo, self._hi
        best = np.full((5, n), np.nan)  # joint-major: each column write is contiguous
        best_cost = np.full(n, np.inf)
        best_total = np.full(n, np.inf)
        valid = above & finite
        for back in (False, True):
            sgn = -1.0 if back else 1.0
            t1 = psi + math.pi if back else psi
            # Plane pitch q = p (front) or pi - p (back): cos q = sgn cos p, sin q = sin p.
            wr = sgn * (r - L * cp)
            wz = zeta - L * sp
            c3 = (wr * wr + wz * wz - (a2 * a2 + a3 * a3)) * (0.5 / (a2 * a3))
            reach_ok = np.abs(c3) <= 1.0 + REACH_TOL
            np.clip(c3, -1.0, 1.0, out=c3)
            s3 = np.sqrt(1.0 - c3 * c3)
            gamma = np.arctan2(wz, wr)
            base3 = np.arccos(c3)
            q = (math.pi - p) if back else p
            r5 = np.where(free_roll, default_roll, roll + math.pi if back else roll)
            t1w, ok1 = _into_vec(t1, lo[0], hi[0])
            t5w, ok5 = _into_vec(r5, lo[4], hi[4])
            ok5 |= free_roll
            branch_ok = reach_ok & ok1 & ok5 & valid
            q4 = -(q + HALF_PI)
            a3s3 = a3 * s3
            a2c = a2 + a3 * c3
            for sign in (1.0, -1.0):
                t3 = base3 if sign > 0 else -base3
                t2 = -(gamma + np.arctan2(a3s3 if sign > 0 else -a3s3, a2c))
                t4 = q4 - t2 - t3
                t2w, ok2 = _into_vec(t2, lo[1], hi[1])
                t3w, ok3 = _into_vec(t3, lo[2], hi[2])
                t4w, ok4 = _into_vec(t4, lo[3], hi[3])
                ok = branch_ok & ok2 & ok3 & ok4
                cols = (t1w, t2w, t3w, t4w, t5w)
                if ref is None:
                    rank = (1.0 if back else 0.0) + (0.0 if sign > 0 else 0.5)
                    cost = np.where(ok, rank, np.inf)
                    total = cost
                else:
                    # The scalar rule: the largest joint change, then the sum of changes.
                    worst = np.abs(t1w - ref[:, 0])
                    total = worst.copy()
                    for j in range(1, 5):
                        dj = np.abs(cols[j] - ref[:, j])
                        np.maximum(worst, dj, out=worst)
                        total += dj
                    cost = np.where(ok, worst, np.inf)
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

    # ------------------------------------------------------------------ helpers

    def _radians(self, joints_deg: Sequence[float]) -> tuple[float, float, float, float, float]:
        if (
            isinstance(joints_deg, str | bytes) or not hasattr(joints_deg, "__len__")
            or len(joints_deg) != 5
        ):
            raise ConfigError(f"expected 5 joint angles in degrees, got {joints_deg!r}")
        a, b, c, d, e = (math.radians(_check_number("joint angle", v)) for v in joints_deg)
        return a, b, c, d, e

    def _radians_deg_list(self, joints_deg: Sequence[float]) -> list[float]:
        return [math.degrees(v) for v in self._radians(joints_deg)]

    @staticmethod
    def _batch(joints_deg: npt.ArrayLike) -> FloatArray:
        q = _float_array(joints_deg, "joint angles")
        if q.ndim != 2 or q.shape[1] != 5:
            raise ConfigError(f"joint angles must be an (N, 5) array, got shape {q.shape}")
        return q


def _motion_cost(s: Sequence[float], current: Sequence[float]) -> tuple[float, float]:
    """The largest joint change (ties within TIE_RAD), then the sum of changes."""
    d = [abs(a - b) for a, b in zip(s, current, strict=True)]
    return (round(max(d) / TIE_RAD) * TIE_RAD, sum(d))


def _float_array(value: npt.ArrayLike, what: str) -> FloatArray:
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be an array of numbers, got {value!r:.80}") from None


def _mdh(alpha: float, a: float, theta: float, d: float) -> FloatArray:
    """Modified-DH link transform Rx(alpha) Tx(a) Rz(theta) Tz(d)."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([
        [ct, -st, 0.0, a],
        [st * ca, ct * ca, -sa, -sa * d],
        [st * sa, ct * sa, ca, ca * d],
        [0.0, 0.0, 0.0, 1.0],
    ])


def _into(angle: float, lo: float, hi: float) -> float | None:
    """The representative of ``angle`` (mod 2 pi) within [lo, hi], clamped; or None."""
    a = lo + (angle - lo + LIMIT_TOL_RAD) % TAU - LIMIT_TOL_RAD
    if a > hi + LIMIT_TOL_RAD:
        return None
    return lo if a < lo else (hi if a > hi else a)


def _into_vec(
    angle: FloatArray, lo: float, hi: float
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    a = np.mod(angle - (lo - LIMIT_TOL_RAD), TAU)
    a += lo - LIMIT_TOL_RAD
    ok = a <= hi + LIMIT_TOL_RAD
    np.clip(a, lo, hi, out=a)
    return a, ok


def _is_back(t1: float, x: float, y: float) -> bool:
    """Whether base yaw ``t1`` faces away from the target's bearing."""
    if math.hypot(x, y) < AXIS_EPS_MM:
        return False
    return abs(_wrap_rad(t1 - math.atan2(y, x))) > HALF_PI


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


__all__ = ["AXIS_EPS_MM", "ArmKinematics", "Joints", "Pose", "wrap_deg"]
