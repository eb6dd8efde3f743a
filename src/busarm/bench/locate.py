"""``busarm bench locate``: how well the wrist camera locates blocks, against the twin's truth.

Everything the measurement uses comes from our own flows, run in the twin exactly as on
hardware: the intrinsics from chessboard pictures (``busarm camera calibrate``), the
hand-eye from tag-board pictures (``busarm camera handeye``), the joints from POS_READ.
The twin's true lens, camera mount and block poses are read only to score the result.

Placements: blocks are put (one picture holds several) at random over the table the
arm reaches with a top-down grasp, wherever one of the survey poses (the ``look`` pose
turned to several base bearings) sees them whole and clear of the gripper.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from busarm.arm.chain import FloatArray
from busarm.arm.kinematics import ArmKinematics
from busarm.bench.common import (
    CalibrationSummary,
    Progress,
    quiet,
    short_machine_info,
)
from busarm.errors import ConfigError, UnreachableError
from busarm.perception.locate import Sighting
from busarm.robot import Robot
from busarm.robot.camera_calibration import sees_points
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.robot.twin_calibration import calibrate_twin_camera
from busarm.twin.lens import LensSpec
from busarm.twin.scene import COLORS, random_scene
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import BlockState
from busarm.vision.calibration import (
    CameraIntrinsics,
    load_intrinsics,
)

__all__ = [
    "BLOCK_GAP_MM",
    "LOCATE_RADIUS_MM",
    "MATCH_MM",
    "SURVEY_BEARINGS_DEG",
    "TARGET_MEDIAN_MM",
    "TARGET_P95_MM",
    "AccuracyReport",
    "AccuracySummary",
    "LocateBenchReport",
    "localisation_accuracy",
    "run_locate_bench",
]


TARGET_MEDIAN_MM = 2.0
TARGET_P95_MM = 5.0
SURVEY_BEARINGS_DEG = (-90.0, -45.0, 0.0, 45.0, 90.0)
LOCATE_RADIUS_MM = (125.0, 265.0)
BLOCK_GAP_MM = 50.0
MATCH_MM = 25.0
"""A sighting further than this from a block is not that block's."""


@dataclass
class AccuracySummary:
    """Localisation accuracy over every placement (errors in mm, horizontal)."""

    placements: int
    located: int
    missed: int
    wrong_color: int
    pictures: int
    median_mm: float
    p95_mm: float
    max_mm: float
    mean_mm: float
    seconds: float


@dataclass
class AccuracyReport:
    """Localisation errors (mm, horizontal) of every placement, and what was missed."""

    errors_mm: list[float] = field(default_factory=list)
    missed: int = 0
    wrong_color: int = 0
    pictures: int = 0
    seconds: float = 0.0

    def summary(self) -> AccuracySummary:
        e = np.asarray(self.errors_mm) if self.errors_mm else np.asarray([math.nan])
        return AccuracySummary(
            placements=len(self.errors_mm) + self.missed, located=len(self.errors_mm),
            missed=self.missed, wrong_color=self.wrong_color, pictures=self.pictures,
            median_mm=float(np.median(e)), p95_mm=float(np.percentile(e, 95)),
            max_mm=float(np.max(e)), mean_mm=float(np.mean(e)),
            seconds=round(self.seconds, 1),
        )


@dataclass
class LocateBenchReport:
    """``busarm bench locate``: the calibration made in the twin, then the accuracy."""

    machine: dict[str, str]
    calibration: CalibrationSummary
    accuracy: AccuracySummary
    twin_lens_distortion: list[float]

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


def _block_corners(x: float, y: float, yaw_deg: float, size: float, table_z: float
                   ) -> npt.NDArray[np.float64]:
    h = size / 2
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pts = [(x + c * dx - s * dy, y + s * dx + c * dy, table_z + z)
           for dx in (-h, h) for dy in (-h, h) for z in (0.0, size)]
    return np.asarray(pts)


def _spots(rng: np.random.Generator, bearing: float, count: int, kin: ArmKinematics,
           cam2base: FloatArray, intrinsics: CameraIntrinsics, size: float, table_z: float,
           ) -> list[tuple[float, float, float]]:
    """Up to ``count`` random (x, y, yaw) the camera sees whole, apart and reachable."""
    spots: list[tuple[float, float, float]] = []
    for _try in range(4000):
        if len(spots) == count:
            break
        r = math.sqrt(rng.uniform(LOCATE_RADIUS_MM[0] ** 2, LOCATE_RADIUS_MM[1] ** 2))
        b = math.radians(bearing + rng.uniform(-60.0, 60.0))
        x, y, yaw = r * math.cos(b), r * math.sin(b), rng.uniform(-45.0, 45.0)
        if abs(math.degrees(b)) > 120.0 or any(
                math.hypot(x - sx, y - sy) < BLOCK_GAP_MM for sx, sy, _ in spots):
            continue
        if not sees_points(_block_corners(x, y, yaw, size, table_z), cam2base,
                           intrinsics, margin_px=6.0):
            continue
        try:
            kin.ik_best(x, y, table_z + size / 2, -90.0)
        except UnreachableError:
            continue
        spots.append((x, y, yaw))
    return spots


def _score(report: AccuracyReport, sightings: Sequence[Sighting],
           truth: Sequence[BlockState]) -> None:
    """Each true block's nearest sighting: its error, or a miss; and a wrong colour."""
    for t in truth:
        near = [s for s in sightings
                if math.hypot(s.location.x_mm - t.x_mm, s.location.y_mm - t.y_mm) < MATCH_MM]
        if not near:
            report.missed += 1
            continue
        best = min(near, key=lambda s: math.hypot(s.location.x_mm - t.x_mm,
                                                 s.location.y_mm - t.y_mm))
        if best.color != t.color:
            report.wrong_color += 1
        report.errors_mm.append(math.hypot(best.location.x_mm - t.x_mm,
                                           best.location.y_mm - t.y_mm))


def localisation_accuracy(
    intrinsics: Path, hand_eye: Path, *, placements: int = 200,
    per_picture: int = 5, seed: int = 0, progress: Progress = quiet,
) -> AccuracyReport:
    """Place blocks over the reachable table and score where the camera, calibrated by
    the ``intrinsics`` and ``hand_eye`` files, puts them."""
    if not 1 <= per_picture <= 8:
        raise ConfigError(f"per_picture = {per_picture} is out of range 1..8")
    if not 1 <= placements <= 100_000:
        raise ConfigError(f"placements = {placements} is out of range 1..100000")
    scene = random_scene(seed, per_picture, list(COLORS), bins=False)
    rng = np.random.default_rng(seed)
    report = AccuracyReport()
    start = time.monotonic()
    with Robot.open(RobotConfig(TwinSpec(scene=scene), camera=CameraSpec(
            intrinsics=intrinsics, hand_eye=hand_eye))) as robot:
        arm, twin, camera, locator = robot.arm, robot.twin, robot.camera, robot.locator()
        assert twin is not None
        cal = robot.require_camera_calibration()
        look = arm.config.pose("look")
        size = scene.blocks[0].size_mm
        table_z = arm.config.table_z_mm
        pictures_per_pose = math.ceil(placements / per_picture / len(SURVEY_BEARINGS_DEG))
        for bearing in SURVEY_BEARINGS_DEG:
            if len(report.errors_mm) + report.missed >= placements:
                break  # placed them all: the other bearings would add nothing
            arm.move_joints((bearing, *look[1:]), speed_deg_s=120.0)
            robot.clock.sleep(0.3)
            cam2base = twin.cam2base()  # truth: only to choose placements the camera sees
            located, missed, pictures = len(report.errors_mm), report.missed, report.pictures
            for _ in range(pictures_per_pose):
                if len(report.errors_mm) + report.missed >= placements:
                    break
                spots = _spots(rng, bearing, per_picture, arm.kin, cam2base, cal.intrinsics,
                               size, table_z)
                poses: dict[int, tuple[float, float, float, float | None]] = {
                    i: (x, y, yaw, None) for i, (x, y, yaw) in enumerate(spots)}
                for i in range(len(spots), per_picture):  # park unused blocks out of sight
                    poses[i] = (-150.0 + 40.0 * i, -350.0, 0.0, None)
                twin.place_blocks(poses)
                frame = camera.read()
                sightings = locator.locate(frame.image, arm.read_joints_deg())
                report.pictures += 1
                _score(report, sightings, twin.blocks()[: len(spots)])
            # This bearing's own counts (the report's are totals over every bearing).
            progress(f"bearing {bearing:+.0f} deg: {len(report.errors_mm) - located} located, "
                     f"{report.missed - missed} missed in {report.pictures - pictures} "
                     "picture(s)")
    report.seconds = time.monotonic() - start
    return report


def run_locate_bench(*, placements: int = 200, seed: int = 0, work_dir: Path | None = None,
                     intrinsics_views: int = 20, hand_eye_views: int = 16,
                     progress: Progress = quiet) -> LocateBenchReport:
    """Calibrate in the twin with our flows, then measure localisation accuracy."""
    with tempfile.TemporaryDirectory() as tmp:
        out = work_dir or Path(tmp)
        with Robot.open(RobotConfig(TwinSpec(blocks=0),
                                          camera=CameraSpec(calibrate=False))) as robot:
            assert robot.twin is not None
            run = calibrate_twin_camera(robot.twin, out, intrinsics_views=intrinsics_views,
                                        hand_eye_views=hand_eye_views, seed=seed,
                                        progress=progress)
        report = localisation_accuracy(run.intrinsics_path, run.hand_eye_path,
                                       placements=placements, seed=seed, progress=progress)
        calibration = CalibrationSummary.of(run, load_intrinsics(run.intrinsics_path))
    return LocateBenchReport(
        machine=short_machine_info(),
        calibration=calibration,
        accuracy=report.summary(),
        twin_lens_distortion=list(LensSpec().distortion),
    )
