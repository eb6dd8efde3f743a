"""Where a pick cycle's time goes (``busarm.bench.pick_timeline``)."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from busarm.bench.pick_timeline import draw_timeline, median_phases, phases

CYCLE = [("closer", 0.4), ("confirmed", 0.4), ("above", 0.7), ("grip", 1.4), ("lift", 1.7),
         ("carry", 2.1), ("release", 2.5), ("done", 2.7)]


def test_a_cycle_is_cut_into_phases_by_the_steps_that_end_them() -> None:
    got = phases(CYCLE)
    assert [name for name, _, _ in got] == [
        "look closer", "judge its shape", "approach", "descend, grip", "lift", "carry",
        "lower, release", "rise"]
    assert got[2] == ("approach", 0.4, pytest.approx(0.3))
    assert sum(seconds for _, _, seconds in got) == pytest.approx(2.7)
    # A step of its own (a block set down to be taken again) is "other".
    assert phases([("set down", 1.0), ("done", 1.5)])[0] == ("other", 0.0, 1.0)


def test_each_phase_median_counts_a_skipped_phase_as_nothing() -> None:
    faster = [(name, t - 0.4 if t > 0.4 else 0.0) for name, t in CYCLE if name != "closer"]
    medians = dict(median_phases([CYCLE, CYCLE, faster]))
    assert medians["look closer"] == pytest.approx(0.4)  # 2 of 3 cycles looked closer
    assert medians["approach"] == pytest.approx(0.3)
    assert "other" not in medians
    assert median_phases([]) == []


def test_the_timeline_is_a_picture_with_a_bar_per_cycle(tmp_path: Path) -> None:
    path = tmp_path / "timeline.png"
    draw_timeline([CYCLE, CYCLE[2:]], path, "two cycles")
    image = cv2.imread(str(path))
    assert image is not None and image.shape[1] == 800
    # The approach's orange is drawn (the legend and the bars).
    orange = (image[:, :, 2] > 200) & (image[:, :, 1] > 140) & (image[:, :, 1] < 200) \
        & (image[:, :, 0] < 140)
    assert orange.sum() > 200
    assert [p.name for p in tmp_path.iterdir()] == ["timeline.png"]  # no temporary left
