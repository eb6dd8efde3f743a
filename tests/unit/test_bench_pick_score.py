"""How ``busarm bench pick`` scores a scene (``busarm.bench.pick._score``): blocks in their
bins by the twin's truth, blocks beyond what a bin holds counted apart, and a scene where a
thing that is not a block moved listed with how far, even if every block was sorted."""

from __future__ import annotations

from pathlib import Path

import pytest

from busarm.apps.pick_sort.bins import BIN_PLACES
from busarm.apps.pick_sort.outcomes import BlockOutcome
from busarm.bench.common import CalibrationSummary, HandEyeFit, IntrinsicsFit
from busarm.bench.pick import SceneResult, SceneTask, _score
from busarm.twin.twin import BlockState

BIN = (60.0, 180.0)
CALIBRATION = CalibrationSummary(IntrinsicsFit(0.1, 20, 500.0, 500.0, 320.0, 240.0),
                                 HandEyeFit(0.2, 12, 0.5, 0.1))


def _result(seed: int, in_bin: int, on_table: int, moved_mm: list[float]) -> SceneResult:
    task = SceneTask(seed, seed, in_bin + on_table, ("red",), Path("c"), Path("h"), False,
                     "clutter")
    truth = [BlockState(i, "red", BIN[0] + (0.0 if i < in_bin else 150.0), BIN[1], 15.0, 0.0,
                        30.0, True) for i in range(in_bin + on_table)]
    outcomes = [BlockOutcome("red", (200.0, float(i)), "sorted" if i < in_bin else "skipped",
                             "" if i < in_bin else "bin full", seconds=4.0)
                for i in range(in_bin + on_table)]
    return SceneResult(task, {"red": BIN}, truth, outcomes, "", [0.5], 40.0, 4.0, 0.0,
                       distractors_moved_mm=moved_mm)


def test_blocks_beyond_a_full_bin_are_counted_apart() -> None:
    full = len(BIN_PLACES)
    report = _score([_result(0, full, 2, []), _result(1, 3, 1, [])], CALIBRATION, 10.0, 1.0,
                    1, False, "clutter")
    assert (report.blocks, report.in_their_bins, report.beyond_bins) == (full + 6, full + 3, 2)
    assert report.fitting_sorted_fraction == pytest.approx((full + 3) / (full + 4), abs=1e-4)
    assert report.sorted_fraction == pytest.approx((full + 3) / (full + 6), abs=1e-4)
    assert [f.scene_seed for f in report.failures] == [0, 1]


def test_a_scene_where_a_thing_moved_is_listed_with_how_far() -> None:
    report = _score([_result(0, 2, 0, [0.4, 12.3]), _result(1, 2, 0, [1.0])], CALIBRATION,
                    10.0, 1.0, 1, False, "clutter")
    assert (report.distractors, report.distractors_moved) == (3, 1)
    assert [f.scene_seed for f in report.failures] == [0]
    assert report.failures[0].to_dict()["distractors_moved_mm"] == [0.4, 12.3]
