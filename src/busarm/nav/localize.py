"""Where the base is on a saved map: Monte Carlo localisation as ROS's AMCL does it.

A cloud of particles (poses of the base in the map's frame) moves with the odometry,
each with noise that grows with how far and how much it moved (AMCL's omni model). Each
scan weighs them by how well its returns land on the map's surfaces: the likelihood
field of ``busarm.nav.scan_match``, mixed with a uniform share (``Z_RAND``) so that a
return off something unmapped (a box not on the map) costs every particle alike. The
cloud is resampled (low variance) only after motion and only when too few particles
carry the weight; its size adapts (KLD sampling: many while the pose is unknown, few
once it is found). When the scans fit worse than they have lately (augmented MCL: the
short-term average ``w_fast`` below the long-term ``w_slow``) random particles go to the
map's free cells, so that a robot carried elsewhere is found again. The estimate is the
weighted mean of the heaviest cluster, refined by a scan match once the cloud gathered.

A cloud gathered after ``start_anywhere`` is not yet believed: the scan is matched over
the whole map for other poses that fit it about as well (``busarm.nav.hypotheses``: a
symmetric room's mirror image, a place along a bare wall), and while any remains the
estimate is not converged (``PoseEstimate.rivals`` says how many). The odometry carries
them all, the scans tell them apart; the one they choose is where the cloud goes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from busarm.base.config import Mount
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.nav.grid import OccupancyGrid
from busarm.nav.hypotheses import Hypotheses, find_rivals
from busarm.nav.map_files import FREE_THRESH
from busarm.nav.mapping import MIN_MATCHED_SHARE, compose, inverse
from busarm.nav.scan_match import (
    INDEPENDENT_BEAMS,
    SIGMA_M,
    LikelihoodField,
    match_scan,
    mean_log_likelihood,
    scan_points,
    thinned,
)
from busarm.units import check_int_range, check_range

__all__ = [
    "BROAD_SIGMA_M",
    "CHOSEN_SIGMA_M",
    "CHOSEN_SIGMA_RAD",
    "CLUSTER_BIN_M",
    "CLUSTER_FLOOR",
    "FIT_SAMPLE",
    "GOOD_FIT",
    "INDEPENDENT_BEAMS",
    "INJECT_MIN",
    "SHARP_SIGMA_M",
    "FloatArray",
    "MotionNoise",
    "ParticleFilter",
    "PoseEstimate",
]


FloatArray = npt.NDArray[np.float64]

BROAD_SIGMA_M = 0.2
"""Until the cloud gathers, returns are scored on a field this broad: the particles lie
too sparsely for the sharp field to find the ones near the truth."""
ALPHA_SLOW, ALPHA_FAST = 0.01, 0.2
FIT_SAMPLE = 500
"""While the cloud is spread, the fit (on the sharp field) is averaged over this many."""
GOOD_FIT = 0.7
"""The likelihood (a geometric mean per return) of a good fit: after ``start_anywhere``
the long-term average starts there, so that a cloud gathered where the scan fits badly
keeps drawing random particles."""
INJECT_MIN = 0.05
"""Resample whatever the effective sample size once this share would be random."""
KLD_ERROR, KLD_Z = 0.05, 2.326
"""KLD sampling: at most this error between the cloud and the belief, at 99 %."""
KLD_BIN_M, KLD_BIN_RAD = 0.5, math.radians(10.0)
CLUSTER_BIN_M = 0.2
CLUSTER_FLOOR = 0.01
"""A cluster joins neighbouring CLUSTER_BIN_M cells holding at least this share of the
heaviest cell's weight."""
CONVERGED_XY_M, CONVERGED_YAW_RAD, CONVERGED_SHARE = 0.1, math.radians(5.0), 0.9
REFINE_WINDOW_M, REFINE_WINDOW_DEG, REFINE_POINTS = 0.05, 2.0, 150
REFINE_SPREADS = 3.0
"""The refining scan match: around the cloud's mean, at least REFINE_WINDOW or this many
of the cloud's deviations wide, with REFINE_POINTS of the returns."""
CHOSEN_SIGMA_M, CHOSEN_SIGMA_RAD = 0.03, 0.03
"""The cloud's spread about the place the scans chose among several alike."""
SHARP_SIGMA_M = 0.025
"""The refining scan match's field: a narrow peak is where the surfaces are."""


@dataclass(frozen=True)
class MotionNoise:
    """The odometry's error as standard deviations per unit of motion (AMCL's omni model,
    its alphas as deviations): of the travel, along and across it, and of the turn."""

    trans_m_per_m: float = 0.1
    trans_m_per_rad: float = 0.02
    yaw_rad_per_rad: float = 0.1
    yaw_rad_per_m: float = 0.1


@dataclass(frozen=True)
class PoseEstimate:
    """Where the filter believes the base is, and how sure it is."""

    pose: Pose2D
    """The base's pose (chassis centre) in the map's frame."""
    covariance: FloatArray
    """3x3 over (x_m, y_m, yaw_rad): the cloud's spread about ``pose`` (the main cluster's
    own once it holds the weight); the yaw's taken on the circle."""
    converged: bool
    """The cluster holds the weight and has gathered (position and yaw spread small)."""
    matched_share: float
    """Share of the latest scan's returns within NEAR_M of a mapped surface at ``pose`` (0
    when no scan came since the last start or motion)."""
    rivals: int = 0
    """Other places on the map the scans so far fit about as well (then not converged)."""
    alike: tuple[Pose2D, ...] = ()
    """With rivals: every place alike, the likeliest first (``pose`` is the first)."""

    def __repr__(self) -> str:
        sd_m = math.sqrt(max(float(self.covariance[0, 0] + self.covariance[1, 1]), 0.0))
        sd_deg = math.degrees(math.sqrt(max(float(self.covariance[2, 2]), 0.0)))
        state = ("converged" if self.converged else
                 f"{self.rivals + 1} places alike" if self.rivals else "searching")
        return (f"PoseEstimate({self.pose!r}, {state}, "
                f"spread {sd_m:.3f} m {sd_deg:.1f} deg, matched {self.matched_share:.2f})")


class ParticleFilter:
    """AMCL-style localisation of the base on ``grid``, its Lidar at ``lidar`` on the base.
    It starts anywhere (global localisation) until ``start_at`` says otherwise."""

    def __init__(self, grid: OccupancyGrid, lidar: Mount, *, particles: int = 500,
                 max_particles: int = 5000, seed: int = 0, beams: int = 60,
                 noise: MotionNoise | None = None, sigma_hit_m: float = SIGMA_M,
                 refine: bool = True) -> None:
        self.max_particles = check_int_range("max_particles", max_particles, 10, 100_000)
        self.min_particles = check_int_range("particles", particles, 10, self.max_particles)
        self.beams = check_int_range("beams", beams, 1, 2000)
        check_range("sigma_hit_m", sigma_hit_m, 0.01, 1.0, "m")
        self.field = LikelihoodField(grid, sigma_hit_m)
        self._broad = LikelihoodField(grid, max(sigma_hit_m, BROAD_SIGMA_M))
        self._sharp = LikelihoodField(grid, min(sigma_hit_m, SHARP_SIGMA_M))
        self.noise = noise or MotionNoise()
        self.refine = refine
        self.mount = Pose2D(lidar.x_m, lidar.y_m, lidar.yaw_rad)
        spec = grid.spec
        self._free = grid.probability <= FREE_THRESH
        rows, cols = np.nonzero(self._free)
        if len(rows) == 0:
            raise ConfigError(f"the map has no free cell (occupancy <= {FREE_THRESH}): "
                              "nowhere to place particles")
        self._free_xy = spec.centres(rows, cols)
        self._rng = np.random.default_rng(check_int_range("seed", seed, 0, 2**32 - 1))
        self._poses: FloatArray = np.zeros((0, 3))
        self._weights: FloatArray = np.zeros(0)
        self._w_slow = self._w_fast = 0.0
        self._fresh = self._moved = self._gathered = self._fit_settled = False
        self._last: PoseEstimate | None = None
        self._doubt = self._cluster_tight = False
        """Whether a gathering cloud is checked for rivals (after ``start_anywhere``)."""
        self._rivals: Hypotheses | None = None
        self.start_anywhere()

    @property
    def particle_count(self) -> int:
        """How many particles the cloud has now (KLD sampling adapts it)."""
        return len(self._poses)

    @property
    def particle_poses(self) -> FloatArray:
        """A copy of the particles, (N, 3): x_m, y_m, yaw_rad in the map's frame."""
        return self._poses.copy()

    def start_at(self, pose: Pose2D, sigma_xy_m: float = 0.1,
                 sigma_yaw_rad: float = 0.1) -> None:
        """Particles around ``pose`` (the base's, map frame), normally spread."""
        _check_poses("start pose", pose)
        check_range("sigma_xy_m", sigma_xy_m, 0.0, 10.0, "m")
        check_range("sigma_yaw_rad", sigma_yaw_rad, 0.0, math.pi, "rad")
        n = self.min_particles
        xy = self._rng.normal([pose.x_m, pose.y_m], sigma_xy_m, (n, 2))
        yaw = pose.yaw_rad + self._rng.normal(0.0, sigma_yaw_rad, n)
        self._reset(np.column_stack([xy, _wrap(yaw)]), w_slow=0.0)
        self._doubt, self._rivals = False, None

    def start_anywhere(self) -> None:
        """Global localisation: max_particles over the map's free cells, any heading."""
        self._reset(self._random_poses(self.max_particles), w_slow=GOOD_FIT)
        self._doubt, self._rivals = True, None

    def predict(self, odom_before: Pose2D, odom_after: Pose2D) -> None:
        """Move every particle by the odometry's motion (in the base's frame at
        ``odom_before``), each with its own noise."""
        _check_poses("odometry", odom_before, odom_after)
        moved = odom_after.relative_to(odom_before)
        trans_m, turn_rad = math.hypot(moved.x_m, moved.y_m), abs(moved.yaw_rad)
        if trans_m < 1e-6 and turn_rad < 1e-6:
            return
        nz = self.noise
        sigma_m = math.hypot(nz.trans_m_per_m * trans_m, nz.trans_m_per_rad * turn_rad)
        sigma_rad = math.hypot(nz.yaw_rad_per_rad * turn_rad, nz.yaw_rad_per_m * trans_m)
        ux, uy = (moved.x_m / trans_m, moved.y_m / trans_m) if trans_m > 0 else (1.0, 0.0)
        n = len(self._poses)
        along = trans_m + self._rng.normal(0.0, sigma_m, n)
        across = self._rng.normal(0.0, sigma_m, n)
        bx, by = along * ux - across * uy, along * uy + across * ux
        p = self._poses
        c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
        p[:, 0] += c * bx - s * by
        p[:, 1] += s * bx + c * by
        p[:, 2] = _wrap(p[:, 2] + moved.yaw_rad + self._rng.normal(0.0, sigma_rad, n))
        if self._rivals is not None:
            self._rivals.move(moved)
        self._moved = True
        self._last = None

    def update(self, bearings_rad: npt.ArrayLike, ranges_m: npt.ArrayLike) -> PoseEstimate:
        """Weigh the particles by one scan (bearings in the Lidar's frame, ranges in m, NaN
        for no return), resample if due; the estimate after it. As in AMCL, a scan from
        where the last one was weighed (no motion since) is not weighed again: the same
        view adds no evidence, only overconfidence; the estimate is still refined on it."""
        b = np.asarray(bearings_rad, dtype=np.float64).ravel()
        r = np.asarray(ranges_m, dtype=np.float64).ravel()
        if b.shape != r.shape:
            raise ConfigError(f"{len(b)} bearings and {len(r)} ranges: one each per beam")
        if not np.isfinite(b).all():
            raise ConfigError(f"bearing {b[~np.isfinite(b)][0]}: bearings must be finite (rad)")
        local = thinned(scan_points(b, r), self.beams)
        if len(local) == 0:
            return self.estimate()
        weigh = self._moved or self._fresh
        if weigh:
            self._weigh(local)
        self._last = self._estimate((b, r))  # of the weighed cloud, before resampling
        # A gathered cluster is checked for places alike even while another cluster holds
        # weight: the filter's thinned beams may not see what tells them apart.
        if self._doubt and (self._cluster_tight or self._rivals is not None):
            self._last = self._judge_rivals(self._last, scan_points(b, r), weigh)
        if weigh and self._moved:
            self._resample()
        self._moved = self._fresh = False
        return self._last

    def _judge_rivals(self, estimate: PoseEstimate, local: FloatArray, weigh: bool
                      ) -> PoseEstimate:
        """A gathered cloud checked for other places alike, once; then those places
        weighed scan by scan until one leads (see the module docstring)."""
        if self._rivals is None:
            sensor = compose(estimate.pose, self.mount)
            sensor, rivals = find_rivals(self._sharp, self._broad, local, self._free_xy,
                                         sensor)
            if not rivals:
                self._doubt = False
                return estimate
            back = inverse(self.mount)
            self._rivals = Hypotheses(self._sharp, self._free, self.mount, [
                compose(pose, back) for pose in (sensor, *(p for p, _ in rivals))])
            weigh = True  # the first view counts once for every place alike
        if weigh:
            self._rivals.weigh(local)
        chosen = self._rivals.decided()
        if chosen is None:
            alike = tuple(h.pose for h in sorted(self._rivals.places, key=lambda h: h.misses))
            return replace(estimate, pose=alike[0], converged=False, rivals=len(alike) - 1,
                           alike=alike)
        # The cloud around the chosen place alone: particles left at the others (its
        # thinned beams see less of what told them apart) would linger there.
        self.start_at(chosen, CHOSEN_SIGMA_M, CHOSEN_SIGMA_RAD)
        return PoseEstimate(chosen, estimate.covariance, False, estimate.matched_share)

    def estimate(self) -> PoseEstimate:
        """The latest update's estimate, or (moved since) that of the cloud alone."""
        if self._last is None:
            self._last = self._estimate(None)
        return self._last

    def _reset(self, poses: FloatArray, w_slow: float) -> None:
        self._poses = poses
        self._weights = np.full(len(poses), 1.0 / len(poses))
        self._w_slow, self._w_fast = w_slow, 0.0
        self._fresh, self._moved, self._gathered, self._fit_settled = True, False, False, False
        self._last = None

    def _random_poses(self, n: int) -> FloatArray:
        half = self.field.spec.resolution_m / 2.0
        xy = self._free_xy[self._rng.integers(len(self._free_xy), size=n)]
        xy = xy + self._rng.uniform(-half, half, (n, 2))
        return np.column_stack([xy, self._rng.uniform(-math.pi, math.pi, n)])

    def _in_map(self, poses: FloatArray, local: FloatArray) -> FloatArray:
        """The scan's returns (sensor frame) seen from each base pose: (N, B, 2), map frame."""
        m = self.mount
        cm, sm = math.cos(m.yaw_rad), math.sin(m.yaw_rad)
        bx = m.x_m + cm * local[:, 0] - sm * local[:, 1]  # in the base's frame
        by = m.y_m + sm * local[:, 0] + cm * local[:, 1]
        c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])
        return np.stack([poses[:, 0:1] + c * bx - s * by, poses[:, 1:2] + s * bx + c * by],
                        axis=-1)

    def _weigh(self, local: FloatArray) -> None:
        points = self._in_map(self._poses, local)
        field = self.field if self._gathered else self._broad
        mean_log = mean_log_likelihood(field, points)
        log_w = np.log(np.maximum(self._weights, 1e-300)) + INDEPENDENT_BEAMS * mean_log
        w = np.exp(log_w - log_w.max())
        self._weights = w / w.sum()
        # How well the scan fits where the cloud now believes the base is (the posterior's
        # mean fit: particles injected at random, likely wrong, weigh little in it).
        if self._gathered:
            w_avg = float(np.sum(self._weights * np.exp(mean_log)))
        else:  # the fit on the sharp field, on a sample drawn by weight: the same scale
            pick = self._rng.choice(len(points), size=min(len(points), FIT_SAMPLE),
                                    p=self._weights)
            w_avg = float(np.mean(np.exp(mean_log_likelihood(self.field, points[pick]))))
        self._follow_fit(w_avg)

    def _follow_fit(self, w_avg: float) -> None:
        """Augmented MCL's averages of how well the scans fit: long- and short-term."""
        if self._w_slow == 0.0:  # the first scan after start_at: the fit it starts from
            self._w_slow = w_avg
        if self._gathered and self._fit_settled:
            self._w_slow += ALPHA_SLOW * (w_avg - self._w_slow)
            self._w_fast += ALPHA_FAST * (w_avg - self._w_fast)
        else:  # still searching: the long-term fit holds, the short-term is this scan's
            self._w_fast = w_avg
        self._fit_settled = self._gathered

    def _resample(self) -> None:
        w = self._weights
        inject = max(0.0, 1.0 - self._w_fast / self._w_slow) if self._w_slow > 0 else 0.0
        if 1.0 / float(np.sum(w * w)) >= len(w) / 2 and inject < INJECT_MIN:
            return
        m = self.max_particles
        # Low variance: one random offset, m evenly spaced pointers into the cumulative weight.
        pointers = (self._rng.uniform() + np.arange(m)) / m
        index = np.minimum(np.searchsorted(np.cumsum(w), pointers), len(w) - 1)
        poses = self._poses[self._rng.permutation(index)]  # any prefix: a fair sample
        random = self._rng.uniform(size=m) < inject
        poses[random] = self._random_poses(int(random.sum()))
        n = _kld_size(poses, self.min_particles)
        self._poses = poses[:n].copy()
        self._weights = np.full(n, 1.0 / n)

    def _estimate(self, scan: tuple[FloatArray, FloatArray] | None) -> PoseEstimate:
        pose, cov, share = self._cloud()
        converged = share >= CONVERGED_SHARE and _tight(cov)
        self._gathered = converged
        if scan is None:
            return PoseEstimate(pose, cov, converged, 0.0)
        b, r = scan
        if converged and self.refine:  # the cloud is as fine as its noise: the map is finer
            # As wide as the cloud is spread (a sparse room's cloud gathers loosely, its
            # mean some centimetres off), at least REFINE_WINDOW.
            sd_m = math.sqrt(float(np.linalg.eigvalsh(cov[:2, :2])[-1]))
            sd_deg = math.degrees(math.sqrt(max(float(cov[2, 2]), 0.0)))
            found = match_scan(self._sharp, b, r, compose(pose, self.mount),
                               window_m=max(REFINE_WINDOW_M, REFINE_SPREADS * sd_m),
                               window_deg=max(REFINE_WINDOW_DEG, REFINE_SPREADS * sd_deg),
                               max_points=REFINE_POINTS)
            if found.matched_share >= MIN_MATCHED_SHARE:
                pose = compose(found.pose, inverse(self.mount))
        local = thinned(scan_points(b, r), self.beams)
        at = np.array([[pose.x_m, pose.y_m, pose.yaw_rad]])
        _, near = self.field.score(self._in_map(at, local)[0])
        return PoseEstimate(pose, cov, converged, float(near))

    def _cloud(self) -> tuple[Pose2D, FloatArray, float]:
        """The weighted mean of the main cluster, the whole cloud's spread about it (a
        stray particle counts by its weight) and the cluster's share of the weight."""
        member = self._main_cluster()
        w, p = self._weights, self._poses
        share = float(w[member].sum())
        wc: FloatArray = w[member] / share
        pc: FloatArray = p[member]
        heading: FloatArray = pc[:, 2]
        yaw = math.atan2(float(np.sum(wc * np.sin(heading))), float(np.sum(wc * np.cos(heading))))
        mean = np.array([float(np.sum(wc * pc[:, 0])), float(np.sum(wc * pc[:, 1])), yaw])
        dev = p - mean
        dev[:, 2] = _wrap(dev[:, 2])  # the yaw's spread on the circle, about the mean's
        cov: FloatArray = (dev * (w / w.sum())[:, None]).T @ dev
        own = dev[member]
        own_cov: FloatArray = (own * wc[:, None]).T @ own
        self._cluster_tight = _tight(own_cov)
        return Pose2D(float(mean[0]), float(mean[1]), yaw), cov, share

    def _main_cluster(self) -> npt.NDArray[np.bool_]:
        """Which particles are in the heaviest cluster: connected CLUSTER_BIN_M cells that
        hold weight (a far-off stray particle does not pull the mean)."""
        import cv2

        s = self.field.spec
        cells_x = max(1, math.ceil(s.width * s.resolution_m / CLUSTER_BIN_M))
        cells_y = max(1, math.ceil(s.height * s.resolution_m / CLUSTER_BIN_M))
        col = np.clip(((self._poses[:, 0] - s.origin_x_m) // CLUSTER_BIN_M).astype(np.int64),
                      0, cells_x - 1)
        row = np.clip(((self._poses[:, 1] - s.origin_y_m) // CLUSTER_BIN_M).astype(np.int64),
                      0, cells_y - 1)
        cell = row * cells_x + col
        mass = np.bincount(cell, self._weights, minlength=cells_x * cells_y)
        held = (mass >= CLUSTER_FLOOR * mass.max()).reshape(cells_y, cells_x)
        _, labels = cv2.connectedComponents(held.astype(np.uint8), connectivity=8)
        labels = np.asarray(labels).ravel()
        label_mass = np.bincount(labels, mass)
        label_mass[0] = -1.0  # the background: cells holding no weight
        member: npt.NDArray[np.bool_] = labels[cell] == int(np.argmax(label_mass))
        return member


def _tight(cov: FloatArray) -> bool:
    """Whether a spread (3x3 over x, y, yaw) is within CONVERGED_XY_M and _YAW_RAD."""
    return bool(np.linalg.eigvalsh(cov[:2, :2])[-1] <= CONVERGED_XY_M ** 2
                and cov[2, 2] <= CONVERGED_YAW_RAD ** 2)


def _check_poses(what: str, *poses: Pose2D) -> None:
    if not all(math.isfinite(v) for p in poses for v in (p.x_m, p.y_m, p.yaw_rad)):
        shown = " to ".join(str(p) for p in poses)
        raise ConfigError(f"{what} {shown}: every value must be a finite number")


def _wrap(angle_rad: FloatArray) -> FloatArray:
    out: FloatArray = np.arctan2(np.sin(angle_rad), np.cos(angle_rad))
    return out


def _kld_size(poses: FloatArray, least: int) -> int:
    """How many of ``poses`` (a shuffled sample) KLD sampling keeps: the first n such that
    n is enough for the KLD_BIN cells occupied by the first n."""
    key = np.stack([np.floor(poses[:, 0] / KLD_BIN_M), np.floor(poses[:, 1] / KLD_BIN_M),
                    np.floor((poses[:, 2] + math.pi) / KLD_BIN_RAD)], axis=1)
    _, first = np.unique(key, axis=0, return_index=True)
    new = np.zeros(len(poses))
    new[first] = 1.0
    k = np.cumsum(new)  # bins occupied by the first 1, 2, ... poses
    km1 = np.maximum(k - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    needed = np.where(k > 1, km1 / (2 * KLD_ERROR) * (1 - a + np.sqrt(a) * KLD_Z) ** 3, 0.0)
    n = np.arange(1, len(poses) + 1)
    enough = np.nonzero((n >= needed) & (n >= least))[0]
    return int(enough[0]) + 1 if len(enough) else len(poses)
