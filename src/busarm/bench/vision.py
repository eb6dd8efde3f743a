"""``busarm bench vision``: colour detection speed and agreement, and detect + localise.

``bench_detection`` runs ``vendor_style_detect`` and ``ColorDetector.detect`` over the
same frames on one core (``cv2.setNumThreads(1)``), in alternating rounds so that a
busy machine slows both alike, and reports frames/s (median and best round) and
whether they found the same blocks: per frame and colour the same count, and the
distance between matched centroids. ``run_vision_bench`` does that on 640x480 twin
pictures and adds, per scene family (``random``: spaced-out blocks; ``clutter``: the pick
bench's cluttered tables), the detect + localise rate (``BlockLocator.locate`` without
shape judging: colour blobs, touching blocks split, yaw, position, reach) and, apart,
the rate with each blob's shape judged and measured (``locate``'s default, a box fit
per blob: far slower, no target).

Rates are frames per second of the process's CPU time (``time.process_time``: one core's
time, OpenCV on one thread), over rounds of a set wall-clock length: on a machine shared
with other work the wall clock counts the time other processes held the cores, and the
rates would say more about them than about the code; on an idle machine the two agree.
Both detectors run in the same process, after the same rendering, so that they meet the
C allocator in the same state (in a fresh process the vendor's full-frame buffers go
back to the system after every frame and are faulted in again: half as slow again).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np
import numpy.typing as npt

from busarm.bench.common import short_machine_info
from busarm.errors import ConfigError
from busarm.vision.calibration import CameraIntrinsics, HandEyeResult
from busarm.vision.camera import UInt8Image, check_bgr_image
from busarm.vision.color import (
    DEFAULT_MIN_AREA_PX,
    ColorDetector,
    Detection,
    vendor_style_detect,
)
from busarm.vision.color_thresholds import ColorThresholds, default_thresholds

if TYPE_CHECKING:
    from busarm.perception.locate import BlockLocator

__all__ = [
    "FAMILIES",
    "MAX_MISMATCHES",
    "TARGET_CLUTTER_FPS",
    "TARGET_LOCATE_FPS",
    "TARGET_SPEEDUP",
    "Agreement",
    "CountMismatch",
    "Detect",
    "DetectionReport",
    "DistanceStats",
    "LocateRate",
    "VisionBenchReport",
    "bench_detection",
    "match_detections",
    "run_vision_bench",
    "twin_pictures",
]


TARGET_SPEEDUP = 3.0
TARGET_LOCATE_FPS = 500.0
"""Detect + localise on the ``random`` family's pictures, frames/s."""
TARGET_CLUTTER_FPS = 300.0
"""Detect + localise on the ``clutter`` family's pictures, frames/s."""
FAMILIES = {"random": (4, 6), "clutter": (6, 12)}
"""Scene families pictured and the blocks a scene of each has: ``random``
(``busarm.twin.scene.random_scene``) and ``clutter`` (rows, clusters, touching groups,
things that are not blocks, lamp or window light: ``busarm.twin.clutter``, as many blocks
as ``busarm bench pick --family clutter`` sorts). Neither has trays."""
MAX_MISMATCHES = 20
"""Frames whose counts differ that the report lists (it counts them all)."""


@dataclass
class CountMismatch:
    """A frame where the two pipelines found different numbers of blocks of some colour."""

    frame: int
    vendor: dict[str, int]
    ours: dict[str, int]


@dataclass
class DistanceStats:
    """Centroid distances (px) between matched detections of the two pipelines."""

    mean: float
    median: float
    p95: float
    max: float


@dataclass
class Agreement:
    """Whether the two pipelines found the same blocks."""

    same_counts_frames: int
    all_same_counts: bool
    count_mismatches: list[CountMismatch]
    """The first ``MAX_MISMATCHES``."""
    vendor_blocks: int
    ours_blocks: int
    matched: int
    unmatched: int
    centroid_distance_px: DistanceStats


@dataclass
class DetectionReport:
    """Frames/s of the vendor-style pipeline and of ``ColorDetector`` on one core, and
    their agreement."""

    frames: int
    width_px: int
    height_px: int
    colors: list[str]
    min_area_px: float
    threads: int
    rounds: int
    seconds_per_case: float
    vendor_fps: float
    ours_fps: float
    speedup: float
    vendor_fps_best: float
    ours_fps_best: float
    vendor_fps_rounds: list[float]
    ours_fps_rounds: list[float]
    agreement: Agreement
    machine: dict[str, str | int | None]
    """cpu, cpus, opencv, numpy."""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


@dataclass
class LocateRate:
    """Detect + localise on one scene family's pictures, on one core."""

    family: str
    pictures: int
    blocks_located: int
    fps: float
    """``BlockLocator.locate`` without judging shapes: median of the rounds."""
    fps_rounds: list[float]
    target_fps: float
    judged_fps: float
    """``locate`` as it is called by default (each blob's shape judged and measured by a
    box fit): one pass over the pictures. No target."""
    judged_blocks: int

    @property
    def met(self) -> bool:
        return self.fps >= self.target_fps


@dataclass
class VisionBenchReport:
    """``busarm bench vision``: detection on twin pictures, and detect + localise."""

    machine: dict[str, str]
    pictures: int
    blocks_located: int
    detection: DetectionReport
    """On the first family's pictures."""
    detect_and_locate_fps: float
    """The first family's (median of the rounds)."""
    detect_and_locate_fps_rounds: list[float]
    families: list[LocateRate]
    """Detect + localise per scene family, the first one's as above."""

    def to_dict(self) -> dict[str, object]:
        return asdict(self)


# ---------------------------------------------------------------------- detection


def match_detections(
    reference: Sequence[Detection], other: Sequence[Detection], max_distance_px: float = 10.0
) -> list[tuple[Detection, Detection, float]]:
    """Pairs (reference, other, centroid distance) of one colour, nearest first, each
    detection used once, no further apart than ``max_distance_px``."""
    candidates = sorted(
        (math.dist(a.centroid_px, b.centroid_px), i, j)
        for i, a in enumerate(reference) for j, b in enumerate(other) if a.color == b.color
    )
    used_a: set[int] = set()
    used_b: set[int] = set()
    pairs = []
    for d, i, j in candidates:
        if d <= max_distance_px and i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            pairs.append((reference[i], other[j], d))
    return pairs


def _rate(fn: Callable[[UInt8Image], object], frames: Sequence[UInt8Image],
          seconds: float) -> float:
    """Frames per CPU second of ``fn`` cycling over ``frames`` for about ``seconds`` (wall
    clock)."""
    n = 0
    cpu = time.process_time()
    deadline = time.perf_counter() + seconds
    while True:
        for frame in frames:
            fn(frame)
            n += 1
        if time.perf_counter() >= deadline:
            return n / max(time.process_time() - cpu, 1e-9)


Detect = Callable[[UInt8Image], list[Detection]]


def _agreement(images: Sequence[UInt8Image], vendor: Detect, ours: Detect,
               names: Sequence[str]) -> Agreement:
    """Per frame and colour the same count, and the distance between matched centroids."""
    same_frames = 0
    mismatches: list[CountMismatch] = []
    distances: list[float] = []
    unmatched = 0
    vendor_blocks = ours_blocks = 0
    for i, image in enumerate(images):
        ref, got = vendor(image), ours(image)
        vendor_blocks += len(ref)
        ours_blocks += len(got)
        counts_ref = {c: sum(d.color == c for d in ref) for c in names}
        counts_got = {c: sum(d.color == c for d in got) for c in names}
        if counts_ref == counts_got:
            same_frames += 1
        else:
            mismatches.append(CountMismatch(i, counts_ref, counts_got))
        pairs = match_detections(ref, got)
        distances.extend(d for _, _, d in pairs)
        unmatched += len(ref) + len(got) - 2 * len(pairs)
    dist = np.array(distances) if distances else np.zeros(1)
    return Agreement(
        same_frames, same_frames == len(images), mismatches[:MAX_MISMATCHES], vendor_blocks,
        ours_blocks, len(distances), unmatched,
        DistanceStats(round(float(dist.mean()), 4), round(float(np.median(dist)), 4),
                      round(float(np.percentile(dist, 95)), 4), round(float(dist.max()), 4)),
    )


def bench_detection(
    frames: Sequence[UInt8Image], thresholds: ColorThresholds,
    colors: Iterable[str] | str | None = None, *, seconds_per_case: float = 3.0,
    rounds: int = 6, min_area_px: float = DEFAULT_MIN_AREA_PX,
) -> DetectionReport:
    """Frames/s of the vendor-style pipeline and of ``ColorDetector`` on one core, and
    their agreement on ``frames``. ``seconds_per_case`` is each side's total time, split
    into ``rounds`` alternating rounds."""
    if not frames:
        raise ValueError("bench_detection needs at least one frame")
    images = [check_bgr_image(f, f"frame {i}") for i, f in enumerate(frames)]
    detector = ColorDetector(thresholds, colors, min_area_px=min_area_px)
    names = detector.colors

    def vendor(image: UInt8Image) -> list[Detection]:
        return vendor_style_detect(image, thresholds, names, min_area_px=min_area_px)

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        agreement = _agreement(images, vendor, detector.detect, names)  # also the warm-up
        per_round = seconds_per_case / rounds
        vendor_fps: list[float] = []
        ours_fps: list[float] = []
        for _ in range(rounds):
            vendor_fps.append(_rate(vendor, images, per_round))
            ours_fps.append(_rate(detector.detect, images, per_round))
    finally:
        cv2.setNumThreads(threads)
    v_med, o_med = float(np.median(vendor_fps)), float(np.median(ours_fps))
    return DetectionReport(
        frames=len(images), width_px=int(images[0].shape[1]), height_px=int(images[0].shape[0]),
        colors=names, min_area_px=min_area_px, threads=1, rounds=rounds,
        seconds_per_case=seconds_per_case, vendor_fps=round(v_med, 1), ours_fps=round(o_med, 1),
        speedup=round(o_med / v_med, 3), vendor_fps_best=round(max(vendor_fps), 1),
        ours_fps_best=round(max(ours_fps), 1),
        vendor_fps_rounds=[round(x, 1) for x in vendor_fps],
        ours_fps_rounds=[round(x, 1) for x in ours_fps],
        agreement=agreement,
        machine={"cpu": _processor(), "cpus": os.cpu_count(), "opencv": cv2.__version__,
                 "numpy": np.__version__},
    )


def _processor() -> str:
    return short_machine_info()["cpu"]


# ---------------------------------------------------------------------- twin pictures


def twin_pictures(count: int = 24, *, seed: int = 0, blocks: tuple[int, int] | None = None,
                  family: str = "random"
                  ) -> list[tuple[npt.NDArray[np.uint8], tuple[float, ...]]]:
    """Arm-camera pictures of seeded twin scenes of ``family`` (``FAMILIES``; 3 colours,
    ``blocks`` blocks, by default the family's), each with the joints it was taken at,
    from the ``look`` pose turned to several bearings."""
    from busarm.arm.config import load_arm_config
    from busarm.twin.clutter import clutter_scene
    from busarm.twin.scene import random_scene
    from busarm.twin.twin import Twin

    if family not in FAMILIES:
        raise ConfigError(f"family {family!r}: one of {', '.join(FAMILIES)}")
    lo, hi = FAMILIES[family] if blocks is None else blocks
    rng = np.random.default_rng(seed)
    config = load_arm_config()
    look = config.pose("look")
    out = []
    for i in range(count):
        n = int(rng.integers(lo, hi + 1))
        scene = (clutter_scene(seed + i, n, bins=False) if family == "clutter"
                 else random_scene(seed + i, n, bins=False))
        joints = (float(rng.uniform(-20.0, 20.0)), *look[1:])
        with Twin(config, scene, realtime=False, start_joints_deg=joints) as twin:
            out.append((twin.render_camera(), twin.joints_deg()))
    return out


def _true_camera() -> tuple[CameraIntrinsics, HandEyeResult]:
    """The twin's true lens and as-built camera mount, as calibration results."""
    from busarm.arm.camera_mount import CameraMount
    from busarm.twin.lens import LensSpec
    from busarm.twin.model import AS_BUILT_MOUNT_ERROR

    lens = LensSpec()
    intrinsics = CameraIntrinsics(model="pinhole", width_px=lens.width_px,
                                  height_px=lens.height_px, camera_matrix=lens.camera_matrix,
                                  distortion=lens.dist_coeffs)
    cam2link = CameraMount.jetauto().offset(*AS_BUILT_MOUNT_ERROR).cam2link
    hand_eye = HandEyeResult(cam2link=cam2link, board2base=np.eye(4), rms_px=0.0,
                             per_view_rms_px=(), views_used=(), intrinsics=intrinsics)
    return intrinsics, hand_eye


def run_vision_bench(*, pictures: int = 24, seed: int = 0, seconds_per_case: float = 3.0,
                     intrinsics: CameraIntrinsics | None = None,
                     hand_eye: HandEyeResult | None = None,
                     families: Sequence[str] = ("random", "clutter")) -> VisionBenchReport:
    """Detection (ours beside the vendor-style pipeline, on the first family's pictures)
    and detect + localise speed per scene family, on one core, on 640x480 twin pictures.
    Without calibration files the twin's true lens and camera mount stand in: the timing
    does not depend on their values."""
    from busarm.arm.config import load_arm_config
    from busarm.arm.kinematics import ArmKinematics
    from busarm.perception.locate import BlockLocator

    if not families or any(f not in FAMILIES for f in families):
        raise ConfigError(f"families {', '.join(families)}: some of {', '.join(FAMILIES)}")
    thresholds = default_thresholds().select(["red", "green", "blue"])
    if intrinsics is None or hand_eye is None:
        intrinsics, hand_eye = _true_camera()
    kin = ArmKinematics.from_config(load_arm_config())
    locator = BlockLocator(kin, intrinsics, hand_eye, ColorDetector(thresholds))
    detection: DetectionReport | None = None
    rates = []
    for family in families:
        shots = twin_pictures(pictures, seed=seed, family=family)
        if detection is None:
            detection = bench_detection([img for img, _ in shots], thresholds,
                                        seconds_per_case=seconds_per_case)
        rates.append(_locate_rate(locator, family, shots, seconds_per_case))
    assert detection is not None
    first = rates[0]
    return VisionBenchReport(
        machine=short_machine_info(), pictures=first.pictures,
        blocks_located=first.blocks_located, detection=detection,
        detect_and_locate_fps=first.fps, detect_and_locate_fps_rounds=first.fps_rounds,
        families=rates,
    )


def _locate_rate(locator: BlockLocator, family: str,
                 shots: Sequence[tuple[npt.NDArray[np.uint8], tuple[float, ...]]],
                 seconds: float) -> LocateRate:
    """Detect + localise frames per CPU second over ``shots`` on one core: three rounds
    of ``seconds / 3`` (wall clock) without judging shapes, then one pass judging them."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        found = sum(len(locator.locate(img, q, judge=False)) for img, q in shots)  # warm-up
        rates = []
        for _ in range(3):
            n, start, cpu = 0, time.perf_counter(), time.process_time()
            while time.perf_counter() - start < seconds / 3:
                for img, q in shots:
                    locator.locate(img, q, judge=False)
                    n += 1
            rates.append(n / max(time.process_time() - cpu, 1e-9))
        cpu = time.process_time()
        judged = sum(len(locator.locate(img, q)) for img, q in shots)
        judged_fps = len(shots) / max(time.process_time() - cpu, 1e-9)
    finally:
        cv2.setNumThreads(threads)
    target = TARGET_CLUTTER_FPS if family == "clutter" else TARGET_LOCATE_FPS
    return LocateRate(
        family=family, pictures=len(shots), blocks_located=found,
        fps=round(float(np.median(rates)), 1), fps_rounds=[round(r, 1) for r in rates],
        target_fps=target, judged_fps=round(judged_fps, 2), judged_blocks=judged)
