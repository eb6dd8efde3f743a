"""Where else the base could be: poses a room's scans cannot yet tell apart.

A particle filter gathers on one pose even where the room looks the same from two (a
symmetric room: its mirror image; a long bare wall: anywhere along it), because
resampling keeps one cloud and starves the others (AMCL's particle deprivation). So
before a global localisation is believed, the scan is matched over the whole map
(``find_rivals``: a coarse correlative search on a broad likelihood field, its peaks
refined on the sharp one) and every pose that fits about as well as the cloud's becomes
a hypothesis. ``Hypotheses`` then moves each with the odometry and counts, scan after
scan, the returns that land on floor the map knows is free, far from every mapped
surface there (``MISS_M``): something there that the map says is not. Only such misses
tell places apart: a map is never drawn exactly alike twice (a big room's far walls a
few centimetres off square), and a likelihood would add up such differences, scan after
scan, into a wrong choice; a return on what the map never saw says nothing either way.
Once every other place has missed ``DECIDE_MISSES`` more returns than one, the room has
told them apart; one ``DROP_MISSES`` behind is dropped. While two remain, nothing should
drive to a goal on either: a room exactly symmetric never decides, and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.base.odometry import Pose2D, wrap_rad
from busarm.nav.mapping import compose, inverse
from busarm.nav.scan_match import (
    INDEPENDENT_BEAMS,
    LikelihoodField,
    match_scan,
    mean_log_likelihood,
    thinned,
)

__all__ = [
    "DECIDE_MISSES",
    "DISTINCT_M",
    "DISTINCT_RAD",
    "DROP_MISSES",
    "MISS_M",
    "RIVAL_LOG",
    "SEARCH_STEP_M",
    "SEARCH_STEP_RAD",
    "Hypotheses",
    "Hypothesis",
    "find_rivals",
    "log_fit",
]


FloatArray = npt.NDArray[np.float64]

SEARCH_STEP_M, SEARCH_STEP_RAD = 0.15, math.radians(6.0)
SEARCH_BEAMS = 72
SEARCH_CANDIDATES = 40
"""The best coarse poses refined (after keeping only one per DISTINCT neighbourhood)."""
DISTINCT_M, DISTINCT_RAD = 0.5, math.radians(30.0)
"""Two poses are different places when this far apart in position or in heading."""
RIVAL_LOG = 6.0
"""A pose is a rival when one scan's fit there is within this (log) of the best's."""
MISS_M = 0.25
"""A return farther than this from every mapped surface is a miss: more than a map's
drawing errors, less than what a thing the map has elsewhere leaves."""
DECIDE_MISSES = 12.0
"""Returns on no mapped surface, more at every other place than at the chosen one."""
DROP_MISSES = 40.0
FOLLOW_WINDOW_M, FOLLOW_WINDOW_DEG = 0.06, 2.0
"""Each hypothesis is re-matched this near itself every scan (the odometry drifts)."""


def log_fit(field: LikelihoodField, local: FloatArray, poses: FloatArray) -> FloatArray:
    """For sensor poses (N, 3) in the map's frame: the scan's log-likelihood there, as
    the filter weighs it (``local``: the returns (B, 2), sensor frame)."""
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
    x = poses[:, 0:1] + c * local[:, 0] - s * local[:, 1]
    y = poses[:, 1:2] + s * local[:, 0] + c * local[:, 1]
    out: FloatArray = INDEPENDENT_BEAMS * mean_log_likelihood(field, np.stack([x, y], -1))
    return out


def _distinct(a: Pose2D, b: Pose2D) -> bool:
    return (math.dist((a.x_m, a.y_m), (b.x_m, b.y_m)) > DISTINCT_M
            or abs(wrap_rad(a.yaw_rad - b.yaw_rad)) > DISTINCT_RAD)


def _coarse(broad: LikelihoodField, local: FloatArray, free_xy: FloatArray) -> FloatArray:
    """Every free position (on a SEARCH_STEP_M lattice) at every SEARCH_STEP_RAD heading,
    scored on the broad field: (P, 4) of x, y, yaw, score, best first."""
    keys = np.unique(np.round(free_xy / SEARCH_STEP_M).astype(np.int64), axis=0)
    xy = keys * SEARCH_STEP_M
    yaws = np.arange(-math.pi, math.pi, SEARCH_STEP_RAD)
    pts = thinned(local, SEARCH_BEAMS)
    c, s = np.cos(yaws), np.sin(yaws)
    turned_x = c[:, None] * pts[:, 0] - s[:, None] * pts[:, 1]  # (T, B)
    turned_y = s[:, None] * pts[:, 0] + c[:, None] * pts[:, 1]
    out = []
    for chunk in np.array_split(xy, max(1, len(xy) // 400)):
        score = broad.likelihood_xy(turned_x[:, None, :] + chunk[None, :, None, 0],
                                    turned_y[:, None, :] + chunk[None, :, None, 1])  # (T, P)
        t = np.argmax(score, axis=0)  # the best heading at each position
        out.append(np.column_stack([chunk, yaws[t], score[t, np.arange(len(chunk))]]))
    cells = np.concatenate(out)
    order: npt.NDArray[np.intp] = np.argsort(-cells[:, 3])
    result: FloatArray = cells[order]
    return result


def find_rivals(sharp: LikelihoodField, broad: LikelihoodField, local: FloatArray,
                free_xy: FloatArray, best: Pose2D) -> tuple[Pose2D, list[tuple[Pose2D, float]]]:
    """``best`` (a sensor pose) refined, and the sensor poses over the whole map where the
    scan (``local``, sensor frame) fits within RIVAL_LOG of how it fits there or better,
    each refined alike, distinct from it and from each other, with their fit
    (``log_fit`` on ``sharp``)."""
    if len(local) == 0:
        return best, []
    found: list[Pose2D] = [best]
    for x, y, yaw, _ in _coarse(broad, local, free_xy):
        guess = Pose2D(float(x), float(y), float(yaw))
        if not all(_distinct(guess, f) for f in found):
            continue
        found.append(guess)
        if len(found) > SEARCH_CANDIDATES:
            break
    b = np.arctan2(local[:, 1], local[:, 0])
    r = np.hypot(local[:, 0], local[:, 1])
    # Every one refined alike (the cloud's mean, too, may be a degree off): a rival is
    # judged against the best its neighbourhood offers, not against a rough guess.
    best, *refined = [match_scan(sharp, b, r, g, window_m=SEARCH_STEP_M,
                                 window_deg=math.degrees(SEARCH_STEP_RAD)).pose for g in found]
    poses = np.array([[p.x_m, p.y_m, p.yaw_rad] for p in (best, *refined)])
    fits = log_fit(sharp, local, poses)
    out: list[tuple[Pose2D, float]] = []
    for pose, fit in zip(refined, fits[1:], strict=True):
        if fit >= fits[0] - RIVAL_LOG and _distinct(pose, best) and all(
                _distinct(pose, p) for p, _ in out):
            out.append((pose, float(fit)))
    return best, out


def _misses(field: LikelihoodField, free: npt.NDArray[np.bool_], local: FloatArray,
            sensor: Pose2D) -> int:
    """How many returns (sensor frame) seen from ``sensor`` land on known free floor
    (``free``, the grid's cells) farther than MISS_M from every mapped surface."""
    c, s = math.cos(sensor.yaw_rad), math.sin(sensor.yaw_rad)
    x = sensor.x_m + c * local[:, 0] - s * local[:, 1]
    y = sensor.y_m + s * local[:, 0] + c * local[:, 1]
    rows, cols = field.spec.cells(np.column_stack([x, y]))
    inside = field.spec.inside(rows, cols)
    r, k = rows[inside], cols[inside]
    return int(np.count_nonzero(free[r, k] & (field.distance_m[r, k] > MISS_M)))


@dataclass
class Hypothesis:
    """One place the base may be (its pose, map frame), and the returns that have landed
    on no mapped surface there so far."""

    pose: Pose2D
    misses: float = 0.0


class Hypotheses:
    """Places the base may be (its poses, map frame; its Lidar at ``mount`` on it),
    followed by the odometry and told apart by the scans (see the module docstring);
    ``free``: which of the map's cells are known free floor."""

    def __init__(self, sharp: LikelihoodField, free: npt.NDArray[np.bool_], mount: Pose2D,
                 places: list[Pose2D]) -> None:
        self.field, self.free = sharp, free
        self.mount = mount
        self.places = [Hypothesis(p) for p in places]
        self.scans = 0

    def __repr__(self) -> str:
        return f"Hypotheses({len(self.places)} places, {self.scans} scans)"

    def move(self, moved: Pose2D) -> None:
        """Each place moved by the base's motion ``moved`` (in its own frame then)."""
        for h in self.places:
            h.pose = compose(h.pose, moved)

    def weigh(self, local: FloatArray) -> None:
        """Each place re-matched near itself and credited with the scan's fit there;
        the far-behind dropped."""
        if len(local) == 0 or not self.places:
            return
        b = np.arctan2(local[:, 1], local[:, 0])
        r = np.hypot(local[:, 0], local[:, 1])
        back = inverse(self.mount)
        for h in self.places:
            found = match_scan(self.field, b, r, compose(h.pose, self.mount),
                               window_m=FOLLOW_WINDOW_M, window_deg=FOLLOW_WINDOW_DEG)
            h.pose = compose(found.pose, back)
            h.misses += _misses(self.field, self.free, local, found.pose)
        best = min(h.misses for h in self.places)
        self.places = [h for h in self.places if h.misses <= best + DROP_MISSES]
        self.scans += 1

    @property
    def leader(self) -> Hypothesis:
        return min(self.places, key=lambda h: h.misses)

    def decided(self) -> Pose2D | None:
        """The place the scans have chosen, or None while another is still close."""
        if not self.places:
            return None
        lead = self.leader
        if all(h is lead or h.misses >= lead.misses + DECIDE_MISSES for h in self.places):
            return lead.pose
        return None
