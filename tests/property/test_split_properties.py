"""busarm.perception.split's sums and places: a mask's middle from its sums is numpy's
mean of its pixels, to the last bit (the greedy squares' ties depend on it), and the sums
are OpenCV's moments; the squares placed lie on the mask and explain no more of it than it
holds, and they are those of the greedy search written plainly (pixel lists, a fresh
middle each turn); a search given up early could not have won, and of several masks (the
side shares of a blob) the one chosen is the first the plain search fits best."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.perception.split import (
    FIT_SLACK_MM,
    MAX_BLOCKS,
    MIN_COVER,
    RESOLUTION_MM,
    _best_squares,
    _fit_bound,
    _place_squares,
    _sums,
)


@st.composite
def masks(draw: st.DrawFn) -> npt.NDArray[np.uint8]:
    """A 0/1 mask of a few rectangles (blocks' top faces, about)."""
    h, w = draw(st.integers(8, 160)), draw(st.integers(8, 160))
    mask = np.zeros((h, w), np.uint8)
    for _ in range(draw(st.integers(1, 5))):
        r, c = draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1))
        mask[r:r + draw(st.integers(1, 80)), c:c + draw(st.integers(1, 80))] = 1
    return mask


@settings(max_examples=200, deadline=None)
@given(masks())
def test_the_middle_is_the_mean_of_the_pixels(mask: npt.NDArray[np.uint8]) -> None:
    rows, cols = np.nonzero(mask)
    count, sum_r, sum_c = _sums(mask.astype(np.float32))
    assert (sum_r / count, sum_c / count) == (float(rows.mean()), float(cols.mean()))


@settings(max_examples=100, deadline=None)
@given(masks(), st.sampled_from([10.0, 20.0, 30.0]))
def test_squares_lie_on_the_mask(mask: npt.NDArray[np.uint8], size_mm: float) -> None:
    centres, fit = _place_squares(mask, size_mm)
    side = max(3, round(size_mm / RESOLUTION_MM))
    assert fit <= float(mask.sum()) / side**2 + 1e-9
    for col, row in centres:
        assert 0 <= row < mask.shape[0] and 0 <= col < mask.shape[1]


def _plain_squares(tops: npt.NDArray[np.uint8], size_mm: float
                   ) -> tuple[npt.NDArray[np.float64], float]:
    """The greedy squares as first written: float sums, the best places listed, the
    middle of what is left and of each window taken from its pixels."""
    side = max(3, round(size_mm / RESOLUTION_MM))
    inner = max(1, side - 2 * round(FIT_SLACK_MM / RESOLUTION_MM))
    fits = cv2.erode(tops, np.ones((inner, inner), np.uint8), borderType=cv2.BORDER_CONSTANT,
                     borderValue=0) > 0
    left = tops.astype(np.float32)
    centres, covered, empty = [], 0.0, 0.0

    def window(r: float, c: float) -> tuple[int, int, npt.NDArray[np.float32]]:
        r0, c0 = round(r) - side // 2, round(c) - side // 2
        return (max(r0, 0), max(c0, 0),
                left[max(r0, 0):max(r0 + side, 0), max(c0, 0):max(c0 + side, 0)])

    for _ in range(MAX_BLOCKS):
        cover = cv2.boxFilter(left, -1, (side, side), normalize=False,
                              borderType=cv2.BORDER_CONSTANT)
        cover[~fits] = 0
        best = float(cover.max())
        if best < MIN_COVER * side * side:
            break
        rows, cols = np.nonzero(cover >= best - 0.01 * side * side)
        lr, lc = np.nonzero(left)
        k = int(np.argmax((rows - lr.mean()) ** 2 + (cols - lc.mean()) ** 2))
        centre = np.array([rows[k], cols[k]], dtype=float)
        for _ in range(2):
            r0, c0, w = window(*centre)
            if w.size == 0 or not w.any():
                break
            wr, wc = np.nonzero(w)
            shift = np.array([wr.mean() + r0, wc.mean() + c0]) - centre
            if float(np.abs(shift).max()) < 0.25:
                break
            centre = centre + np.clip(shift, -side / 4, side / 4)
        centres.append(centre)
        _, _, w = window(*centre)
        held = float(w.sum())
        covered += held
        empty += side * side - held
        w[:] = 0.0
    fit = (covered - 2.0 * float(left.sum()) - 2.0 * empty) / (side * side)
    return np.array(centres).reshape(-1, 2)[:, ::-1], fit


@settings(max_examples=150, deadline=None)
@given(masks(), st.sampled_from([10.0, 20.0, 30.0]))
def test_squares_are_the_plain_greedy_searchs(mask: npt.NDArray[np.uint8], size_mm: float
                                              ) -> None:
    centres, fit = _place_squares(mask, size_mm)
    want, want_fit = _plain_squares(mask, size_mm)
    np.testing.assert_array_equal(centres, want)
    assert fit == want_fit


@settings(max_examples=200, deadline=None)
@given(masks())
def test_a_masks_sums_are_opencvs_moments(mask: npt.NDArray[np.uint8]) -> None:
    m = cv2.moments(mask, binaryImage=True)
    assert _sums(mask) == (m["m00"], m["m01"], m["m10"])


@settings(max_examples=150, deadline=None)
@given(masks(), st.sampled_from([10.0, 20.0, 30.0]),
       st.one_of(st.just(0.0), st.floats(-5.0, 5.0)), st.booleans())
def test_squares_given_up_could_not_have_beaten_the_fit_they_were_to_beat(
        mask: npt.NDArray[np.uint8], size_mm: float, off: float, ties: bool) -> None:
    full = _place_squares(mask, size_mm)
    assert full is not None
    fit_to_beat = full[1] + off  # the same fit (a tie), or a better or worse one
    side = max(3, round(size_mm / RESOLUTION_MM))
    assert full[1] <= _fit_bound(0.0, float(mask.sum()), 0.0, side * side)
    got = _place_squares(mask, size_mm, (fit_to_beat, ties))
    if got is None:  # given up only if it could not beat it
        assert not (full[1] > fit_to_beat or (full[1] == fit_to_beat and ties))
    else:  # else the same squares
        np.testing.assert_array_equal(got[0], full[0])
        assert got[1] == full[1]


@settings(max_examples=100, deadline=None)
@given(st.lists(masks(), min_size=1, max_size=4), st.sampled_from([10.0, 20.0, 30.0]))
def test_the_best_squares_are_those_of_the_first_mask_they_fit_best(
        tops: list[npt.NDArray[np.uint8]], size_mm: float) -> None:
    shape = tops[0].shape  # the side shares of one blob: one plane
    tops = [t if t.shape == shape else cv2.resize(t, shape[::-1],
                                                  interpolation=cv2.INTER_NEAREST)
            for t in tops]
    plain = [_plain_squares(t, size_mm) for t in tops]
    first_best = max(range(len(tops)), key=lambda i: (plain[i][1], -i))
    np.testing.assert_array_equal(_best_squares(tops, size_mm), plain[first_best][0])
