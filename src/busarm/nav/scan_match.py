"""Where a scan fits a map best: a correlative search over a likelihood field.

The map's occupied cells become a likelihood field (each cell's distance to the nearest
occupied one, through OpenCV's distance transform; a return scores exp(-d^2 / 2 sigma^2)).
Around a guess (the odometry's), every pose on a grid of shifts and turns is scored at
once in numpy, then the search repeats finer around the best: coarse to fine, as
Olson's real-time correlative scan matching does. The answer says how sure it is: the
best score and the share of returns that landed near a surface.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D, wrap_rad
from busarm.nav.grid import OccupancyGrid

__all__ = [
    "INDEPENDENT_BEAMS",
    "NEAR_M",
    "OCCUPIED_P",
    "PRIOR_WEIGHT",
    "SIGMA_M",
    "Z_HIT",
    "Z_RAND",
    "FloatArray",
    "LikelihoodField",
    "Match",
    "match_scan",
    "mean_log_likelihood",
    "scan_points",
    "thinned",
]


FloatArray = npt.NDArray[np.float64]

SIGMA_M = 0.05
OCCUPIED_P = 0.65
NEAR_M = 0.1
"""A return this close to a mapped surface counts as matched."""
Z_HIT, Z_RAND = 0.95, 0.05
"""A return's likelihood in a filter's weighing: Z_HIT x the field's (near a surface) +
Z_RAND (anything: an unmapped box costs every pose alike)."""
INDEPENDENT_BEAMS = 10.0
"""Neighbouring beams see the same wall, so their errors are not independent: a scan's
mean log-likelihood counts as this many beams' (else one scan would crush the cloud)."""
PRIOR_WEIGHT = 0.05
"""A guess's prior, in the score's units (a mean likelihood, 0..1): a shift of one sigma
from it costs as much as 2.5 % of the returns moving off their surface."""


@dataclass(frozen=True)
class Match:
    pose: Pose2D
    """The sensor's pose that fits best."""
    score: float
    """Mean likelihood of the returns at that pose (0..1)."""
    matched_share: float
    """Share of the returns within NEAR_M of a mapped surface."""


class LikelihoodField:
    """Distance to the nearest occupied cell of a grid, and the likelihood of a return."""

    def __init__(self, grid: OccupancyGrid, sigma_m: float = SIGMA_M) -> None:
        import cv2

        self.spec = grid.spec
        occupied = grid.probability >= OCCUPIED_P
        free_of_hits = np.where(occupied, 0, 255).astype(np.uint8)
        dist_cells = cv2.distanceTransform(free_of_hits, cv2.DIST_L2, 5)
        self.distance_m = np.asarray(dist_cells, dtype=np.float64) * self.spec.resolution_m
        if not occupied.any():
            self.distance_m[:] = np.inf
        self.likelihood = np.exp(-np.square(self.distance_m) / (2 * sigma_m ** 2))
        # Row-major flat copies: the scoring reads four cells a point by one index each.
        self._likelihood_flat = np.ascontiguousarray(self.likelihood).ravel()
        self._near_flat = np.ascontiguousarray(self.distance_m <= NEAR_M).ravel()

    def score(self, points_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """For points of shape (..., N, 2): the mean likelihood (interpolated between
        cell centres, so that a shift smaller than a cell still counts) and the share
        within NEAR_M of a surface, over the last axis (outside the grid: 0)."""
        return self.score_xy(points_m[..., 0], points_m[..., 1])

    def score_xy(self, x_m: FloatArray, y_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``score`` of the points whose x and y are given apart, each of shape (..., N)."""
        like, inside, cell = self._interpolated(x_m, y_m)
        near = inside & self._near_flat.take(cell)
        shape = np.broadcast_shapes(np.shape(x_m), np.shape(y_m))
        return like.reshape(shape).mean(axis=-1), near.reshape(shape).mean(axis=-1)

    def likelihood_xy(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """``score_xy``'s mean likelihood alone (the share near a surface not counted)."""
        like, _, _ = self._interpolated(x_m, y_m)
        shape = np.broadcast_shapes(np.shape(x_m), np.shape(y_m))
        return np.asarray(like.reshape(shape).mean(axis=-1))

    def _interpolated(self, x_m: FloatArray, y_m: FloatArray
                      ) -> tuple[FloatArray, npt.NDArray[np.bool_], npt.NDArray[np.intp]]:
        """Each point's likelihood (flat), whether it is inside the grid, and its cell.
        (In place where it can: the searches score some hundred thousand points a scan.)"""
        s = self.spec
        fx = np.subtract(x_m, s.origin_x_m).ravel()
        fx /= s.resolution_m
        fx -= 0.5
        fy = np.subtract(y_m, s.origin_y_m).ravel()
        fy /= s.resolution_m
        fy -= 0.5
        c0, r0 = np.floor(fx), np.floor(fy)
        tx, ty = fx, fy
        tx -= c0
        ty -= r0
        inside = r0 >= 0
        inside &= r0 < s.height - 1
        inside &= c0 >= 0
        inside &= c0 < s.width - 1
        outside = ~inside
        # The cell below-left of each point (row-major; 0 outside, where it scores 0).
        w = s.width
        r0 *= w
        r0 += c0
        r0[outside] = 0.0
        cell = r0.astype(np.intp)
        lk = self._likelihood_flat
        # Bilinear: (1-ty) ((1-tx) a + tx b) + ty ((1-tx) c + tx d).
        low, low_right = lk.take(cell), lk.take(cell + 1)
        high, high_right = lk.take(cell + w), lk.take(cell + (w + 1))
        ux = 1 - tx
        low *= ux
        low_right *= tx
        low += low_right
        high *= ux
        high_right *= tx
        high += high_right
        np.subtract(1, ty, out=ux)
        low *= ux
        high *= ty
        low += high
        low[outside] = 0.0
        return low, inside, cell


def scan_points(bearings_rad: npt.ArrayLike, ranges_m: npt.ArrayLike) -> FloatArray:
    """A scan's returns in the sensor's own frame, shape (N, 2) (no-return beams left out)."""
    b = np.asarray(bearings_rad, dtype=np.float64).ravel()
    r = np.asarray(ranges_m, dtype=np.float64).ravel()
    ok = np.isfinite(r)
    return np.stack([r[ok] * np.cos(b[ok]), r[ok] * np.sin(b[ok])], axis=1)


def thinned(points: FloatArray, most: int) -> FloatArray:
    """At most ``most`` of the points, evenly spread."""
    if len(points) <= most:
        return points
    out: FloatArray = points[np.linspace(0, len(points) - 1, most).round().astype(int)]
    return out


def mean_log_likelihood(field: LikelihoodField, points: FloatArray) -> FloatArray:
    """Per pose, the mean log-likelihood of its returns (points (N, B, 2), map frame):
    log(Z_HIT x the field's + Z_RAND) averaged over each pose's B returns."""
    # One point per group: the field's mean over the last axis is each return's own.
    like = field.likelihood_xy(points[:, :, None, 0], points[:, :, None, 1])
    out: FloatArray = np.log(Z_HIT * like + Z_RAND).mean(axis=1)
    return out


def _search(field: LikelihoodField, local: FloatArray, guess: Pose2D, half_m: float,
            step_m: float, half_rad: float, step_rad: float,
            prior: tuple[Pose2D, float] | None = None) -> tuple[Pose2D, float, float]:
    shifts = np.arange(-half_m, half_m + step_m / 2, step_m)
    turns = np.arange(-half_rad, half_rad + step_rad / 2, step_rad)
    yaw = guess.yaw_rad + turns
    c, s = np.cos(yaw), np.sin(yaw)
    # Points turned by each candidate yaw: (T, N) x and y, then shifted by every (dx, dy).
    turned_x = c[:, None] * local[:, 0] - s[:, None] * local[:, 1]
    turned_y = s[:, None] * local[:, 0] + c[:, None] * local[:, 1]
    dx, dy = np.meshgrid(shifts, shifts, indexing="ij")
    offsets = np.stack([guess.x_m + dx.ravel(), guess.y_m + dy.ravel()], axis=1)  # (S, 2)
    score = field.likelihood_xy(  # candidates (T, S, N)
        turned_x[:, None, :] + offsets[None, :, None, 0],
        turned_y[:, None, :] + offsets[None, :, None, 1])
    if prior is not None:  # the odometry's word: far from it costs, where the map is flat
        centre, sigma_m = prior
        off2 = (offsets[:, 0] - centre.x_m) ** 2 + (offsets[:, 1] - centre.y_m) ** 2
        score = score - PRIOR_WEIGHT * off2[None, :] / (2 * sigma_m ** 2)
    t, k = np.unravel_index(int(np.argmax(score)), score.shape)
    pose = Pose2D(float(offsets[k, 0]), float(offsets[k, 1]), wrap_rad(float(yaw[t])))
    _, near = field.score_xy(turned_x[t] + offsets[k, 0], turned_y[t] + offsets[k, 1])
    return pose, float(score[t, k]), float(near)


def match_scan(field: LikelihoodField, bearings_rad: npt.ArrayLike, ranges_m: npt.ArrayLike,
               guess: Pose2D, *, window_m: float = 0.15, window_deg: float = 6.0,
               max_points: int = 180, prior_sigma_m: float | None = None) -> Match:
    """The sensor pose near ``guess`` (within ``window_m`` and ``window_deg``) at which the
    scan fits the map best; with ``prior_sigma_m``, ``guess`` is also believed that well
    (a shift from it costs PRIOR_WEIGHT x its square over 2 sigma^2): where the map cannot
    tell places apart (along a corridor, a bare wall), the guess stands."""
    local = scan_points(bearings_rad, ranges_m)
    if len(local) == 0:
        return Match(guess, 0.0, 0.0)
    local = thinned(local, max_points)  # the search's cost grows with the points
    res = field.spec.resolution_m
    prior = None if prior_sigma_m is None else (guess, prior_sigma_m)
    pose, score, near = _search(field, local, guess, window_m, res, math.radians(window_deg),
                                math.radians(1.0), prior)
    pose, score, near = _search(field, local, pose, res, res / 4, math.radians(1.0),
                                math.radians(0.25), prior)
    pose, score, near = _search(field, local, pose, res / 4, res / 16, math.radians(0.25),
                                math.radians(0.0625), prior)
    return Match(pose, score, near)
