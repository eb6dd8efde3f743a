"""The arm's kinematic chain and its forward kinematics, in closed form. Pure: no bus, no I/O.

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

The inverse kinematics is ``busarm.arm.kinematics`` (``ArmKinematics``, this chain with
its solvers); the constants and angle helpers below are shared with the solvers.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from busarm.arm.config import Geometry
from busarm.errors import ConfigError
from busarm.units import fixed_number

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

    def __repr__(self) -> str:
        return (f"Pose(x_mm={fixed_number(self.x_mm)}, y_mm={fixed_number(self.y_mm)}, "
                f"z_mm={fixed_number(self.z_mm)}, pitch_deg={fixed_number(self.pitch_deg)}, "
                f"roll_deg={fixed_number(self.roll_deg)})")


def wrap_deg(angle_deg: float) -> float:
    """An angle in (-180, 180]."""
    a = math.fmod(angle_deg, 360.0)
    if a <= -180.0:
        a += 360.0
    elif a > 180.0:
        a -= 360.0
    return a


def wrap_rad(a: float) -> float:
    """An angle in (-pi, pi]."""
    a = math.fmod(a, TAU)
    if a <= -math.pi:
        a += TAU
    elif a > math.pi:
        a -= TAU
    return a


def check_number(name: str, value: object) -> float:
    """``value`` as a finite float; ConfigError naming ``name`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise ConfigError(f"{name} must be a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f"{name} = {value!r} must be finite")
    return v


def float_array(value: npt.ArrayLike, what: str) -> FloatArray:
    """``value`` as a float64 array; ConfigError naming ``what`` if it is not numbers."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be an array of numbers, got {value!r:.80}") from None


class ArmChain:
    """The 5-joint chain of one arm geometry with its joint limits, the table and the
    base keep-out (the arguments: see ``ArmKinematics``), and its forward kinematics.

    The underscored numbers (mm, radians) are what the solvers of
    ``busarm.arm.kinematics`` and ``busarm.arm.ik_batch`` compute with.
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

    def in_base(self, x_mm: float, y_mm: float, z_mm: float) -> bool:
        """Whether a tool point lies inside the keep-out cylinder round the base axis."""
        return z_mm < self._keep_top and math.hypot(x_mm, y_mm) < self._keep_r - 1e-9

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
        out = list(self._dh_products(joints_deg, len(self.dh_table())))
        tool = np.eye(4)
        tool[2, 3] = self._tool
        out.append(out[-1] @ tool)
        return out

    def frame(self, joints_deg: Sequence[float], index: int) -> FloatArray:
        """``frames(joints_deg)[index]`` for DH frame ``index + 1`` (0..4), without the
        frames after it (the same products in the same order)."""
        if not 0 <= index < len(self.dh_table()):
            raise IndexError(f"DH frame index {index} is out of range 0..4 (frames() has "
                             f"the tool's too)")
        *_, last = self._dh_products(joints_deg, index + 1)
        return last

    def _dh_products(self, joints_deg: Sequence[float], count: int) -> Iterator[FloatArray]:
        """DH frames 1..``count`` in the base frame, each the product of those before it
        and its own transform."""
        q = self._radians(joints_deg)
        t = np.eye(4)
        for i, (alpha, a, d) in enumerate(self.dh_table()[:count]):
            t = t @ _mdh(alpha, a, q[i], d)
            yield t

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

    # ------------------------------------------------------------------ checks

    def _radians(self, joints_deg: Sequence[float]) -> tuple[float, float, float, float, float]:
        if (
            isinstance(joints_deg, str | bytes) or not hasattr(joints_deg, "__len__")
            or len(joints_deg) != 5
        ):
            raise ConfigError(f"expected 5 joint angles in degrees, got {joints_deg!r}")
        a, b, c, d, e = (math.radians(check_number("joint angle", v)) for v in joints_deg)
        return a, b, c, d, e

    def _radians_deg_list(self, joints_deg: Sequence[float]) -> list[float]:
        return [math.degrees(v) for v in self._radians(joints_deg)]

    @staticmethod
    def _batch(joints_deg: npt.ArrayLike) -> FloatArray:
        q = float_array(joints_deg, "joint angles")
        if q.ndim != 2 or q.shape[1] != 5:
            raise ConfigError(f"joint angles must be an (N, 5) array, got shape {q.shape}")
        return q


def _mdh(alpha: float, a: float, theta: float, d: float) -> FloatArray:
    """Modified-DH link transform Rx(alpha) Tx(a) Rz(theta) Tz(d)."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([
        [ct, -st, 0.0, a],
        [st * ca, ct * ca, -sa, -sa * d],
        [st * sa, ct * sa, ca, ca * d],
        [0.0, 0.0, 0.0, 1.0],
    ])


__all__ = [
    "AXIS_EPS_MM",
    "ArmChain",
    "FloatArray",
    "Joints",
    "Pose",
    "check_number",
    "float_array",
    "wrap_deg",
    "wrap_rad",
]
