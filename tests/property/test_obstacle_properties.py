"""Properties of where a thing that is not a block may be (busarm.perception.obstacles): seen
whole from cameras anywhere above the table, an upright box is always inside what is kept
off (the cones through its casts never clear a point of it), and what one camera sees of
a low thing (a pen) leaves the space above it clear, where a column of unknown height on
its cast would not."""

from __future__ import annotations

import math

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.perception.obstacles import Obstacle, View, near_convex, refine

PROPS = settings(max_examples=150, deadline=None, derandomize=True)
TABLE_Z_MM = -20.0


def _box(x: float, y: float, length: float, width: float, yaw_deg: float,
         height: float) -> np.ndarray:
    """The eight corners (mm) of an upright box standing on the table."""
    a = math.radians(yaw_deg)
    u = np.array([math.cos(a), math.sin(a)]) * length / 2
    v = np.array([-math.sin(a), math.cos(a)]) * width / 2
    foot = [np.array([x, y]) + su * u + sv * v for su in (-1, 1) for sv in (-1, 1)]
    return np.array([[*p, TABLE_Z_MM + h] for p in foot for h in (0.0, height)])


def _seen(box: np.ndarray, camera: np.ndarray) -> Obstacle:
    """What one camera sees of the box: its corners cast onto the table, their hull."""
    t = (camera[2] - TABLE_Z_MM) / (camera[2] - box[:, 2])
    cast = camera[:2] + (box[:, :2] - camera[:2]) * t[:, None]
    hull = cv2.convexHull(cast.astype(np.float32)).reshape(-1, 2).astype(np.float64)
    return Obstacle(hull, views=(View(hull, camera, TABLE_Z_MM),))


def _inside(box: np.ndarray, rng: np.random.Generator, n: int) -> np.ndarray:
    """Points spread through the box (its corners are trilinear weights' extremes)."""
    base = box[::2]
    weights = rng.dirichlet(np.ones(4), n)
    xy = weights @ base[:, :2]
    z = TABLE_Z_MM + rng.uniform(0.0, 1.0, n) * (box[1, 2] - TABLE_Z_MM)
    return np.column_stack([xy, z])


cameras = st.tuples(st.floats(-150.0, 300.0), st.floats(-250.0, 250.0), st.floats(150.0, 400.0))


@PROPS
@given(x=st.floats(100.0, 280.0), y=st.floats(-200.0, 200.0), length=st.floats(8.0, 150.0),
       width=st.floats(8.0, 70.0), yaw=st.floats(-90.0, 90.0), height=st.floats(2.0, 90.0),
       views=st.lists(cameras, min_size=1, max_size=3), seed=st.integers(0, 2**16))
def test_a_thing_seen_whole_is_never_cleared(x: float, y: float, length: float, width: float,
                                            yaw: float, height: float,
                                            views: list[tuple[float, float, float]],
                                            seed: int) -> None:
    box = _box(x, y, length, width, yaw, height)
    thing: list[Obstacle] = []
    for cam in views:
        thing = refine(thing, [_seen(box, np.array(cam))])
    assert len(thing) == 1
    points = np.vstack([box, _inside(box, np.random.default_rng(seed), 200)])
    held = thing[0].holds(points, 0.01)  # each point's answer, in one call
    assert held.all(), points[~held][:3]
    assert all(thing[0].reaches(corner[None, :], 0.01) for corner in box)


def test_the_space_above_a_pen_is_cleared_that_a_column_keeps() -> None:
    # A pen lying across the camera's line of sight: a point well above it (by more than
    # the cast is wide, scaled) is cast beyond the pen's cast, so it is not in the pen.
    pen = _box(200.0, 0.0, 140.0, 10.0, 90.0, 9.0)
    seen = refine([], [_seen(pen, np.array([60.0, 0.0, 330.0]))])[0]
    above = np.array([[x, y, TABLE_Z_MM + 40.0] for x in (198.0, 200.0, 202.0)
                      for y in np.linspace(-60.0, 60.0, 13)])
    assert not seen.reaches(above, 2.5)
    assert Obstacle(seen.corners).reaches(above, 2.5)  # of unknown height: it may be tall
    assert seen.reaches(np.array([[200.0, 0.0, TABLE_Z_MM + 10.0]]), 2.5)  # its own top
    tall = refine([], [_seen(_box(200.0, 0.0, 140.0, 10.0, 90.0, 60.0),
                             np.array([60.0, 0.0, 330.0]))])[0]
    assert tall.reaches(above, 2.5)  # a wall as tall is not cleared


def test_near_convex_keeps_a_margin_round_a_square() -> None:
    square = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    pts = np.array([[5.0, 5.0], [11.9, 5.0], [12.1, 5.0], [5.0, -1.0]])
    assert near_convex(square, pts, 2.0).tolist() == [True, True, False, True]
    assert near_convex(square[::-1], pts, 2.0).tolist() == [True, True, False, True]
