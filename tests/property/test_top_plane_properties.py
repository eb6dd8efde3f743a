"""busarm.perception.top_plane reads all of a picture's outlines as grids of blocks at
once: the same grids as one outline at a time (``split.edge_yaw_deg`` and
``split.cast_cube_extent``, as the locator read them blob by blob), whatever the outlines."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.perception.split import cast_cube_extent, edge_yaw_deg
from busarm.perception.top_plane import outline_grids

SIZE = 30.0
TABLE_Z = 0.0


@st.composite
def outlines(draw: st.DrawFn) -> npt.NDArray[np.float64]:
    """A blob's straight outline on the top plane: a turned rectangle's corners, a
    little bent (mm)."""
    cx, cy = draw(st.floats(50.0, 300.0)), draw(st.floats(-200.0, 200.0))
    w, h = draw(st.floats(5.0, 130.0)), draw(st.floats(5.0, 130.0))
    a = math.radians(draw(st.floats(-90.0, 90.0)))
    corners = np.array([[-w, -h], [w, -h], [w, h], [-w, h]]) / 2
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    pts = corners @ rot.T + (cx, cy)
    bend = draw(st.lists(st.floats(-2.0, 2.0), min_size=8, max_size=8))
    pts = np.vstack([pts, (pts + np.roll(pts, -1, axis=0)) / 2 + np.reshape(bend, (4, 2))])
    return np.asarray(pts[[0, 4, 1, 5, 2, 6, 3, 7]], np.float64)


def _one(pts: npt.NDArray[np.float64], camera: npt.NDArray[np.float64]
         ) -> tuple[float, tuple[int, int], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """One outline read on its own (the locator's former per-blob reading)."""
    yaw = edge_yaw_deg(pts)
    a = math.radians(yaw)
    axes = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])
    rel = pts @ axes.T
    lo_blob, hi_blob = rel.min(axis=0), rel.max(axis=0)
    centre = ((lo_blob + hi_blob) / 2) @ axes
    lo, hi = cast_cube_extent(centre, axes, yaw, SIZE, TABLE_Z, camera)
    sides = (hi - lo) - SIZE
    counts = tuple(max(1, round((ext - side / 2) / SIZE))
                   for ext, side in zip(hi_blob - lo_blob, sides, strict=True))
    shown = np.clip((hi_blob - lo_blob - np.array(counts) * SIZE) / np.maximum(sides, 1e-6),
                    0.0, 1.0)
    first = lo_blob + SIZE / 2 + shown * (-lo - SIZE / 2)
    return yaw, (counts[0], counts[1]), first, lo + hi


@settings(max_examples=150, deadline=None)
@given(st.lists(outlines(), min_size=1, max_size=6),
       st.tuples(st.floats(-100.0, 100.0), st.floats(-100.0, 100.0), st.floats(200.0, 450.0)))
def test_all_outlines_at_once_read_as_each_alone(
        many: list[npt.NDArray[np.float64]], camera: tuple[float, float, float]) -> None:
    cam = np.array(camera)
    grids = outline_grids(many, SIZE, TABLE_Z, cam)
    assert len(grids) == len(many)
    for pts, grid in zip(many, grids, strict=True):
        yaw, counts, first, cast = _one(pts, cam)
        assert math.isclose(grid.yaw_deg, yaw, abs_tol=1e-9)
        assert grid.counts == counts
        np.testing.assert_allclose(grid.first, first, atol=1e-6)
        np.testing.assert_allclose(grid.cast_uv_mm, cast, atol=1e-6)


def test_no_outlines_no_grids() -> None:
    assert outline_grids([], SIZE, TABLE_Z, np.array([0.0, 0.0, 300.0])) == []
