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
import platform
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.apps.camera_calibration import (
    sees_points,
)
from busarm.apps.locate import BlockLocator
from busarm.apps.twin_setup import Progress, calibrate_in_twin, open_twin_arm, quiet
from busarm.arm.config import load_arm_config
from busarm.errors import BusArmError, ConfigError, UnreachableError
from busarm.twin.camera import TwinCamera
from busarm.twin.lens import LensSpec
from busarm.twin.scene import COLORS, REACH_RADIUS_MM, random_scene
from busarm.twin.twin import Twin
from busarm.vision.calibration import (
    CameraIntrinsics,
    HandEyeResult,
    load_hand_eye,
    load_intrinsics,
)
from busarm.vision.color import ColorDetector, default_thresholds

TARGET_MEDIAN_MM = 2.0
TARGET_P95_MM = 5.0
SURVEY_BEARINGS_DEG = (-90.0, -45.0, 0.0, 45.0, 90.0)
LOCATE_RADIUS_MM = (125.0, 265.0)
BLOCK_GAP_MM = 50.0



@dataclass
class AccuracyReport:
    """Localisation errors (mm, horizontal) of every placement, and what was missed."""

    errors_mm: list[float] = field(default_factory=list)
    missed: int = 0
    wrong_color: int = 0
    pictures: int = 0
    seconds: float = 0.0

    def summary(self) -> dict[str, Any]:
        e = np.asarray(self.errors_mm) if self.errors_mm else np.asarray([math.nan])
        return {
            "placements": len(self.errors_mm) + self.missed, "located": len(self.errors_mm),
            "missed": self.missed, "wrong_color": self.wrong_color, "pictures": self.pictures,
            "median_mm": float(np.median(e)), "p95_mm": float(np.percentile(e, 95)),
            "max_mm": float(np.max(e)), "mean_mm": float(np.mean(e)),
            "seconds": round(self.seconds, 1),
        }


def _block_corners(x: float, y: float, yaw_deg: float, size: float, table_z: float
                   ) -> npt.NDArray[np.float64]:
    h = size / 2
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    pts = [(x + c * dx - s * dy, y + s * dx + c * dy, table_z + z)
           for dx in (-h, h) for dy in (-h, h) for z in (0.0, size)]
    return np.asarray(pts)


def localisation_accuracy(
    intrinsics: CameraIntrinsics, hand_eye: HandEyeResult, *, placements: int = 200,
    per_picture: int = 5, seed: int = 0, progress: Progress = quiet,
) -> AccuracyReport:
    """Place blocks over the reachable table and score where the camera puts them."""
    if not 1 <= per_picture <= 8:
        raise ConfigError(f"per_picture = {per_picture} is out of range 1..8")
    if not 1 <= placements <= 100_000:
        raise ConfigError(f"placements = {placements} is out of range 1..100000")
    colors = list(COLORS)
    scene = random_scene(seed, per_picture, colors, bins=False)
    rng = np.random.default_rng(seed)
    report = AccuracyReport()
    start = time.monotonic()
    arm, twin = open_twin_arm(scene)
    with arm, TwinCamera(twin) as camera:
        locator = BlockLocator(arm.kin, intrinsics, hand_eye, ColorDetector(default_thresholds()),
                               table_z_mm=arm.config.table_z_mm)
        look = arm.config.pose("look")
        size = scene.blocks[0].size_mm
        table_z = arm.config.table_z_mm
        pictures_per_pose = math.ceil(placements / per_picture / len(SURVEY_BEARINGS_DEG))
        for bearing in SURVEY_BEARINGS_DEG:
            pose = (bearing, *look[1:])
            arm.move_joints(pose, speed_deg_s=120.0)
            time.sleep(0.3)
            cam2base = twin.cam2base()  # truth: only to choose placements the camera sees
            for _ in range(pictures_per_pose):
                if len(report.errors_mm) + report.missed >= placements:
                    break
                spots: list[tuple[float, float, float]] = []
                for _try in range(4000):
                    if len(spots) == per_picture:
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
                        arm.kin.ik_best(x, y, table_z + size / 2, -90.0)
                    except UnreachableError:
                        continue
                    spots.append((x, y, yaw))
                poses: dict[int, tuple[float, float, float, float | None]] = {
                    i: (x, y, yaw, None) for i, (x, y, yaw) in enumerate(spots)}
                for i in range(len(spots), per_picture):  # park unused blocks out of sight
                    poses[i] = (-150.0 + 40.0 * i, -350.0, 0.0, None)
                twin.place_blocks(poses)
                frame = camera.read()
                joints = arm.read_joints_deg()
                sightings = locator.locate(frame.image, joints)
                report.pictures += 1
                truth = twin.blocks()[: len(spots)]
                for t in truth:
                    near = [s for s in sightings
                            if math.hypot(s.location.x_mm - t.x_mm, s.location.y_mm - t.y_mm) < 25]
                    if not near:
                        report.missed += 1
                        continue
                    best = min(near, key=lambda s: math.hypot(s.location.x_mm - t.x_mm,
                                                             s.location.y_mm - t.y_mm))
                    if best.color != t.color:
                        report.wrong_color += 1
                    report.errors_mm.append(math.hypot(best.location.x_mm - t.x_mm,
                                                       best.location.y_mm - t.y_mm))
                progress(f"bearing {bearing:+.0f}: {len(report.errors_mm)} located, "
                         f"{report.missed} missed")
    report.seconds = time.monotonic() - start
    return report


def run_locate_bench(*, placements: int = 200, seed: int = 0, work_dir: Path | None = None,
                     intrinsics_views: int = 20, hand_eye_views: int = 16,
                     progress: Progress = quiet) -> dict[str, Any]:
    """Calibrate in the twin with our flows, then measure localisation accuracy."""
    with tempfile.TemporaryDirectory() as tmp:
        out = work_dir or Path(tmp)
        intr_path, he_path, calib = calibrate_in_twin(
            out, intrinsics_views=intrinsics_views, hand_eye_views=hand_eye_views, seed=seed,
            progress=progress)
        intrinsics = load_intrinsics(intr_path)
        hand_eye = load_hand_eye(he_path, intrinsics=intrinsics)
        report = localisation_accuracy(intrinsics, hand_eye, placements=placements, seed=seed,
                                       progress=progress)
    return {
        "machine": {"cpu": platform.processor() or platform.machine(),
                    "python": platform.python_version()},
        "calibration": calib,
        "accuracy": report.summary(),
        "twin_lens_distortion": list(LensSpec().distortion),
    }


# ---------------------------------------------------------------------- speed

TARGET_SPEEDUP = 2.0
TARGET_LOCATE_FPS = 500.0


def twin_pictures(count: int = 24, *, seed: int = 0, blocks: tuple[int, int] = (4, 6)
                  ) -> list[tuple[npt.NDArray[np.uint8], tuple[float, ...]]]:
    """Arm-camera pictures of seeded twin scenes (3 colours, ``blocks`` blocks), each with
    the joints it was taken at, from the ``look`` pose turned to several bearings."""
    rng = np.random.default_rng(seed)
    config = load_arm_config()
    look = config.pose("look")
    out = []
    for i in range(count):
        scene = random_scene(seed + i, int(rng.integers(blocks[0], blocks[1] + 1)), bins=False)
        joints = (float(rng.uniform(-20.0, 20.0)), *look[1:])
        with Twin(config, scene, realtime=False, start_joints_deg=joints) as twin:
            out.append((twin.render_camera(), twin.joints_deg()))
    return out


def run_vision_bench(*, pictures: int = 24, seed: int = 0, seconds_per_case: float = 3.0,
                     intrinsics: CameraIntrinsics | None = None,
                     hand_eye: HandEyeResult | None = None) -> dict[str, Any]:
    """Detection (ours beside the vendor-style pipeline) and detect + localise speed on
    one core, on 640x480 twin pictures. Without calibration files the twin's true lens
    and camera mount stand in: the timing does not depend on their values."""
    import cv2

    from busarm.arm.kinematics import ArmKinematics
    from busarm.bench_vision import bench_detection
    from busarm.twin.model import AS_BUILT_MOUNT_ERROR, CameraMount

    shots = twin_pictures(pictures, seed=seed)
    thresholds = default_thresholds().select(["red", "green", "blue"])
    detection = bench_detection([img for img, _ in shots], thresholds,
                                seconds_per_case=seconds_per_case)
    if intrinsics is None or hand_eye is None:
        lens = LensSpec()
        intrinsics = CameraIntrinsics(model="pinhole", width_px=lens.width_px,
                                      height_px=lens.height_px,
                                      camera_matrix=lens.camera_matrix,
                                      distortion=lens.dist_coeffs)
        cam2link = CameraMount.jetauto().offset(*AS_BUILT_MOUNT_ERROR).cam2link
        hand_eye = HandEyeResult(cam2link=cam2link, board2base=np.eye(4), rms_px=0.0,
                                 per_view_rms_px=(), views_used=(), intrinsics=intrinsics)
    kin = ArmKinematics.from_config(load_arm_config())
    locator = BlockLocator(kin, intrinsics, hand_eye, ColorDetector(thresholds))
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        found = sum(len(locator.locate(img, q)) for img, q in shots)  # warm-up
        rates = []
        for _ in range(3):
            n, start = 0, time.perf_counter()
            while time.perf_counter() - start < seconds_per_case / 3:
                for img, q in shots:
                    locator.locate(img, q)
                    n += 1
            rates.append(n / (time.perf_counter() - start))
    finally:
        cv2.setNumThreads(threads)
    return {
        "machine": {"cpu": platform.processor() or platform.machine(),
                    "python": platform.python_version()},
        "pictures": len(shots), "blocks_located": found,
        "detection": detection,
        "detect_and_locate_fps": round(float(np.median(rates)), 1),
        "detect_and_locate_fps_rounds": [round(r, 1) for r in rates],
    }


# ---------------------------------------------------------------------- pick-and-sort

TARGET_SORTED = 0.98
TARGET_CYCLE_S = 5.0


def run_pick_bench(*, scenes: int = 50, seed: int = 0, blocks: tuple[int, int] = (3, 6),
                   colors: tuple[str, ...] = ("red", "green", "blue"),
                   work_dir: Path | None = None, progress: Progress = quiet) -> dict[str, Any]:
    """Pick-and-sort over seeded twin scenes, scored against the twin's truth: how many
    blocks end in their colour's bin, whether any run reports a block sorted that is not,
    the cycle time per block and the first survey's localisation error."""
    from busarm.apps.pick_sort import IN_BIN_MM, PickSorter

    if not 1 <= scenes <= 10_000:
        raise ConfigError(f"scenes = {scenes} is out of range 1..10000")
    rng = np.random.default_rng(seed)
    with tempfile.TemporaryDirectory() as tmp:
        intr_path, he_path, calib = calibrate_in_twin(work_dir or Path(tmp), seed=seed,
                                                      intrinsics_views=12, hand_eye_views=10,
                                                      progress=progress)
        intrinsics = load_intrinsics(intr_path)
        hand_eye = load_hand_eye(he_path, intrinsics=intrinsics)
    total = in_bin = false_sorted = reported_sorted = 0
    slipped = 0.0
    tilted = 0
    cycles: list[float] = []
    survey_errors: list[float] = []
    failures: list[dict[str, Any]] = []
    start = time.monotonic()
    for i in range(scenes):
        n = int(rng.integers(blocks[0], blocks[1] + 1))
        scene = random_scene(seed + i, n, list(colors), radius_mm=REACH_RADIUS_MM)
        arm, twin = open_twin_arm(scene)
        with arm, TwinCamera(twin) as camera:
            bins = {b.color: (b.x_mm, b.y_mm) for b in scene.bins}
            locator = BlockLocator(arm.kin, intrinsics, hand_eye,
                                   ColorDetector(default_thresholds().select(list(colors))),
                                   table_z_mm=arm.config.table_z_mm)

            def sim_clock(t: Twin = twin) -> float:
                return t.sim_time_s

            sorter = PickSorter(arm, camera, locator, bins, clock=sim_clock)
            first = sorter.survey()
            for t in twin.blocks():
                near = [math.hypot(s.location.x_mm - t.x_mm, s.location.y_mm - t.y_mm)
                        for s in first if s.color == t.color]
                if near:
                    survey_errors.append(min(near))
            try:
                report = sorter.run()
                error = ""
            except BusArmError as exc:  # a failed run is a result too: score what is there
                report, error = sorter.report, f"{type(exc).__name__}: {exc}"
                progress(f"scene {i + 1}: the run stopped: {error}")
            truth = twin.blocks()
            slipped += twin.slipped_s
        total += len(truth)
        placed = [math.hypot(t.x_mm - bins[t.color][0], t.y_mm - bins[t.color][1]) < IN_BIN_MM
                  for t in truth]
        in_bin += sum(placed)
        sorted_here = sum(b.outcome == "sorted" for b in report.blocks)
        reported_sorted += sorted_here
        false_sorted += max(0, sorted_here - sum(placed))
        cycles += [b.seconds for b in report.blocks if b.outcome == "sorted"]
        tilted += sum(b.outcome == "sorted" and b.grasp_pitch_deg not in (None, -90.0)
                      for b in report.blocks)
        if not all(placed) or error or sorted_here != sum(placed):
            failures.append({"scene_seed": seed + i, "blocks": n, "error": error,
                             "outcomes": [b.to_dict() for b in report.blocks],
                             "not_in_bins": [asdict(t) for t, ok in zip(truth, placed,
                                                                        strict=True) if not ok]})
        progress(f"scene {i + 1}/{scenes}: {sum(placed)}/{len(truth)} in their bins")
    errors = np.asarray(survey_errors) if survey_errors else np.asarray([math.nan])
    return {
        "machine": {"cpu": platform.processor() or platform.machine(),
                    "python": platform.python_version()},
        "calibration": calib, "scenes": scenes, "blocks": total,
        "in_their_bins": in_bin, "sorted_fraction": round(in_bin / max(total, 1), 4),
        "reported_sorted": reported_sorted, "reported_sorted_but_not": false_sorted,
        "sorted_with_a_tilted_grasp": tilted,
        "median_cycle_s": round(float(np.median(cycles)), 2) if cycles else None,
        "p95_cycle_s": round(float(np.percentile(cycles, 95)), 2) if cycles else None,
        "survey_error_median_mm": round(float(np.median(errors)), 2),
        "survey_error_p95_mm": round(float(np.percentile(errors, 95)), 2),
        "seconds": round(time.monotonic() - start, 1),
        "twin_slipped_s": round(slipped, 2),
        "failures": failures[:20],
    }
