"""The twin's cameras (``Twin`` has them): renders of the simulation, ideal and through
the lens, for vision or as a live view, and snapshots of its state to draw from while
physics goes on."""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.twin.lens import LensSpec
from busarm.twin.model import M_PER_MM, MJ_FROM_CV
from busarm.twin.mujoco_gl import Renderers

__all__ = [
    "LIVE_DENSITY",
    "ImageArray",
    "TwinRendering",
    "live_render_size",
]


ImageArray = npt.NDArray[np.uint8]
FloatArray = npt.NDArray[np.float64]

LIVE_DENSITY = 0.75
"""A live wrist-camera frame's render has this share of the full render's pixels a
side (its centre is drawn a little softer; a CPU draws about half the pixels): a stream
for a person or a dashboard, not the pictures vision measures on."""


def live_render_size(width: int, height: int) -> tuple[int, int]:
    """The live render of a ``width`` x ``height`` view: the same vertical fov with
    ``LIVE_DENSITY`` of the pixels a side (the lens's tables are made for it; the margin
    of 2 keeps every ray of the lens inside)."""
    return 2 * math.ceil(width * LIVE_DENSITY / 2) + 2, 2 * math.ceil(height * LIVE_DENSITY / 2)


class TwinRendering:
    """What ``Twin`` draws with: its model, state, lock, lens and renderers."""

    mujoco: Any
    model: Any
    data: Any
    lens: LensSpec
    realtime: bool
    _renderers: Renderers
    _lock: threading.RLock
    _render_size: tuple[int, int]
    _live_render_size: tuple[int, int]
    _fovy_deg: float

    def sync(self) -> None:
        """Catch physics up with the clock (``Twin`` does)."""
        raise NotImplementedError

    def release_renderers(self) -> None:
        """Close the renderers this thread made (a GL context lives in its thread)."""
        self._renderers.release()

    def snapshot(self, into: Any = None) -> Any:
        """A copy of the simulation's state now (an ``MjData``), to render from later or
        in another thread while physics goes on (``render_ideal(data=...)``).

        ``into``: an earlier snapshot of this twin to overwrite (no new ``MjData``, which
        costs many times the copy: a camera stream recycles its frames' snapshots)."""
        if self.realtime:
            self.sync()
        copy_ = self.mujoco.MjData(self.model) if into is None else into
        with self._lock:
            self.mujoco.mj_copyData(copy_, self.model, self.data)
        return copy_

    def render_ideal(self, camera: str = "arm_camera", *, live: bool = False,
                     data: Any = None) -> ImageArray:
        """The ideal pinhole render (RGB) of a camera: no lens (``overview`` is 640x480).

        ``live``: a view for a person, drawn without shadows or antialiasing (on a CPU
        those are most of a frame's cost: several times cheaper), the arm camera's with
        ``LIVE_DENSITY`` of the render's pixels a side; the pictures vision works on keep
        them. ``data``: a ``snapshot()`` to draw instead of now.
        """
        size = ((self._live_render_size if live else self._render_size)
                if camera == "arm_camera" else (640, 480))
        renderer = self._renderers.get(self.model, *size, live)
        if data is not None:
            renderer.update_scene(data, camera=camera)
        else:
            if self.realtime:
                self.sync()
            with self._lock:
                renderer.update_scene(self.data, camera=camera)
        renderer.scene.flags[self.mujoco.mjtRndFlag.mjRND_SHADOW] = not live
        image: ImageArray = renderer.render()
        return image

    def render_camera(self, *, live: bool = False, data: Any = None) -> ImageArray:
        """The arm camera's image as the vision layer gets it: BGR, through the lens
        (``live``, ``data``: see ``render_ideal``)."""
        import cv2

        rgb = self.render_ideal("arm_camera", live=live, data=data)
        # The lens first, then the channels' order: the same pixels (the lens bends each
        # channel alike), with fewer of them to reorder.
        seen = self.lens.apply(rgb, self._fovy_deg if live else None)
        return np.asarray(cv2.cvtColor(seen, cv2.COLOR_RGB2BGR), dtype=np.uint8)

    def render_overview(self, *, live: bool = False) -> ImageArray:
        """The overview camera (BGR, 640x480, no lens): the whole table from above the front
        (``live``: see ``render_ideal``)."""
        import cv2

        return np.asarray(cv2.cvtColor(self.render_ideal("overview", live=live),
                                       cv2.COLOR_RGB2BGR), dtype=np.uint8)

    def cam2base_from_mujoco(self, camera: str = "arm_camera") -> FloatArray:
        """A camera's pose as MuJoCo has it, in OpenCV axes and mm (the arm camera's for
        tests; the overview's to draw on its pictures)."""
        with self._lock:
            cam = self.model.camera(camera).id
            out = np.eye(4)
            out[:3, :3] = self.data.cam_xmat[cam].reshape(3, 3) @ MJ_FROM_CV
            out[:3, 3] = self.data.cam_xpos[cam] / M_PER_MM
            return out
