"""AMCL-style localisation on a saved map of the L-shaped room (nav_world).

The map is built from simulated scans, saved as map_server files and read back, as a
robot would load it. The Lidar sits off the base's centre and turned, so that a filter
that forgot its mount would not find the truth. Odometry reads long and turns too far;
scans carry range noise and drop returns.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from nav_world import BEARINGS, WALLS, Segment, box, mapped, scan_from

from busarm.base.config import Mount
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.localize import ParticleFilter, PoseEstimate
from busarm.nav.map_files import load_map, save_map
from busarm.nav.mapping import compose

MOUNT = Mount(0.1, -0.03, 0.2, math.pi / 2)
LIDAR = Pose2D(MOUNT.x_m, MOUNT.y_m, MOUNT.yaw_rad)
SPEC = GridSpec(-2.525, -2.025, 0.05, 101, 81)
"""5 cm cells, their centres on the walls (as a wall anywhere is, on average)."""
MAPPING_POSES = [Pose2D(x, y, 0.3) for x, y in [
    (-1.5, -1.0), (0.0, -1.0), (1.5, -1.0), (1.5, 0.0), (0.0, 0.2), (-1.5, 0.2), (-1.5, 1.0),
    (0.0, 1.0), (-0.2, -0.6)]]


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory) -> OccupancyGrid:
    grid = mapped(*(compose(p, LIDAR) for p in MAPPING_POSES), spec=SPEC, times=6)
    path = Path(tmp_path_factory.mktemp("map")) / "room.yaml"
    save_map(path, grid)
    return load_map(path)


@dataclass
class Run:
    """The true base driven by steps; the odometry's version of them; a scan after each."""

    pf: ParticleFilter
    truth: Pose2D
    seed: int = 0
    scale: float = 1.0
    """The odometry reads this much of each translation..."""
    drift_deg: float = 0.0
    """... and this much more turn at each step."""
    walls: Sequence[Segment] = tuple(WALLS)
    odom: Pose2D = field(default_factory=Pose2D)
    steps: int = 0
    rng: np.random.Generator = field(init=False)

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def scan(self) -> np.ndarray:
        ranges = scan_from(compose(self.truth, LIDAR), self.walls)
        ranges = ranges + self.rng.normal(0.0, 0.01, ranges.shape)
        ranges[self.rng.uniform(size=ranges.shape) < 0.05] = np.nan  # dropped returns
        return ranges

    def update(self) -> PoseEstimate:
        return self.pf.update(BEARINGS, self.scan())

    def step(self, dx_m: float, dy_m: float, dyaw_deg: float) -> PoseEstimate:
        self.truth = compose(self.truth, Pose2D(dx_m, dy_m, math.radians(dyaw_deg)))
        odom = compose(self.odom, Pose2D(dx_m * self.scale, dy_m * self.scale,
                                         math.radians(dyaw_deg + self.drift_deg)))
        self.pf.predict(self.odom, odom)
        self.odom = odom
        self.steps += 1
        return self.update()

    def off(self, pose: Pose2D) -> tuple[float, float]:
        """How far ``pose`` is from the truth: metres, degrees."""
        return (math.hypot(pose.x_m - self.truth.x_m, pose.y_m - self.truth.y_m),
                abs(math.degrees(math.remainder(pose.yaw_rad - self.truth.yaw_rad, math.tau))))


def wiggle(run: Run, steps: int) -> PoseEstimate:
    """Turn on the spot 15 deg at a time, rocking 5 cm back and forth (the base stays
    within 0.11 m of where it began)."""
    est = run.pf.estimate()
    for _ in range(steps):
        est = run.step(0.05 if run.steps % 4 < 2 else -0.05, 0.0, 15.0)
    return est


def clearance_m(x_m: float, y_m: float) -> float:
    """Distance from a point inside the room to its nearest wall (negative: outside)."""
    inside = (-2 < x_m < 2 and -1.5 < y_m < 0.5) or (-2 < x_m < 0.5 and 0.5 <= y_m < 1.5)
    if not inside:
        return -1.0
    p = np.array([x_m, y_m])
    best = math.inf
    for a, b in WALLS:
        a_, e = np.array(a), np.array(b) - np.array(a)
        t = float(np.clip(np.dot(p - a_, e) / np.dot(e, e), 0.0, 1.0))
        best = min(best, float(np.linalg.norm(p - a_ - t * e)))
    return best


PATH = ([(0.1, 0.0, 0.0)] * 28 + [(0.0, 0.0, 30.0)] * 3 + [(0.1, 0.0, 0.0)] * 11
        + [(0.0, 0.0, 30.0)] * 3 + [(0.1, 0.0, 0.0)] * 12 + [(0.0, 0.0, 30.0)] * 3
        + [(0.08, 0.0, 0.0)] * 10)
"""Along the room's bottom, up its right, back along the middle and up the left arm."""


def test_tracking_follows_the_truth_where_the_odometry_drifts(room: OccupancyGrid) -> None:
    start = Pose2D(-1.5, -1.1, 0.0)
    pf = ParticleFilter(room, MOUNT, seed=1)
    pf.start_at(Pose2D(-1.45, -1.13, 0.05))
    run = Run(pf, start, seed=1, scale=1.03, drift_deg=0.5)
    offs = [run.off(run.step(*step).pose) for step in PATH]
    metres, degrees = np.array(offs).T
    assert np.median(metres) < 0.03 and np.median(degrees) < 2.0, offs
    assert metres.max() < 0.06, offs
    believed = compose(start, run.odom)
    assert run.off(believed)[0] > 0.15 and run.off(believed)[1] > 20  # the odometry drifted
    final = pf.estimate()
    assert final.converged and final.matched_share > 0.9


@settings(max_examples=5, deadline=None)
@given(st.floats(-1.8, 1.8), st.floats(-1.3, 1.3), st.floats(-math.pi, math.pi),
       st.integers(0, 10_000))
def test_from_anywhere_it_finds_the_robot(room: OccupancyGrid, x_m: float, y_m: float,
                                          yaw_rad: float, seed: int) -> None:
    assume(clearance_m(x_m, y_m) > 0.3)
    pf = ParticleFilter(room, MOUNT, seed=seed)
    run = Run(pf, Pose2D(x_m, y_m, yaw_rad), seed=seed, scale=1.02, drift_deg=0.3)
    run.update()
    est = wiggle(run, 30)
    metres, degrees = run.off(est.pose)
    assert metres < 0.05 and degrees < 3.0, (est, run.truth)
    assert est.converged
    assert pf.particle_count < pf.max_particles  # fewer once found


def test_a_kidnapped_robot_is_found_again(room: OccupancyGrid) -> None:
    pf = ParticleFilter(room, MOUNT, seed=3)
    pf.start_at(Pose2D(-1.4, -1.0, 0.0))
    run = Run(pf, Pose2D(-1.4, -1.0, 0.0), seed=3, scale=1.02)
    for _ in range(8):
        est = run.step(0.05, 0.0, 0.0)
    assert run.off(est.pose)[0] < 0.03
    # Carried 1.5 m to the right and turned; the odometry knows nothing of it.
    run.truth = Pose2D(run.truth.x_m + 1.5, run.truth.y_m + 0.1, run.truth.yaw_rad + 1.0)
    est = wiggle(run, 1)
    assert run.off(est.pose)[0] > 1.0  # it first believes it is where it was
    for _ in range(30):
        if run.off(wiggle(run, 1).pose)[0] < 0.05:
            break
    else:
        pytest.fail(f"not found again in 30 updates: {pf.estimate()} vs {run.truth}")
    final = wiggle(run, 3)
    assert run.off(final.pose)[0] < 0.05 and final.converged


def test_unmapped_boxes_do_not_pull_the_estimate(room: OccupancyGrid) -> None:
    truth = Pose2D(1.2, -1.0, 0.4)
    # Not on the map: one against the wall behind, one standing free 0.6 m away.
    box_walls = (*WALLS, *box(1.2, -1.27, 0.1), *box(1.55, -0.5, 0.12))
    pf = ParticleFilter(room, MOUNT, seed=4)
    pf.start_at(Pose2D(1.25, -0.97, 0.45))
    run = Run(pf, truth, seed=4, walls=box_walls)
    offs = [run.off(run.step(0.03 if i % 2 else -0.03, 0.0, 5.0).pose)[0] for i in range(15)]
    assert max(offs[5:]) < 0.03, offs
    est = pf.estimate()
    assert est.converged and est.matched_share < 0.9  # the boxes' returns: off the map


def test_the_covariance_shrinks_as_the_cloud_gathers(room: OccupancyGrid) -> None:
    pf = ParticleFilter(room, MOUNT, seed=5)
    anywhere = pf.estimate()
    assert not anywhere.converged and pf.particle_count == pf.max_particles
    assert math.sqrt(anywhere.covariance[2, 2]) > 1.5  # any heading: ~pi / sqrt(3)
    assert np.trace(anywhere.covariance[:2, :2]) > 0.5  # the whole room
    run = Run(pf, Pose2D(-1.2, 0.9, -2.0), seed=5)
    traces = [np.trace(anywhere.covariance[:2, :2]), np.trace(run.update().covariance[:2, :2])]
    found = wiggle(run, 25)
    traces.append(float(np.trace(found.covariance[:2, :2])))
    assert traces[0] > traces[1] > traces[2], traces
    assert found.converged and math.sqrt(found.covariance[2, 2]) < math.radians(5)
    assert np.all(np.linalg.eigvalsh(found.covariance) >= -1e-12)  # a covariance
    assert pf.particle_count <= 1000


def test_scans_without_motion_are_weighed_once(room: OccupancyGrid) -> None:
    """The same view again says nothing new: the cloud neither sharpens nor resamples."""
    pf = ParticleFilter(room, MOUNT, seed=6)
    pf.start_at(Pose2D(0.05, -1.03, 0.05))  # the default spread: 0.1 m, 0.1 rad
    run = Run(pf, Pose2D(0.0, -1.0, 0.0), seed=6)
    first = run.update()
    assert first.converged  # one scan gathers a start this close
    particles = pf.particle_poses
    again = [run.update() for _ in range(5)]
    assert np.array_equal(pf.particle_poses, particles)
    assert all(np.allclose(e.covariance, first.covariance) for e in again)
    moved = run.step(0.05, 0.0, 0.0)
    assert not np.allclose(moved.covariance, first.covariance)


@pytest.mark.parametrize(("kwargs", "words"), [
    ({"particles": 5}, "particles = 5 is out of range 10..5000"),
    ({"particles": 6000}, "particles = 6000 is out of range 10..5000"),
    ({"max_particles": 0}, "max_particles = 0 is out of range 10..100000"),
    ({"beams": 0}, "beams = 0 is out of range 1..2000"),
    ({"sigma_hit_m": 2.0}, "sigma_hit_m = 2.0 m is out of range 0.01..1 m"),
    ({"seed": -1}, "seed = -1 is out of range 0..4294967295"),
])
def test_bad_settings_are_refused_by_name(room: OccupancyGrid, kwargs: dict[str, float],
                                          words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        ParticleFilter(room, MOUNT, **kwargs)


def test_bad_starts_and_scans_are_refused_by_name(room: OccupancyGrid) -> None:
    pf = ParticleFilter(room, MOUNT, seed=7)
    before = pf.particle_poses
    with pytest.raises(ConfigError, match=r"sigma_xy_m = -1.0 m is out of range 0..10 m"):
        pf.start_at(Pose2D(), sigma_xy_m=-1.0)
    with pytest.raises(ConfigError, match=r"sigma_yaw_rad must be a number, got nan"):
        pf.start_at(Pose2D(), sigma_yaw_rad=math.nan)
    with pytest.raises(ConfigError, match=r"3 bearings and 2 ranges: one each per beam"):
        pf.update([0.0, 0.1, 0.2], [1.0, 1.0])
    with pytest.raises(ConfigError, match=r"odometry .* to .*nan.*: every value must be a fin"):
        pf.predict(Pose2D(), Pose2D(0.1, math.nan, 0.0))
    with pytest.raises(ConfigError, match=r"start pose .*inf.*: every value must be a finite"):
        pf.start_at(Pose2D(math.inf, 0.0, 0.0))
    with pytest.raises(ConfigError, match=r"bearing nan: bearings must be finite \(rad\)"):
        pf.update([0.0, math.nan], [1.0, 1.0])
    assert np.array_equal(pf.particle_poses, before)  # nothing changed by the refusals
    with pytest.raises(ConfigError, match=r"no free cell"):
        ParticleFilter(OccupancyGrid(SPEC), MOUNT)  # all unknown
