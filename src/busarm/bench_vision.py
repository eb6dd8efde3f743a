"""Colour detection speed and agreement: :class:`ColorDetector` against the vendor's way.

``bench_detection`` runs ``vendor_style_detect`` and ``ColorDetector.detect`` over the
same frames on one core (``cv2.setNumThreads(1)``), in alternating rounds so that a
busy machine slows both alike, and reports frames/s (median and best round) and
whether they found the same blocks: per frame and colour the same count, and the
distance between matched centroids. ``synthetic_frames`` makes 640x480 test scenes:
matte blocks in the digital twin's colours on its table, with lighting falloff, a
dark arm edge, noise and a slight blur, each with the true block poses.
"""

from __future__ import annotations

import math
import os
import platform
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from busarm.twin.model import TABLE_RGB
from busarm.twin.scene import COLORS
from busarm.vision.camera import UInt8Image, check_bgr_image
from busarm.vision.color import (
    DEFAULT_MIN_AREA_PX,
    ColorDetector,
    ColorThresholds,
    Detection,
    vendor_style_detect,
)

# The twin's materials (linear RGB 0..1), as rendered under white light.
BLOCK_RGB: dict[str, tuple[float, float, float]] = COLORS
ARM_RGB = (0.12, 0.12, 0.13)


@dataclass(frozen=True)
class Block:
    """A square block seen from above: colour, centre (u, v) px, side px, yaw deg."""

    color: str
    center_px: tuple[float, float]
    side_px: float
    yaw_deg: float

    def corners_px(self) -> np.ndarray[Any, np.dtype[np.float64]]:
        """The 4 x 2 corners in pixel coordinates (integer = pixel centre)."""
        pts = cv2.boxPoints((self.center_px, (self.side_px, self.side_px), self.yaw_deg))
        return np.asarray(pts, dtype=np.float64)


def bgr_from_rgb(rgb: Sequence[float], gain: float = 1.0) -> tuple[int, int, int]:
    """8-bit BGR of a 0..1 RGB colour times ``gain`` (clipped)."""
    return tuple(int(np.clip(round(c * gain * 255.0), 0, 255)) for c in rgb[::-1])  # type: ignore[return-value]


def render_blocks(
    blocks: Iterable[Block], width_px: int = 640, height_px: int = 480, *,
    noise_sigma: float = 3.0, blur: bool = True, lighting: float = 0.0, arm: bool = False,
    seed: int = 0, palette: dict[str, tuple[float, float, float]] | None = None,
) -> UInt8Image:
    """A table-coloured frame with ``blocks`` drawn anti-aliased at sub-pixel positions.

    ``lighting`` (0..0.5) darkens the frame towards one corner by up to that fraction,
    ``arm`` adds a dark bar along the top edge (the gripper in view), ``noise_sigma`` is
    Gaussian sensor noise in levels, ``blur`` a slight 3x3 lens blur.
    """
    palette = BLOCK_RGB if palette is None else palette
    image = np.empty((height_px, width_px, 3), np.uint8)
    image[:] = bgr_from_rgb(TABLE_RGB)
    if arm:
        cv2.rectangle(image, (width_px // 3, 0), (2 * width_px // 3, height_px // 12),
                      bgr_from_rgb(ARM_RGB), cv2.FILLED)
    for block in blocks:
        pts = np.rint(block.corners_px() * 16.0).astype(np.int32)  # 4 fractional bits
        cv2.fillPoly(image, [pts], bgr_from_rgb(palette[block.color]), cv2.LINE_AA, shift=4)
    out = image.astype(np.float32)
    if lighting > 0:
        yy, xx = np.mgrid[0:height_px, 0:width_px].astype(np.float32)
        falloff = 1.0 - lighting * (xx / width_px + yy / height_px) / 2.0
        out *= falloff[..., None]
    if noise_sigma > 0:
        out += np.random.default_rng(seed).normal(0.0, noise_sigma, out.shape).astype(np.float32)
    result = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    if blur:
        result = np.asarray(cv2.GaussianBlur(result, (3, 3), 0.6), dtype=np.uint8)
    return result


def random_blocks(
    rng: np.random.Generator, count: int, width_px: int = 640, height_px: int = 480, *,
    colors: Sequence[str] = ("red", "green", "blue"), side_px: tuple[float, float] = (36, 90),
) -> list[Block]:
    """``count`` blocks of random colour, side, yaw and place, apart from each other and
    the frame's edges (so each stays one blob)."""
    blocks: list[Block] = []
    for _ in range(count * 200):
        if len(blocks) == count:
            break
        side = float(rng.uniform(*side_px))
        reach = side * math.sqrt(0.5) + 4.0
        u = float(rng.uniform(reach, width_px - reach))
        v = float(rng.uniform(reach + height_px / 12.0, height_px - reach))
        if all(math.dist((u, v), b.center_px) > reach + b.side_px * math.sqrt(0.5) + 10
               for b in blocks):
            blocks.append(Block(str(colors[int(rng.integers(len(colors)))]), (u, v), side,
                                float(rng.uniform(-45.0, 45.0))))
    return blocks


def synthetic_frames(
    count: int, *, seed: int = 0, width_px: int = 640, height_px: int = 480,
    blocks: tuple[int, int] = (3, 6), colors: Sequence[str] = ("red", "green", "blue"),
) -> list[tuple[UInt8Image, list[Block]]]:
    """``count`` scenes with 3..6 blocks each (seeded), and the blocks in each."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        n = int(rng.integers(blocks[0], blocks[1] + 1))
        scene = random_blocks(rng, n, width_px, height_px, colors=colors)
        image = render_blocks(scene, width_px, height_px, seed=seed * 100_003 + i,
                              lighting=float(rng.uniform(0.0, 0.3)), arm=bool(i % 2))
        out.append((image, scene))
    return out


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
    """Frames per second of ``fn`` cycling over ``frames`` for about ``seconds``."""
    n = 0
    start = time.perf_counter()
    deadline = start + seconds
    while True:
        for frame in frames:
            fn(frame)
            n += 1
        now = time.perf_counter()
        if now >= deadline:
            return n / (now - start)


def bench_detection(
    frames: Sequence[UInt8Image], thresholds: ColorThresholds,
    colors: Iterable[str] | str | None = None, *, seconds_per_case: float = 3.0,
    rounds: int = 6, min_area_px: float = DEFAULT_MIN_AREA_PX,
) -> dict[str, Any]:
    """Frames/s of the vendor-style pipeline and of ``ColorDetector`` on one core, and
    their agreement on ``frames``. ``seconds_per_case`` is each side's total time, split
    into ``rounds`` alternating rounds. Returns a JSON-ready dict."""
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
        # Agreement first (it is also the warm-up).
        same_frames = 0
        mismatches: list[dict[str, Any]] = []
        distances: list[float] = []
        unmatched = 0
        vendor_blocks = ours_blocks = 0
        for i, image in enumerate(images):
            ref, got = vendor(image), detector.detect(image)
            vendor_blocks += len(ref)
            ours_blocks += len(got)
            counts_ref = {c: sum(d.color == c for d in ref) for c in names}
            counts_got = {c: sum(d.color == c for d in got) for c in names}
            if counts_ref == counts_got:
                same_frames += 1
            else:
                mismatches.append({"frame": i, "vendor": counts_ref, "ours": counts_got})
            pairs = match_detections(ref, got)
            distances.extend(d for _, _, d in pairs)
            unmatched += len(ref) + len(got) - 2 * len(pairs)
        per_round = seconds_per_case / rounds
        vendor_fps: list[float] = []
        ours_fps: list[float] = []
        for _ in range(rounds):
            vendor_fps.append(_rate(vendor, images, per_round))
            ours_fps.append(_rate(detector.detect, images, per_round))
    finally:
        cv2.setNumThreads(threads)
    dist = np.array(distances) if distances else np.zeros(1)
    v_med, o_med = float(np.median(vendor_fps)), float(np.median(ours_fps))
    return {
        "frames": len(images),
        "width_px": int(images[0].shape[1]),
        "height_px": int(images[0].shape[0]),
        "colors": names,
        "min_area_px": min_area_px,
        "threads": 1,
        "rounds": rounds,
        "seconds_per_case": seconds_per_case,
        "vendor_fps": round(v_med, 1),
        "ours_fps": round(o_med, 1),
        "speedup": round(o_med / v_med, 3),
        "vendor_fps_best": round(max(vendor_fps), 1),
        "ours_fps_best": round(max(ours_fps), 1),
        "vendor_fps_rounds": [round(x, 1) for x in vendor_fps],
        "ours_fps_rounds": [round(x, 1) for x in ours_fps],
        "agreement": {
            "same_counts_frames": same_frames,
            "all_same_counts": same_frames == len(images),
            "count_mismatches": mismatches[:20],
            "vendor_blocks": vendor_blocks,
            "ours_blocks": ours_blocks,
            "matched": len(distances),
            "unmatched": unmatched,
            "centroid_distance_px": {
                "mean": round(float(dist.mean()), 4),
                "median": round(float(np.median(dist)), 4),
                "p95": round(float(np.percentile(dist, 95)), 4),
                "max": round(float(dist.max()), 4),
            },
        },
        "machine": {
            "cpu": platform.processor() or platform.machine(),
            "cpus": os.cpu_count(),
            "opencv": cv2.__version__,
            "numpy": np.__version__,
        },
    }


__all__ = [
    "BLOCK_RGB",
    "TABLE_RGB",
    "Block",
    "bench_detection",
    "bgr_from_rgb",
    "match_detections",
    "random_blocks",
    "render_blocks",
    "synthetic_frames",
]
