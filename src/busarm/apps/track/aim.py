"""Aiming the wrist camera at a point on the table, through the arm's IK.

The camera looks straight down from a fixed height (the tool pointing down, as in the
arm's ``look`` pose): for a point on a plane (the top face of a block), the tool's
(x, y) that puts the image centre's ray through it is found by a fixed-point iteration
(the camera rides the wrist-pitch link beside the tool: with the tool pointing down at a
fixed height, where its centre's ray meets the plane is a fixed offset from the tool in
the arm's vertical plane, turned by the base: one IK solution, checked by casting the
ray, and a second if the measured joints were not quite pointing down). Pure geometry:
no bus, no camera.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import Joints
from busarm.errors import UnreachableError, VisionError
from busarm.perception.locate import BlockLocator
from busarm.vision.localize import table_points_from_pixels

__all__ = [
    "AIM_ITERATIONS",
    "AIM_TOLERANCE_MM",
    "DOWN_PITCH_DEG",
    "CameraAim",
    "FloatArray",
]


FloatArray = npt.NDArray[np.float64]

DOWN_PITCH_DEG = -90.0
"""The tool points straight down: so does the camera (busarm's look pose)."""
AIM_ITERATIONS = 6
AIM_TOLERANCE_MM = 0.2
"""The iteration stops once the centre's ray meets the plane this near the point."""


class CameraAim:
    """Joints that put the image centre over a point of the plane ``plane_z_mm``, the tool
    at ``tool_z_mm`` pointing down (see the module docstring)."""

    def __init__(self, locator: BlockLocator, tool_z_mm: float, plane_z_mm: float) -> None:
        self.locator = locator
        self.kin = locator.kin
        self.tool_z_mm = float(tool_z_mm)
        self.plane_z_mm = float(plane_z_mm)
        i = locator.intrinsics
        self.centre_px = ((i.width_px - 1) / 2.0, (i.height_px - 1) / 2.0)
        """The image's centre (OpenCV pixel centres): where the block is kept."""

    def cast(self, pixels_px: npt.ArrayLike, joints_deg: Sequence[float]) -> FloatArray:
        """(N, 2) pixels -> (N, 3) points on the plane, the arm at ``joints_deg``
        (VisionError for a pixel whose ray misses it)."""
        return table_points_from_pixels(pixels_px, self.locator.intrinsics,
                                        self.locator.cam2base(joints_deg), self.plane_z_mm)

    def centre_on_plane(self, joints_deg: Sequence[float]) -> tuple[float, float]:
        """Where the image centre's ray meets the plane, the arm at ``joints_deg``."""
        p = self.cast([self.centre_px], joints_deg)[0]
        return float(p[0]), float(p[1])

    def offset_mm(self, joints_deg: Sequence[float]) -> tuple[float, float]:
        """Where the centre's ray meets the plane in the arm's vertical plane: (along the
        arm from the tool point, to its left), mm. With the tool pointing down at a fixed
        height it is the same wherever the arm reaches (the camera's link keeps its tilt,
        and the base turns it all), so a point is aimed at in one step."""
        here = self.kin.fk(joints_deg)
        hx, hy = self.centre_on_plane(joints_deg)
        bearing = math.atan2(here.y_mm, here.x_mm)
        c, s = math.cos(bearing), math.sin(bearing)
        return (c * hx + s * hy - math.hypot(here.x_mm, here.y_mm), -s * hx + c * hy)

    def solve(self, x_mm: float, y_mm: float, current_deg: Sequence[float]) -> Joints:
        """Joints (nearest ``current_deg``) that aim the image centre at (x, y) on the
        plane; UnreachableError if the tool cannot be put where that needs it."""
        try:
            along, left = self.offset_mm(current_deg)
        except VisionError:
            raise UnreachableError("the camera does not look at the table from here") from None
        joints: Joints | None = None
        for _ in range(AIM_ITERATIONS):
            # The tool at (rho, bearing) puts the centre at R(bearing) (rho + along, left).
            r2 = x_mm * x_mm + y_mm * y_mm - left * left
            if r2 <= 0.0:
                raise UnreachableError(f"the camera cannot look down at ({x_mm:.0f}, "
                                       f"{y_mm:.0f}) mm: too near the arm's axis")
            rho = math.sqrt(r2) - along
            bearing = math.atan2(y_mm, x_mm) - math.atan2(left, rho + along)
            joints = self.kin.ik_best(rho * math.cos(bearing), rho * math.sin(bearing),
                                      self.tool_z_mm, DOWN_PITCH_DEG, current_deg=current_deg)
            hit = self._hit_or_none(joints)
            if hit is None:
                raise UnreachableError(f"the camera cannot look down at ({x_mm:.0f}, "
                                       f"{y_mm:.0f}) mm")
            if math.hypot(x_mm - hit[0], y_mm - hit[1]) <= AIM_TOLERANCE_MM:
                break
            along, left = self.offset_mm(joints)
        assert joints is not None
        return joints

    def _hit_or_none(self, joints_deg: Sequence[float]) -> tuple[float, float] | None:
        try:
            return self.centre_on_plane(joints_deg)
        except VisionError:
            return None
