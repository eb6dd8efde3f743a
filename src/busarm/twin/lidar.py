"""The mobile twin's Lidar: ray casting from the chassis's ``lidar`` site into the arena.

``TwinLidarWorld`` is the world a simulated RPLIDAR A1 (busarm.sim.rplidar) measures: for
a bearing in the Lidar's frame it casts one ray (``mj_ray``) in the Lidar's horizontal
plane from where the chassis is at that moment, so a scan taken while driving is skewed
as a spinning Lidar's is. The robot's own parts are not seen (their geom group is left
out: a real unit sees its mast and arm, which its owner masks). ``LidarNoise`` adds what a
triangulating Lidar adds: range noise growing with distance, and dropouts (random, and
at grazing incidence, where too little light comes back). ``true_ranges`` casts the same
rays all at once (``mj_multiRay``) without noise: the ground truth benchmarks compare
against, which the code under test never reads.

Everything goes through the A1's bytes: ``lidar_for_twin`` is the simulated device, read
by the same driver as a real one (busarm.lidar.rplidar).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.protocol.rplidar import A1_RANGE_MAX_M
from busarm.sim.rplidar import SimRplidar
from busarm.twin.model import ROBOT_GROUP

if TYPE_CHECKING:
    from busarm.twin.twin import Twin

__all__ = [
    "TWIN_LIDAR_HZ",
    "FloatArray",
    "LidarNoise",
    "TwinLidarWorld",
    "lidar_for_twin",
]


FloatArray = npt.NDArray[np.float64]

TWIN_LIDAR_HZ = 10.0
"""The twin's A1 spins at its fastest (the A1 runs 5.5-10 Hz)."""


@dataclass(frozen=True)
class LidarNoise:
    """Range noise (sigma = ``sigma_m`` + ``sigma_share`` x range) and dropouts."""

    sigma_m: float = 0.002
    sigma_share: float = 0.004
    dropout: float = 0.01
    """Share of returns lost at random."""
    grazing_deg: float = 80.0
    """Beyond this angle between the beam and a surface's normal there is no return."""

    @classmethod
    def none(cls) -> LidarNoise:
        return cls(0.0, 0.0, 0.0, 90.0)


class TwinLidarWorld:
    """Bearing (rad, counter-clockwise in the Lidar's frame) -> measured range (m, NaN: no
    return) in ``twin``'s arena, now. Thread-safe (it reads the twin under its lock)."""

    def __init__(self, twin: Twin, noise: LidarNoise | None = None, seed: int = 0) -> None:
        if twin.arena is None:
            raise ConfigError("the twin has no arena (no mobile robot, so no Lidar): open it "
                              "with family=arena or arena=FILE")
        self.twin = twin
        self.noise = noise if noise is not None else LidarNoise()
        self._np_rng = np.random.default_rng(seed)
        self._site = twin.model.site("lidar").id
        self._groups = np.ones(6, dtype=np.uint8)
        self._groups[ROBOT_GROUP] = 0

    def _origin(self) -> tuple[FloatArray, FloatArray]:
        d = self.twin.data
        return (np.array(d.site_xpos[self._site]),
                np.array(d.site_xmat[self._site]).reshape(3, 3))

    def __call__(self, bearing_rad: float) -> float:
        return self.ranges([bearing_rad])[0]

    def ranges(self, bearings_rad: Sequence[float]) -> list[float]:
        """Measured ranges at several bearings, cast together (the simulated A1 asks for
        a batch of nodes at once): as ``__call__`` for each, one ray cast for all."""
        dist, normals, vec = self._cast(np.asarray(bearings_rad, dtype=np.float64))
        n = self.noise
        keep = (dist >= 0) & (dist <= A1_RANGE_MAX_M)
        if n.grazing_deg < 90.0:
            cos_inc = np.abs(np.einsum("ij,ij->i", normals, vec))
            keep &= cos_inc >= math.cos(math.radians(n.grazing_deg))
        if n.dropout:
            keep &= self._np_rng.random(len(dist)) >= n.dropout
        sigma = n.sigma_m + n.sigma_share * dist
        noisy = dist + self._np_rng.standard_normal(len(dist)) * sigma
        out: list[float] = np.where(keep, noisy, np.nan).tolist()
        return out

    def _cast(self, b: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Distances (-1: no hit), surface normals and unit directions of rays at ``b``."""
        mj = self.twin.mujoco
        dist = np.empty(len(b))
        geoms = np.empty(len(b), dtype=np.int32)
        normals = np.zeros(3 * len(b))
        with self.twin.lock:
            origin, rot = self._origin()
            vec = (rot @ np.stack([np.cos(b), np.sin(b), np.zeros_like(b)])).T.copy()
            mj.mj_multiRay(self.twin.model, self.twin.data, origin, vec.ravel(), self._groups,
                           1, -1, geoms, dist, normals, len(b), A1_RANGE_MAX_M)
        return dist, normals.reshape(-1, 3), vec

    def true_ranges(self, bearings_rad: npt.ArrayLike) -> FloatArray:
        """Noise-free ranges (m, NaN: nothing within the A1's reach) at each bearing, now."""
        dist, _normals, _vec = self._cast(np.asarray(bearings_rad, dtype=np.float64).ravel())
        return np.where((dist < 0) | (dist > A1_RANGE_MAX_M), np.nan, dist)


def lidar_for_twin(twin: Twin, *, scan_hz: float = TWIN_LIDAR_HZ,
                   noise: LidarNoise | None = None, seed: int = 0) -> SimRplidar:
    """A simulated A1 on ``twin``'s chassis, on the twin's clock (its bytes are what a real
    one sends: serve it on a pty, or read it in this process with ``SimTransport``)."""
    return SimRplidar(TwinLidarWorld(twin, noise, seed), scan_hz=scan_hz, clock=twin.clock,
                      seed=seed)
