"""Look poses chosen from the kinematics: joints that aim the wrist camera at a point on a
surface, from about a given height over it. Pure geometry: no bus, no camera.

The camera rides the wrist-pitch link (its pose there is the hand-eye calibration's), so
the base yaw turns the whole view and the wrist roll does not move it: the shoulder,
elbow and wrist pitch are searched on a grid in the arm's vertical plane, and the pose
whose optical axis meets the surface nearest the point (within ``AIM_MM``), from nearest
the asked height, within the asked tilt from straight down, with the tool kept off the
surface and off the deck near the arm, is the one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import Joints
from busarm.arm.config import Geometry
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import UnreachableError

__all__ = [
    "AIM_MM",
    "GRID_DEG",
    "SHOULDER_FROM_DEG",
    "TILT_WEIGHT_MM",
    "TOOL_CLEAR_MM",
    "FloatArray",
    "look_pose",
]


FloatArray = npt.NDArray[np.float64]

GRID_DEG = 2.5
"""The joints are searched this finely (the view moves about 20 mm a step at 500 mm)."""
AIM_MM = 20.0
"""The camera's axis meets the surface at most this far from the point."""
TOOL_CLEAR_MM = 80.0
"""A look keeps the tool point this high over the surface at least."""
TILT_WEIGHT_MM = 2.0
"""A degree of tilt from straight down costs as much as this many mm off the height."""
SHOULDER_FROM_DEG = -120.0
"""The shoulder is searched from here forward (leaning far back, the arm sees itself)."""


def _plane_grid(limits_deg: Sequence[tuple[float, float]]) -> FloatArray:
    """Shoulder, elbow, wrist pitch (deg) on the grid within their limits: (N, 3)."""
    (_, _), (lo2, hi2), (lo3, hi3), (lo4, hi4), _ = limits_deg
    axes = [np.arange(max(lo2, SHOULDER_FROM_DEG), hi2 + 1e-9, GRID_DEG),
            np.arange(lo3, hi3 + 1e-9, GRID_DEG), np.arange(lo4, hi4 + 1e-9, GRID_DEG)]
    return np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)


@dataclass(frozen=True)
class _Views:
    """Every grid pose whose camera looks down at all (the optical axis more than
    ``_MIN_DOWN`` below level), with what does not depend on the surface: one arm and
    camera mount's, worked out once (a look is asked several times a block)."""

    joints_deg: FloatArray  # (N, 3) shoulder, elbow, wrist pitch
    cam: FloatArray  # (N, 3) the camera's position, mm
    axis: FloatArray  # (N, 3) its optical axis
    tilt_deg: FloatArray  # the axis from straight down
    rho: FloatArray  # the wrist pitch axis: from the arm's axis, mm
    z: FloatArray  # ... and its height, mm
    tip_rho: FloatArray  # the tool point: from the arm's axis, mm
    tip_z: FloatArray  # ... and its height, mm


_MIN_DOWN = 0.1  # the optical axis's downward part: under it (84 deg from down) no view


@lru_cache(maxsize=2)  # about 18 MB each: a process has one arm and mount (two at a recalibration)
def _views(g: Geometry, limits_deg: tuple[tuple[float, float], ...],
           cam2link_bytes: bytes) -> _Views:
    cam2link = np.frombuffer(cam2link_bytes).reshape(4, 4)
    q = _plane_grid(limits_deg)
    q2, q3, q4 = np.radians(q).T
    # The wrist-pitch link's frame in the arm's plane (base yaw 0): its origin (the wrist
    # pitch axis) and its rotation Rx(-90) Rz(q2 + q3 + q4), as the modified DH gives it.
    rho = g.upper_arm_mm * np.cos(q2) + g.forearm_mm * np.cos(q2 + q3)
    z = g.base_height_mm - g.upper_arm_mm * np.sin(q2) - g.forearm_mm * np.sin(q2 + q3)
    a = q2 + q3 + q4
    ca, sa = np.cos(a), np.sin(a)
    # That rotation's rows are (ca, -sa, 0), (0, 0, 1), (-sa, -ca, 0).
    (ox, oy, oz), (zx, zy, zz) = cam2link[:3, 3], cam2link[:3, 2]
    down = sa * zx + ca * zy  # the optical axis (OpenCV z), downward
    keep = down > _MIN_DOWN
    ca, sa, rho, z, down = ca[keep], sa[keep], rho[keep], z[keep], down[keep]
    cam = np.stack([rho + ca * ox - sa * oy, np.full_like(rho, oz), z - sa * ox - ca * oy],
                   axis=1)
    axis = np.stack([ca * zx - sa * zy, np.full_like(rho, zz), -down], axis=1)
    tilt = np.degrees(np.arccos(np.clip(down, -1.0, 1.0)))
    length = g.wrist_to_tip_mm
    views = _Views(q[keep], cam, axis, tilt, rho, z, rho - length * sa, z - length * ca)
    for array in vars(views).values():
        array.flags.writeable = False  # shared by every later call
    return views


def look_pose(kin: ArmKinematics, cam2link: FloatArray, surface_z_mm: float,
              distance_mm: float, camera_mm: float, max_tilt_deg: float,
              deck: tuple[float, float] = (0.0, 0.0), *, tilt_deg: float = 0.0) -> Joints:
    """Joints (base yaw 0, wrist roll 0) that aim the camera at the point ``distance_mm``
    straight ahead of the arm's axis on the surface at ``surface_z_mm``, from about
    ``camera_mm`` over it, the axis at most ``max_tilt_deg`` from straight down.
    ``deck``: (its reach from the axis, mm; the tool's least height over it, z 0).
    ``tilt_deg``: the tilt preferred (0: straight down; more to see things' sides).
    UnreachableError if no pose on the grid does."""
    limits = tuple((float(lo), float(hi)) for lo, hi in kin.limits_deg)
    v = _views(kin.geometry, limits, np.ascontiguousarray(cam2link, dtype=np.float64).tobytes())
    cam, axis = v.cam, v.axis
    t = (cam[:, 2] - surface_z_mm) / -axis[:, 2]
    aim = np.hypot(cam[:, 0] + t * axis[:, 0] - distance_mm, cam[:, 1] + t * axis[:, 1])
    height = cam[:, 2] - surface_z_mm
    deck_r, deck_clear = deck
    near_deck = (v.tip_rho < deck_r) | (v.rho < deck_r)
    ok = ((aim < AIM_MM) & (v.tilt_deg <= max_tilt_deg)
          & (v.tip_z >= surface_z_mm + TOOL_CLEAR_MM)
          & (~near_deck | ((v.tip_z >= deck_clear) & (v.z >= deck_clear))))
    if not ok.any():
        raise UnreachableError(
            f"no look pose aims the camera at {distance_mm:.0f} mm ahead on the surface at "
            f"z {surface_z_mm:.0f} mm within {max_tilt_deg:g} deg of straight down")
    cost = np.abs(height - camera_mm) + TILT_WEIGHT_MM * np.abs(v.tilt_deg - tilt_deg) + aim
    best = int(np.argmin(np.where(ok, cost, math.inf)))
    shoulder, elbow, wrist = (float(x) for x in v.joints_deg[best])
    return 0.0, shoulder, elbow, wrist, 0.0
