"""Where the wrist camera sits on the arm: a rigid pose on one of its links.

The arm config's ``[camera]`` section gives the drawing's numbers (the vendor's bracket);
``CameraMount`` turns them into the 4x4 pose the vision code and the twin use. The real
pose of a real bracket comes from hand-eye calibration, never from here: the drawing is
for planning views and for building the twin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.arm.config import CameraConfig
from busarm.errors import ConfigError

__all__ = [
    "CameraMount",
    "FloatArray",
]


FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CameraMount:
    """Where the arm camera sits: a pose in the wrist-pitch link's DH frame (frame 4).

    ``cam2link`` follows OpenCV's camera axes (x right, y down, z forward), in mm.
    """

    cam2link: FloatArray

    @classmethod
    def from_config(cls, camera: CameraConfig | None) -> CameraMount:
        """The mount an arm config's ``[camera]`` draws; ConfigError if it has none."""
        if camera is None:
            raise ConfigError("the arm config has no [camera]: where does the wrist camera "
                              "sit? (see the shipped jetauto_pro.toml)")
        return cls.jetauto(camera.behind_mm, camera.above_mm, camera.tilt_deg)

    @classmethod
    def jetauto(cls, behind_mm: float = 51.0, above_mm: float = 64.0,
                tilt_deg: float = 0.0) -> CameraMount:
        """The vendor's mount: ``behind_mm`` behind and ``above_mm`` above the wrist pitch
        axis (field notes), looking along the tool, tilted ``tilt_deg`` toward it.

        In frame 4 the tool axis is +y and "above" (seen with the tool horizontal) is +x.
        """
        t = math.radians(tilt_deg)
        z_cam = np.array([-math.sin(t), math.cos(t), 0.0])   # forward, tilted down
        y_cam = np.array([-math.cos(t), -math.sin(t), 0.0])  # image down
        x_cam = np.cross(y_cam, z_cam)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2] = x_cam, y_cam, z_cam
        m[:3, 3] = (above_mm, -behind_mm, 0.0)
        return cls(m)

    def offset(self, translation_mm: tuple[float, float, float],
               rotation_deg: tuple[float, float, float]) -> CameraMount:
        """This mount moved by ``translation_mm`` and turned by ``rotation_deg`` (a rotation
        vector) in its own camera axes: how a real camera sits on its bracket."""
        rotvec = np.radians(np.asarray(rotation_deg, dtype=float))
        angle = float(np.linalg.norm(rotvec))
        rot = np.eye(3)
        if angle > 0:
            k = rotvec / angle
            kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            rot = np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx
        delta = np.eye(4)
        delta[:3, :3] = rot
        delta[:3, 3] = translation_mm
        return CameraMount(self.cam2link @ delta)
