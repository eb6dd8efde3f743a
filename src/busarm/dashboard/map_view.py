"""The map the page shows while a mobile job runs: what the job knows, drawn about once a
second.

The job's thread hands over a ``MapScene`` (the grid and what happened on it, in the
map's frame) at most every ``MAP_PERIOD_S`` (``MapView.due``): copies, so that the
server's thread draws it (busarm.nav.map_picture) while the job goes on. ``png()`` draws
the newest scene once and keeps its PNG for every page that asks (``GET /map.png``);
the scene's number is in each ``state`` message (``map``), so a page loads a new picture
only when there is one, and ``info()`` (``GET /api/map``) says where the map's metres
fall on it, so that a click on a map names a point there.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import cv2
import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D
from busarm.nav.grid import OccupancyGrid
from busarm.nav.map_picture import map_picture, picture_frame
from busarm.vision.annotate import draw_label, label_size

__all__ = [
    "EMPTY_PX",
    "MAP_PERIOD_S",
    "Image",
    "MapScene",
    "MapView",
    "Point",
]


Image = npt.NDArray[np.uint8]
Point = tuple[float, float]

MAP_PERIOD_S = 1.0
"""A job hands the page a new map picture at most this often."""
EMPTY_PX = (480, 360)


@dataclass(frozen=True)
class MapScene:
    """What the map view draws (m, the map's frame; ``title`` above it)."""

    grid: OccupancyGrid
    title: str
    path: tuple[Point, ...] = ()
    """The path driven."""
    plans: tuple[tuple[Point, ...], ...] = ()
    pose: Pose2D | None = None
    """Where the base is now."""
    returns: tuple[Point, ...] = ()
    """The latest Lidar returns."""
    marks: Mapping[str, Point] = field(default_factory=dict)
    frame: str = "map"
    """``map``: the frame of the named points (a click there names one); ``odometry``:
    where the base started (line following's picture)."""

    def picture(self) -> Image:
        image = map_picture(self.grid, path=self.path, plans=self.plans,
                            marks=dict(self.marks), returns=self.returns, pose=self.pose)
        return _titled(image, self.title)


def _titled(image: Image, title: str) -> Image:
    w, h = label_size(title, swatch=False)
    draw_label(image, title, (2, 2, 2 + w, 2 + h))
    return image


class MapView:
    """The newest ``MapScene`` of the running (or last) mobile job, as a PNG on demand."""

    def __init__(self, period_s: float = MAP_PERIOD_S) -> None:
        self.period_s = period_s
        self._lock = threading.Lock()
        self._scene: MapScene | None = None
        self._sequence = 0
        self._shown_at = -math.inf
        self._png: tuple[int, bytes] | None = None

    @property
    def sequence(self) -> int:
        """The number of the newest scene (0: none yet)."""
        return self._sequence

    def due(self) -> bool:
        """Whether a new scene is wanted (the last is ``period_s`` old): a job builds one
        only then, and its copies cost nothing on the other scans."""
        return time.monotonic() - self._shown_at >= self.period_s

    def show(self, scene: MapScene) -> None:
        """Make ``scene`` the newest (from the job's thread)."""
        with self._lock:
            self._scene = scene
            self._sequence += 1
            self._shown_at = time.monotonic()

    def info(self) -> dict[str, object]:
        """The newest scene's number, frame, and where its metres fall on its picture."""
        with self._lock:
            scene, sequence = self._scene, self._sequence
        if scene is None:
            return {"sequence": sequence, "frame": None}
        f = picture_frame(scene.grid)
        return {"sequence": sequence, "frame": scene.frame, "origin_x_m": f.origin_x_m,
                "origin_y_m": f.origin_y_m, "px_per_m": f.px_per_m, "width_px": f.width_px,
                "height_px": f.height_px, "marks": {k: list(v) for k, v in scene.marks.items()}}

    def png(self) -> tuple[int, bytes]:
        """(the scene's number, its picture as PNG); drawn once per scene."""
        with self._lock:
            scene, sequence, kept = self._scene, self._sequence, self._png
        if kept is not None and kept[0] == sequence:
            return kept
        image = scene.picture() if scene is not None else _titled(
            np.full((EMPTY_PX[1], EMPTY_PX[0], 3), 128, np.uint8),
            "no map yet: transport maps the arena first (on a twin), or start with --map")
        ok, data = cv2.imencode(".png", image)
        if not ok:  # not expected of an 8-bit BGR picture; the page keeps its last one
            raise RuntimeError("the map picture could not be encoded as PNG")
        drawn = (sequence, bytes(data))
        with self._lock:
            if self._sequence == sequence:
                self._png = drawn
        return drawn
