"""The batched outline misfit (busarm.perception.outline_fit) gives, for each shape of a
batch, what the one-shape-at-a-time misfit it replaced gives, to the bit: the same hull,
the same resampling (np.interp's), the same distances; and its finite-difference
Jacobian is scipy's '2-point' one, to the bit, bounds included."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize._numdiff import approx_derivative

from busarm.perception.outline_fit import (
    HULL_POINTS,
    FiniteDifferences,
    PreparedView,
    box_corners,
    cylinder_points,
    misfit,
    prepared_view,
    residuals,
)

FloatArray = npt.NDArray[np.float64]

CAM2BASE = np.array([[0.0, -1.0, 0.0, 180.0], [-1.0, 0.0, 0.0, 10.0],
                     [0.0, 0.0, -1.0, 260.0], [0.0, 0.0, 0.0, 1.0]])
"""A camera 260 mm above the table, looking straight down."""


def _reference_resample(contour: FloatArray, count: int) -> FloatArray:
    closed = np.vstack([contour, contour[:1]])
    step = np.hypot(*np.diff(closed, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(step)])
    at = np.linspace(0.0, arc[-1], count, endpoint=False)
    return np.column_stack([np.interp(at, arc, closed[:, 0]), np.interp(at, arc, closed[:, 1])])


def _reference_segments(points: FloatArray, starts: FloatArray, ends: FloatArray
                        ) -> tuple[FloatArray, npt.NDArray[np.intp]]:
    d = ends - starts
    rel = points[:, None, :] - starts[None]
    t = np.clip((rel * d).sum(axis=2) / np.maximum((d * d).sum(axis=1), 1e-18), 0.0, 1.0)
    gap = rel - t[..., None] * d
    squared = (gap * gap).sum(axis=2)
    nearest = squared.argmin(axis=1)
    return np.sqrt(squared[np.arange(len(points)), nearest]), nearest


def _reference_misfit(corners: FloatArray, v: PreparedView) -> tuple[FloatArray, FloatArray]:
    """The misfit of one shape in one view as busarm computed it before batching."""
    cam = corners @ v.base2cam[:3, :3].T + v.base2cam[:3, 3]
    z = np.maximum(cam[:, 2], 1.0)
    img = cam[:, :2] / z[:, None]
    index = cv2.convexHull(img.astype(np.float32), returnPoints=False).ravel()
    hull = img[index]
    ends = np.roll(hull, -1, axis=0)
    to_hull, _ = _reference_segments(v.outline, hull, ends)
    edge = ends - hull
    rel = v.outline[:, None, :] - hull[None]
    cross = edge[None, :, 0] * rel[..., 1] - edge[None, :, 1] * rel[..., 0]
    turn = float(np.sum(hull[:, 0] * ends[:, 1] - ends[:, 0] * hull[:, 1]))
    outside = (cross * turn < 0).any(axis=1)
    first = to_hull * np.where(v.weight > 0, 1.0, outside) * v.scale_px
    to_outline, nearest = _reference_segments(_reference_resample(hull, HULL_POINTS), v.outline,
                                              np.roll(v.outline, -1, axis=0))
    second = to_outline * v.weight[nearest] * v.scale_px
    return np.concatenate([first, second]), np.concatenate([v.weight, v.weight[nearest]])


def _view(seed: int, trusted_share: float) -> PreparedView:
    """An outline (normalised coordinates) round a thing near the table point the camera
    looks at: a wobbly closed curve of 64 points; some of it untrusted."""
    rng = np.random.default_rng(seed)
    a = np.linspace(0.0, 2 * np.pi, 64, endpoint=False)
    r = 0.12 * (1 + 0.15 * np.cos(4 * a + rng.uniform(0, 6))) * rng.uniform(0.6, 1.4)
    outline = np.column_stack([0.02 + r * np.cos(a), -0.03 + r * np.sin(a)])
    own = (rng.uniform(size=64) < trusted_share).astype(np.float64)
    weight = np.minimum(own, np.roll(own, -1))
    return prepared_view(outline, weight, np.linalg.inv(CAM2BASE), 474.0)


boxes = st.tuples(st.floats(-40.0, 40.0), st.floats(-40.0, 40.0), st.floats(-3.2, 3.2),
                  st.floats(5.0, 60.0), st.floats(5.0, 60.0), st.floats(1.0, 80.0))


@settings(max_examples=150, deadline=None)
@given(st.lists(boxes, min_size=1, max_size=7), st.integers(0, 10_000),
       st.sampled_from([1.0, 0.8, 0.4]))
def test_each_box_of_a_batch_has_the_misfit_it_has_alone(
        shapes: list[tuple[float, ...]], seed: int, trusted: float) -> None:
    p = np.array(shapes) + np.array([180.0, 10.0, 0.0, 0.0, 0.0, 0.0])
    views = [_view(seed, trusted), _view(seed + 1, 1.0)]
    res, weight = misfit(box_corners(p, 0.0), views)
    assert np.array_equal(residuals(box_corners(p, 0.0), views), res)
    for i in range(len(p)):
        corners = box_corners(p[i:i + 1], 0.0)
        alone = misfit(corners, views)
        assert np.array_equal(alone[0][0], res[i]) and np.array_equal(alone[1][0], weight[i])
        expected = [_reference_misfit(corners[0], v) for v in views]
        # The corners' projections may differ from the old code's in the last bit (a
        # batched matrix product): the same up to that.
        np.testing.assert_allclose(res[i], np.concatenate([e[0] for e in expected]),
                                   rtol=1e-9, atol=1e-9)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.floats(-30.0, 30.0), st.floats(-30.0, 30.0),
                          st.floats(1.0, 60.0), st.floats(0.5, 90.0)), min_size=1, max_size=5),
       st.integers(0, 10_000))
def test_a_cylinder_batch_matches_the_one_at_a_time_misfit(
        shapes: list[tuple[float, ...]], seed: int) -> None:
    q = np.array(shapes) + np.array([180.0, 10.0, 0.0, 0.0])
    view = _view(seed, 0.8)
    res, _ = misfit(cylinder_points(q, 0.0), [view])
    points = cylinder_points(q, 0.0)
    for i in range(len(q)):
        np.testing.assert_allclose(res[i], _reference_misfit(points[i], view)[0], rtol=1e-9,
                                   atol=1e-9)


def test_the_misfit_of_one_shape_is_the_old_one_to_the_bit() -> None:
    """One shape (a fit's own step) in float64: no batched product, the same bits."""
    view = _view(7, 0.7)
    for box in ([180.0, 10.0, 0.3, 30.0, 25.0, 28.0], [175.0, 0.0, 1.2, 44.0, 20.0, 5.0]):
        corners = box_corners(np.array([box]), 0.0)
        expected = _reference_misfit(corners[0], view)
        got = misfit(corners, [view])
        assert np.array_equal(got[0][0], expected[0])
        assert np.array_equal(got[1][0], expected[1])


@settings(max_examples=100, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=4, max_size=4),
       st.lists(st.floats(0.1, 60.0), min_size=2, max_size=2), st.booleans())
def test_the_jacobian_is_scipys_forward_differences(
        xy: list[float], sides: list[float], at_bound: bool) -> None:
    lower = [-np.inf, -np.inf, -np.inf, -np.inf, 1.0, 0.5]
    upper = [np.inf, np.inf, np.inf, np.inf, 400.0, 400.0]
    x = np.array([*xy, *sides])
    x[4] = max(x[4], 1.0)
    if at_bound:
        x[5] = 400.0  # a forward step would leave the bounds: scipy turns it back
    x[5] = min(max(x[5], 0.5), 400.0)
    a = np.random.default_rng(0).normal(size=(20, 6))

    def batch(q: FloatArray) -> FloatArray:
        # Row by row the same arithmetic (no matrix product, whose rounding may depend
        # on the batch).
        out: FloatArray = np.sin(q[:, None, :] * a[None] * 1e-2).sum(axis=2)
        return out

    steps = FiniteDifferences(batch, lower, upper)
    f0 = steps.residuals(x)
    expected = approx_derivative(lambda q: batch(q[None])[0], x, method="2-point", f0=f0,
                                 bounds=(lower, upper))
    assert np.array_equal(steps.jacobian(x), expected)
    fresh = FiniteDifferences(batch, lower, upper)  # no residuals at x kept
    assert np.array_equal(fresh.jacobian(x), expected)
