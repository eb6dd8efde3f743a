"""What the benchmarks share: the machine they ran on, latency percentiles, the progress
callback, the summary of the twin calibration the vision benchmarks start with, and the
report and runner of the benchmarks over seeded twin worlds (transport, line)."""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Generic, TypeVar

from busarm.errors import ConfigError
from busarm.progress import Progress, quiet
from busarm.robot.seeded_runs import run_seeded
from busarm.units import check_int_range

R = TypeVar("R")

if TYPE_CHECKING:
    from busarm.robot.twin_calibration import TwinCalibration
    from busarm.vision.calibration import CameraIntrinsics

__all__ = [
    "CalibrationSummary",
    "HandEyeFit",
    "IntrinsicsFit",
    "Progress",
    "SeededBenchReport",
    "Verdict",
    "latency_percentiles_ms",
    "machine_info",
    "machine_line",
    "quiet",
    "run_seeded",
    "run_seeded_bench",
    "short_machine_info",
]


def machine_info() -> dict[str, str]:
    """What ran the benchmark, for docs/benchmarks.md: cpu, cores, python, os."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": str(os.cpu_count()),
        "python": platform.python_version(),
        "os": f"{platform.system()} {platform.release()}",
    }


def machine_line(machine: dict[str, str], *, with_os: bool = True) -> str:
    """``machine_info`` as a report's line: cpu, cores, Python (and the os)."""
    m = machine
    return (f"machine: {m['cpu']}, {m['cores']} cores, Python {m['python']}"
            + (f", {m['os']}" if with_os else ""))


def short_machine_info() -> dict[str, str]:
    """The processor and Python version only (the twin benchmarks' reports)."""
    return {"cpu": platform.processor() or platform.machine(),
            "python": platform.python_version()}


def latency_percentiles_ms(samples_s: Sequence[float]) -> dict[str, float]:
    """p50, p90, p99 and max of durations in seconds, in milliseconds."""
    ordered = sorted(samples_s)

    def pct(p: float) -> float:
        return ordered[min(len(ordered) - 1, int(p * len(ordered)))] * 1e3

    return {"p50": round(pct(0.50), 4), "p90": round(pct(0.90), 4),
            "p99": round(pct(0.99), 4), "max": round(ordered[-1] * 1e3, 4)}


@dataclass
class IntrinsicsFit:
    """The intrinsics calibration made in the twin: reprojection error and focal/centre."""

    rms_px: float
    views: int
    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float


@dataclass
class HandEyeFit:
    """The hand-eye calibration made in the twin, and how far it is from the true mount."""

    rms_px: float
    views: int
    error_vs_truth_mm: float
    error_vs_truth_deg: float


@dataclass
class CalibrationSummary:
    """Both calibrations a twin benchmark made with our own flows before measuring."""

    intrinsics: IntrinsicsFit
    hand_eye: HandEyeFit

    @classmethod
    def of(cls, run: TwinCalibration | None, i: CameraIntrinsics) -> CalibrationSummary:
        """From a calibration made in the twin (``Robot.open`` or ``calibrate_twin_camera``)
        and the intrinsics it found."""
        if run is None or run.intrinsics_rms_px is None:
            raise ConfigError("a benchmark's calibration must be made in the twin, "
                              "intrinsics and hand-eye")
        return cls(IntrinsicsFit(run.intrinsics_rms_px, run.intrinsics_views, i.fx, i.fy, i.cx,
                                 i.cy),
                   HandEyeFit(run.hand_eye_rms_px, run.hand_eye_views, run.hand_eye_error_mm,
                              run.hand_eye_error_deg))


Verdict = Callable[[bool], str]
"""How a report's text shows a target met (True) or missed: the command line's ok or
FAIL (which it counts)."""


@dataclass
class SeededBenchReport(Generic[R]):
    """A benchmark over seeded twin worlds, one run each (``run_seeded_bench``): the
    machine, the runs in seed order, the seconds it all took here and the workers."""

    machine: dict[str, str]
    runs: list[R] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1

    def summary(self) -> dict[str, Any]:
        """The figures over all the runs."""
        raise NotImplementedError

    def text(self, verdict: Verdict) -> str:
        """The report for a person (after the benchmark's name), each target judged."""
        raise NotImplementedError

    @property
    def time_text(self) -> str:
        return f"{self.seconds:.0f} s on this computer, {self.workers} worker(s)"

    def run_dict(self, run: R) -> dict[str, Any]:
        """One run as the JSON report gives it."""
        return asdict(run)  # type: ignore[call-overload, no-any-return]

    def to_dict(self) -> dict[str, Any]:
        return {"machine": self.machine, "seconds": self.seconds, "workers": self.workers,
                "summary": self.summary(), "runs": [self.run_dict(r) for r in self.runs]}


B = TypeVar("B", bound=SeededBenchReport[Any])


def run_seeded_bench(report: B, task: Callable[[int, Path, Path], Any],
                     describe: Callable[[int, int, Any], str], *, what: str, count: int,
                     seed: int, max_workers: int, progress: Progress = quiet) -> B:
    """``report`` filled with ``task`` run on ``count`` seeds from ``seed`` (``what``: the
    count's name, checked 1..1000), on ``report.workers`` processes (``run_seeded``)."""
    check_int_range(what, count, 1, 1000)
    check_int_range("workers", report.workers, 1, max_workers)
    start = time.monotonic()
    report.runs = run_seeded(task, [seed + i for i in range(count)], report.workers, progress,
                             describe)
    report.seconds = time.monotonic() - start
    return report
