"""``busarm bench track``: colour tracking on the twin, against the twin's truth.

Run ``i`` (seed ``i``) slides a red block along the mover's ``PATH_KINDS[i % 3]`` (circle,
figure-eight, a walk drawn from the seed) at ``SPEEDS_MM_S[(i // 3) % 3]`` mm/s, after it
has rested ``REST_S`` for the arm to find it; ``busarm track``'s job follows it for
``seconds`` of twin time. Each frame is scored with the twin's truth, which only this
module reads: the block's true top centre projected through the twin's own camera pose
and lens (``truth_error_px``), not the job's detection; from when the block starts to
move. The targets: at least ``TARGET_WITHIN`` of the frames within ``CENTRED_PX`` of the
image centre at every speed up to 50 mm/s.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from busarm.apps.track.job import CENTRED_PX, TrackJob, TrackSettings
from busarm.bench.common import (
    Progress,
    SeededBenchReport,
    Verdict,
    machine_info,
    quiet,
    run_seeded_bench,
)
from busarm.robot import Robot
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.twin.mover import PATH_KINDS, BlockMover, named_path, track_scene
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin
from busarm.units import check_range

__all__ = [
    "MAX_WORKERS",
    "REST_S",
    "SPEEDS_MM_S",
    "TARGET_WITHIN",
    "TrackBenchReport",
    "TrackRun",
    "run_track",
    "run_track_bench",
    "truth_error_px",
]


SPEEDS_MM_S = (20.0, 35.0, 50.0)
TARGET_WITHIN = 0.9
REST_S = 1.0
"""The block rests at its path's start this long first: the arm finds it."""
MAX_WORKERS = 8
COLOR = "red"


def truth_error_px(twin: Twin, index: int = 0) -> float:
    """How far from the image centre block ``index``'s top centre really is (px): its
    true place through the twin's own camera pose and lens (ground truth)."""
    import cv2

    block = twin.blocks()[index]
    cam2base = twin.cam2base_from_mujoco()
    top = np.array([block.x_mm, block.y_mm, block.z_mm + block.size_mm / 2])
    base2cam = np.linalg.inv(cam2base)
    point = base2cam[:3, :3] @ top + base2cam[:3, 3]
    lens = twin.lens
    px, _ = cv2.projectPoints(point.reshape(1, 1, 3), np.zeros(3), np.zeros(3),
                              lens.camera_matrix, lens.dist_coeffs)
    u, v = (float(c) for c in px.reshape(2))
    return math.hypot(u - (lens.width_px - 1) / 2, v - (lens.height_px - 1) / 2)


@dataclass
class TrackRun:
    seed: int
    path: str
    speed_mm_s: float
    frames: int = 0
    within: float = 0.0
    median_px: float = math.nan
    p95_px: float = math.nan
    max_px: float = math.nan
    latency_median_ms: float = math.nan
    latency_p95_ms: float = math.nan
    compute_median_ms: float = math.nan
    """This computer's time from a frame to its command (the twin's clock counts only
    the bus)."""
    compute_p95_ms: float = math.nan
    stop: str = ""
    seconds: float = 0.0
    wall_s: float = 0.0


def run_track(seed: int, intrinsics: Path, hand_eye: Path, seconds: float = 10.0) -> TrackRun:
    """One seeded run on a twin of its own (this process)."""
    wall = time.monotonic()
    kind = PATH_KINDS[seed % len(PATH_KINDS)]
    speed = SPEEDS_MM_S[(seed // len(PATH_KINDS)) % len(SPEEDS_MM_S)]
    path = named_path(kind, seed)
    x0, y0, _, _ = path.at(0.0)
    out = TrackRun(seed, path.name, speed)
    with Robot.open(RobotConfig(
            TwinSpec(scene=track_scene(COLOR, (x0, y0))),
            camera=CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye))) as robot:
        twin = robot.twin
        assert twin is not None
        mover = BlockMover(twin, path, speed, start_after_s=REST_S).attach()
        moving_from = twin.sim_time_s + REST_S
        errors: list[float] = []

        def on_frame(frame: Any) -> None:
            if twin.sim_time_s >= moving_from:
                errors.append(truth_error_px(twin))

        job = TrackJob(robot, COLOR, settings=TrackSettings(seconds=seconds + REST_S),
                       on_frame=on_frame)
        report = job.run()
        mover.detach()
    _score(out, errors, report.latencies_s)
    cpu = report.compute_stats_s()
    if cpu is not None:
        out.compute_median_ms, out.compute_p95_ms = cpu[0] * 1000, cpu[1] * 1000
    out.stop, out.seconds = report.why, report.seconds
    out.wall_s = time.monotonic() - wall
    return out


def _score(out: TrackRun, errors: list[float], latencies_s: list[float]) -> None:
    out.frames = len(errors)
    if errors:
        out.within = sum(e <= CENTRED_PX for e in errors) / len(errors)
        out.median_px = float(np.median(errors))
        out.p95_px = float(np.percentile(errors, 95))
        out.max_px = max(errors)
    if latencies_s:
        out.latency_median_ms = float(np.median(latencies_s)) * 1000
        out.latency_p95_ms = float(np.percentile(latencies_s, 95)) * 1000


@dataclass
class TrackBenchReport(SeededBenchReport[TrackRun]):
    def summary(self) -> dict[str, Any]:
        by_speed = {}
        for speed in sorted({r.speed_mm_s for r in self.runs}):
            runs = [r for r in self.runs if r.speed_mm_s == speed]
            frames = sum(r.frames for r in runs)
            by_speed[f"{speed:g}"] = {
                "runs": len(runs), "frames": frames,
                "within": round(sum(r.within * r.frames for r in runs) / frames, 4)
                if frames else 0.0,
                "worst_within": round(min(r.within for r in runs), 4),
                "median_px": round(float(np.median([r.median_px for r in runs])), 2),
                "p95_px": round(max(r.p95_px for r in runs), 2)}
        lat = [r.latency_median_ms for r in self.runs if math.isfinite(r.latency_median_ms)]
        return {"runs": len(self.runs), "by_speed_mm_s": by_speed,
                "latency_median_ms": round(float(np.median(lat)), 2) if lat else None,
                "latency_p95_ms": round(max(r.latency_p95_ms for r in self.runs), 2)
                if lat else None,
                "compute_median_ms": _median([r.compute_median_ms for r in self.runs]),
                "compute_p95_ms": _median([r.compute_p95_ms for r in self.runs])}

    def text(self, verdict: Verdict) -> str:
        rows = [f"{'seed':>4} {'path':8} {'mm/s':>5} {'frames':>6} {'<=40px':>7} "
                f"{'median':>7} {'p95':>6} {'max':>6} {'latency ms':>11} {'cpu ms':>11}  stop"]
        rows += [f"{r.seed:4d} {r.path:8} {r.speed_mm_s:5.0f} {r.frames:6d} "
                 f"{r.within * 100:6.1f}% {r.median_px:7.1f} {r.p95_px:6.1f} {r.max_px:6.1f} "
                 f"{r.latency_median_ms:5.1f}/{r.latency_p95_ms:5.1f} "
                 f"{r.compute_median_ms:5.1f}/{r.compute_p95_ms:5.1f}  {r.stop}"
                 for r in self.runs]
        s = self.summary()
        lines = [f"{s['runs']} seeded runs, a red block slid about, scored with the twin's "
                 "truth (pixel error: the block's true top centre from the image centre)",
                 *rows]
        for speed, v in s["by_speed_mm_s"].items():
            lines.append(f"at {speed} mm/s: {v['within'] * 100:.1f}% of {v['frames']} frames "
                         f"within {CENTRED_PX:g} px {verdict(v['worst_within'] >= TARGET_WITHIN)}"
                         f" (each run >= {TARGET_WITHIN * 100:g}%), median {v['median_px']} "
                         f"px, p95 {v['p95_px']} px")
        lines.append(f"latency frame -> command: median {s['latency_median_ms']} ms, p95 "
                     f"{s['latency_p95_ms']} ms of twin time (the bus), with this computer's "
                     f"work from frame to command: median {s['compute_median_ms']} ms, p95 "
                     f"{s['compute_p95_ms']} ms (medians of the runs); {self.time_text}")
        return "\n".join(lines)


def _median(values: list[float]) -> float | None:
    finite = [v for v in values if math.isfinite(v)]
    return round(float(np.median(finite)), 2) if finite else None


def _run_line(done: int, total: int, r: TrackRun) -> str:
    return (f"run {done}/{total} (seed {r.seed}, {r.path} at {r.speed_mm_s:g} mm/s): "
            f"{r.within * 100:.1f}% within {CENTRED_PX:g} px, median {r.median_px:.1f} px, "
            f"p95 {r.p95_px:.1f} px; {r.wall_s:.0f} s here")


def run_track_bench(*, runs: int = 9, seed: int = 0, workers: int = 1,
                    progress: Progress = quiet) -> TrackBenchReport:
    """Tracking over ``runs`` seeded runs (seeds ``seed``..; see the module docstring)."""
    check_range("runs", runs, 1, 1000)
    return run_seeded_bench(TrackBenchReport(machine_info(), workers=workers), run_track,
                            _run_line, what="runs", count=runs, seed=seed,
                            max_workers=MAX_WORKERS, progress=progress)
