"""A person sliding a block about the twin's table: ``BlockMover``.

The block follows a path on the table (``MoverPath``: waypoints, a circle, a
figure-eight, a seeded smooth walk) at a steady speed, reached over a short ramp from
rest. It is moved kinematically on the twin's own clock (simulated or real): before each
physics chunk (``Twin.physics_hooks``) its free joint is set to where the path has it then,
flat on the table and at the path's speed, so contacts and renders follow, and
``Twin.blocks()`` stays the truth of where it is.
"""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.twin.model import M_PER_MM
from busarm.twin.scene import Block, Scene
from busarm.twin.twin import Twin
from busarm.units import check_int_range, check_range

__all__ = [
    "DEFAULT_CENTRE_MM",
    "MAX_SPEED_MM_S",
    "PATH_KINDS",
    "RAMP_S",
    "BlockMover",
    "MoverPath",
    "circle_path",
    "eight_path",
    "named_path",
    "track_scene",
    "walk_path",
    "waypoints_path",
]


FloatArray = npt.NDArray[np.float64]

MAX_SPEED_MM_S = 200.0
"""A hand sliding a block: faster than any tracking is asked to follow."""
RAMP_S = 0.5
"""From rest to the path's speed (and the block starts where the path starts)."""
PATH_KINDS = ("circle", "eight", "walk")
"""The named paths (``named_path``); waypoints are given as points."""
DEFAULT_CENTRE_MM = (240.0, 0.0)
"""Where the named paths go round: in the arm's look-down view, where the camera can be
held straight over every point of them (180-300 mm from the arm's axis)."""
_STEP_MM = 1.0
"""The paths are polylines this fine (a curve's chords then sag well under 0.1 mm)."""


class MoverPath:
    """A path on the table (mm, base frame) walked at a steady speed along its length.

    ``closed``: it goes round for ever (a loop); else the block stops at its end."""

    def __init__(self, points_mm: npt.ArrayLike, closed: bool, name: str = "path") -> None:
        pts = np.asarray(points_mm, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
            raise ConfigError(f"a mover path needs two or more finite (x, y) points in mm, "
                              f"got shape {pts.shape}")
        if closed and not np.allclose(pts[0], pts[-1]):
            pts = np.vstack([pts, pts[:1]])
        seg = np.hypot(*np.diff(pts, axis=0).T)
        if float(seg.sum()) < 1.0:
            raise ConfigError(f"the mover path {name!r} is shorter than 1 mm")
        self.points_mm: FloatArray = pts
        self.closed = closed
        self.name = name
        self._cum: FloatArray = np.concatenate([[0.0], np.cumsum(seg)])

    def __repr__(self) -> str:
        return (f"MoverPath({self.name!r}, {self.length_mm:.0f} mm"
                f"{', closed' if self.closed else ''})")

    @property
    def length_mm(self) -> float:
        return float(self._cum[-1])

    def at(self, s_mm: float) -> tuple[float, float, float, float]:
        """(x, y, heading dx, dy) after ``s_mm`` along it (round again on a loop)."""
        cum = self._cum
        s = s_mm % self.length_mm if self.closed else min(max(s_mm, 0.0), self.length_mm)
        i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(cum) - 2))
        a, b = self.points_mm[i], self.points_mm[i + 1]
        span = cum[i + 1] - cum[i]
        t = 0.0 if span <= 0 else (s - cum[i]) / span
        d = (b - a) / span if span > 0 else np.zeros(2)
        return (float(a[0] + t * (b[0] - a[0])), float(a[1] + t * (b[1] - a[1])),
                float(d[0]), float(d[1]))

    def check_on(self, scene: Scene, margin_mm: float) -> None:
        """ConfigError naming the first point of the path off ``scene``'s table."""
        for x, y in self.points_mm:
            if not scene.table.contains(float(x), float(y), margin_mm):
                raise ConfigError(f"the mover path {self.name!r} leaves the table at "
                                  f"({x:.0f}, {y:.0f}) mm")


def _dense(points: FloatArray, closed: bool) -> FloatArray:
    """Points at most ``_STEP_MM`` apart along the polyline through ``points``."""
    pts = np.vstack([points, points[:1]]) if closed else points
    out = [pts[:1]]
    for a, b in itertools.pairwise(pts):
        n = max(1, math.ceil(float(np.linalg.norm(b - a)) / _STEP_MM))
        t = np.arange(1, n + 1)[:, None] / n
        out.append(a + t * (b - a))
    return np.vstack(out)


def _curve(fn: FloatArray, name: str) -> MoverPath:
    return MoverPath(_dense(fn, closed=True), closed=True, name=name)


def _check_centre(centre_mm: Sequence[float]) -> tuple[float, float]:
    if len(centre_mm) != 2:
        raise ConfigError(f"centre_mm = {tuple(centre_mm)!r}: expected (x, y) in mm")
    x, y = (check_range(n, v, -1000.0, 1000.0, "mm") for n, v in zip("xy", centre_mm,
                                                                      strict=True))
    return x, y


def circle_path(centre_mm: Sequence[float] = DEFAULT_CENTRE_MM,
                radius_mm: float = 50.0) -> MoverPath:
    """A circle, counter-clockwise, starting on its +x side."""
    cx, cy = _check_centre(centre_mm)
    r = check_range("radius_mm", radius_mm, 5.0, 500.0, "mm")
    a = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    return _curve(np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], axis=1), "circle")


def eight_path(centre_mm: Sequence[float] = DEFAULT_CENTRE_MM,
               half_x_mm: float = 40.0, half_y_mm: float = 80.0) -> MoverPath:
    """A figure-eight (a Lissajous 1:2 curve) through ``centre_mm``, its lobes along y."""
    cx, cy = _check_centre(centre_mm)
    hx = check_range("half_x_mm", half_x_mm, 5.0, 500.0, "mm")
    hy = check_range("half_y_mm", half_y_mm, 5.0, 500.0, "mm")
    a = np.linspace(0.0, 2 * math.pi, 720, endpoint=False)
    return _curve(np.stack([cx + hx * np.sin(2 * a), cy + hy * np.sin(a)], axis=1), "eight")


def walk_path(seed: int, centre_mm: Sequence[float] = DEFAULT_CENTRE_MM,
              half_extent_mm: tuple[float, float] = (45.0, 80.0), knots: int = 6) -> MoverPath:
    """A seeded smooth walk: a closed Catmull-Rom spline through ``knots`` random points
    within ``half_extent_mm`` (x, y) of ``centre_mm``, visited round the centre (so it
    never doubles back on itself sharply)."""
    check_int_range("seed", seed, 0, 2**32 - 1)
    check_int_range("knots", knots, 3, 20)
    cx, cy = _check_centre(centre_mm)
    hx, hy = (check_range(n, v, 5.0, 500.0, "mm")
              for n, v in zip(("half_x_mm", "half_y_mm"), half_extent_mm, strict=True))
    rng = random.Random(seed)
    base = rng.uniform(0.0, 2 * math.pi)
    knots_xy = []
    for k in range(knots):
        a = base + 2 * math.pi * (k + rng.uniform(-0.2, 0.2)) / knots
        r = rng.uniform(0.6, 1.0)
        knots_xy.append((cx + hx * r * math.cos(a), cy + hy * r * math.sin(a)))
    p = np.asarray(knots_xy)
    t = np.linspace(0.0, 1.0, 120, endpoint=False)[:, None]
    pieces = []
    for k in range(knots):
        p0, p1, p2, p3 = (p[(k + j) % knots] for j in (-1, 0, 1, 2))
        pieces.append(0.5 * (2 * p1 + (p2 - p0) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t**2
                             + (3 * p1 - p0 - 3 * p2 + p3) * t**3))
    return _curve(np.vstack(pieces), f"walk {seed}")


def waypoints_path(points_mm: Sequence[Sequence[float]], *, closed: bool = False) -> MoverPath:
    """Straight legs through ``points_mm`` (x, y mm); ``closed``: back to the first."""
    pts = np.asarray(points_mm, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1:] != (2,) or len(pts) < 2:
        raise ConfigError(f"waypoints: expected two or more (x, y) points in mm, got "
                          f"{np.shape(pts)}")
    return MoverPath(_dense(pts, closed), closed=closed, name="waypoints")


def named_path(kind: str, seed: int = 0,
               centre_mm: Sequence[float] = DEFAULT_CENTRE_MM) -> MoverPath:
    """One of ``PATH_KINDS`` round ``centre_mm`` (a walk drawn from ``seed``)."""
    if kind == "circle":
        return circle_path(centre_mm)
    if kind == "eight":
        return eight_path(centre_mm)
    if kind == "walk":
        return walk_path(seed, centre_mm)
    raise ConfigError(f"mover path {kind!r}; allowed: {', '.join(PATH_KINDS)}")


def track_scene(color: str, start_mm: tuple[float, float] = DEFAULT_CENTRE_MM, *,
                others: Sequence[tuple[str, float, float]] = (("green", 330.0, -250.0),
                                                             ("blue", 330.0, 250.0)),
                size_mm: float = 30.0) -> Scene:
    """A table for the colour-tracking game: one block of ``color`` at ``start_mm`` (the
    one a mover slides: index 0), blocks of other colours out of its way, no trays."""
    blocks = [Block(color, *start_mm, size_mm=size_mm)]
    blocks += [Block(c, x, y, size_mm=size_mm) for c, x, y in others if c != color]
    return Scene(blocks=tuple(blocks), source=f"tracking a {color} block")


class BlockMover:
    """Slide block ``index`` of ``twin``'s scene along ``path`` at ``speed_mm_s`` (see the
    module docstring). ``start_after_s``: it rests at the path's start that long first.

    ``attach()`` puts the block at the path's start and starts the hand; ``detach()``
    lets the block go (it then rests where it is). ``where_mm(t_s)``: where the hand has it
    at the twin's time ``t_s``."""

    def __init__(self, twin: Twin, path: MoverPath, speed_mm_s: float, *, index: int = 0,
                 start_after_s: float = 0.0) -> None:
        if isinstance(index, bool) or not isinstance(index, int) or not (
                0 <= index < len(twin.scene.blocks)):
            raise ConfigError(f"block index {index!r} is out of range "
                              f"0..{len(twin.scene.blocks) - 1}")
        self.speed_mm_s = check_range("speed_mm_s", speed_mm_s, 0.0, MAX_SPEED_MM_S, "mm/s")
        self.start_after_s = check_range("start_after_s", start_after_s, 0.0, 3600.0, "s")
        block = twin.scene.blocks[index]
        path.check_on(twin.scene, block.radius_mm)
        self.twin, self.path, self.index = twin, path, index
        self._z_m = (twin.config.table_z_mm + block.size_mm / 2) * M_PER_MM
        joint = twin.model.joint(f"block{index}")
        self._qpos, self._dof = int(joint.qposadr[0]), int(joint.dofadr[0])
        half = math.radians(block.yaw_deg) / 2
        self._quat = (math.cos(half), 0.0, 0.0, math.sin(half))
        self._t0_s: float | None = None

    def distance_mm(self, t_s: float) -> float:
        """How far along the path the hand is at the twin's time ``t_s``: a constant
        acceleration over ``RAMP_S`` from rest, then the steady speed."""
        if self._t0_s is None:
            return 0.0
        t = max(t_s - self._t0_s, 0.0)
        if t <= RAMP_S:
            return 0.5 * self.speed_mm_s * t * t / RAMP_S
        return self.speed_mm_s * (t - RAMP_S / 2)

    def _speed_at(self, t_s: float) -> float:
        if self._t0_s is None:
            return 0.0
        t = max(t_s - self._t0_s, 0.0)
        s = self.speed_mm_s * min(t / RAMP_S, 1.0)
        if not self.path.closed and self.distance_mm(t_s) >= self.path.length_mm:
            return 0.0
        return s

    def where_mm(self, t_s: float) -> tuple[float, float]:
        x, y, _, _ = self.path.at(self.distance_mm(t_s))
        return x, y

    def attach(self) -> BlockMover:
        """Put the block at the path's start and move it from now on (the twin's time)."""
        x, y, _, _ = self.path.at(0.0)
        self.twin.place_block(self.index, x, y, math.degrees(2 * math.atan2(
            self._quat[3], self._quat[0])))
        with self.twin.lock:
            self._t0_s = self.twin.sim_time_s + self.start_after_s
            if self._hook not in self.twin.physics_hooks:
                self.twin.physics_hooks.append(self._hook)
        return self

    def detach(self) -> None:
        with self.twin.lock:
            if self._hook in self.twin.physics_hooks:
                self.twin.physics_hooks.remove(self._hook)
            self.twin.data.qvel[self._dof:self._dof + 6] = 0.0

    def _hook(self, t_s: float, chunk_s: float) -> None:
        """Before a physics chunk: the block where the hand has it, moving as the hand
        does (so the chunk's steps carry it on toward where it will be)."""
        x, y, dx, dy = self.path.at(self.distance_mm(t_s))
        v = self._speed_at(t_s) * M_PER_MM
        d = self.twin.data
        d.qpos[self._qpos:self._qpos + 3] = (x * M_PER_MM, y * M_PER_MM, self._z_m)
        d.qpos[self._qpos + 3:self._qpos + 7] = self._quat
        d.qvel[self._dof:self._dof + 6] = (v * dx, v * dy, 0.0, 0.0, 0.0, 0.0)
