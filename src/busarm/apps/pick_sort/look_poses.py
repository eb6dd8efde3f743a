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

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import Joints
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


def _plane_grid(kin: ArmKinematics) -> FloatArray:
    """Shoulder, elbow, wrist pitch (deg) on the grid within their limits: (N, 3)."""
    (_, _), (lo2, hi2), (lo3, hi3), (lo4, hi4), _ = kin.limits_deg
    axes = [np.arange(max(lo2, SHOULDER_FROM_DEG), hi2 + 1e-9, GRID_DEG),
            np.arange(lo3, hi3 + 1e-9, GRID_DEG), np.arange(lo4, hi4 + 1e-9, GRID_DEG)]
    return np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)


def look_pose(kin: ArmKinematics, cam2link: FloatArray, surface_z_mm: float,
              distance_mm: float, camera_mm: float, max_tilt_deg: float,
              deck: tuple[float, float] = (0.0, 0.0), *, tilt_deg: float = 0.0) -> Joints:
    """Joints (base yaw 0, wrist roll 0) that aim the camera at the point ``distance_mm``
    straight ahead of the arm's axis on the surface at ``surface_z_mm``, from about
    ``camera_mm`` over it, the axis at most ``max_tilt_deg`` from straight down.
    ``deck``: (its reach from the axis, mm; the tool's least height over it, z 0).
    ``tilt_deg``: the tilt preferred (0: straight down; more to see things' sides).
    UnreachableError if no pose on the grid does."""
    q = _plane_grid(kin)
    q2, q3, q4 = np.radians(q).T
    g = kin.geometry
    # The wrist-pitch link's frame in the arm's plane (base yaw 0): its origin (the wrist
    # pitch axis) and its rotation Rx(-90) Rz(q2 + q3 + q4), as the modified DH gives it.
    rho = g.upper_arm_mm * np.cos(q2) + g.forearm_mm * np.cos(q2 + q3)
    z = g.base_height_mm - g.upper_arm_mm * np.sin(q2) - g.forearm_mm * np.sin(q2 + q3)
    a = q2 + q3 + q4
    ca, sa = np.cos(a), np.sin(a)
    rot = np.zeros((len(q), 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 2] = ca, -sa, 1.0
    rot[:, 2, 0], rot[:, 2, 1] = -sa, -ca
    origin = np.stack([rho, np.zeros_like(rho), z], axis=1)
    cam = origin + rot @ cam2link[:3, 3]
    axis = rot @ cam2link[:3, 2]  # the optical axis (OpenCV z)
    length = g.wrist_to_tip_mm
    tip_rho, tip_z = rho - length * sa, z - length * ca
    down = -axis[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (cam[:, 2] - surface_z_mm) / down
    hit_x, hit_y = cam[:, 0] + t * axis[:, 0], cam[:, 1] + t * axis[:, 1]
    aim = np.hypot(hit_x - distance_mm, hit_y)
    tilt = np.degrees(np.arccos(np.clip(down, -1.0, 1.0)))
    height = cam[:, 2] - surface_z_mm
    deck_r, deck_clear = deck
    near_deck = (tip_rho < deck_r) | (rho < deck_r)
    ok = ((down > 0.1) & (aim < AIM_MM) & (tilt <= max_tilt_deg)
          & (tip_z >= surface_z_mm + TOOL_CLEAR_MM)
          & (~near_deck | ((tip_z >= deck_clear) & (z >= deck_clear))))
    if not ok.any():
        raise UnreachableError(
            f"no look pose aims the camera at {distance_mm:.0f} mm ahead on the surface at "
            f"z {surface_z_mm:.0f} mm within {max_tilt_deg:g} deg of straight down")
    cost = np.abs(height - camera_mm) + TILT_WEIGHT_MM * np.abs(tilt - tilt_deg) + aim
    best = int(np.argmin(np.where(ok, cost, math.inf)))
    shoulder, elbow, wrist = (float(v) for v in q[best])
    return 0.0, shoulder, elbow, wrist, 0.0
