"""``busarm bench pick`` through its real path: the calibration made in a twin, scenes on
twins in worker processes, scored against the twins' truth, times in twin seconds."""

from __future__ import annotations

import pytest

from busarm.bench.pick import run_pick_bench
from busarm.errors import ConfigError

pytestmark = pytest.mark.slow  # benchmark runs


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_scenes_sorted_in_two_worker_processes_are_scored_in_scene_order() -> None:
    lines: list[str] = []
    report = run_pick_bench(scenes=3, seed=7, blocks=(1, 2), workers=2, progress=lines.append)
    assert report.scenes == 3 and report.workers == 2 and report.clock == "simulated"
    assert 3 <= report.blocks <= 6
    assert report.in_their_bins == report.blocks == report.reported_sorted
    assert report.reported_sorted_but_not == 0 and report.failures == []
    assert report.beyond_bins == 0 and report.fitting_sorted_fraction == 1.0
    assert len(report.cycles_s) == report.blocks
    assert report.median_cycle_s is not None and 2.0 < report.median_cycle_s < 6.0
    # Twin seconds, not wall ones: each scene's moves take seconds of twin time.
    assert report.sim_seconds > 2.0 * report.blocks
    assert report.speedup == pytest.approx(report.sim_seconds / report.seconds, rel=0.02)
    assert report.calibration.hand_eye.error_vs_truth_mm < 3.0
    # Scored from the runs' own first surveys (none made for the bench alone).
    assert report.survey_error_median_mm is not None and report.survey_error_median_mm < 2.0
    assert sum("in their bins" in line for line in lines) == 3
    # The same seeds give the same scenes, in one process as in two.
    again = run_pick_bench(scenes=1, seed=7, blocks=(1, 2))
    assert again.cycles_s == report.cycles_s[: len(again.cycles_s)]


def test_bad_benchmark_sizes_are_refused() -> None:
    with pytest.raises(ConfigError, match="scenes = 0 is out of range 1..10000"):
        run_pick_bench(scenes=0)
    with pytest.raises(ConfigError, match="workers = 65 is out of range 1..64"):
        run_pick_bench(scenes=1, workers=65)
