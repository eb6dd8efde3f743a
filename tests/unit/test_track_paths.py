"""The twin's hand's paths (busarm.twin.mover): steady speed along them, loops that close,
seeded walks that repeat, bad paths refused. Pure geometry (no twin)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from busarm.errors import ConfigError
from busarm.twin.mover import (
    DEFAULT_CENTRE_MM,
    PATH_KINDS,
    MoverPath,
    circle_path,
    named_path,
    track_scene,
    walk_path,
    waypoints_path,
)


@pytest.mark.parametrize("kind", PATH_KINDS)
def test_a_named_path_is_a_closed_loop_walked_at_a_steady_speed(kind: str) -> None:
    path = named_path(kind, seed=4)
    assert path.closed and 200.0 < path.length_mm < 800.0
    # Equal lengths along it are equal distances on the table (chords of a fine polyline).
    points = [path.at(s)[:2] for s in np.arange(0.0, path.length_mm, 1.0)]
    gaps = [math.dist(a, b) for a, b in itertools.pairwise(points)]
    assert min(gaps) > 0.99 and max(gaps) <= 1.0 + 1e-9
    assert math.dist(path.at(0.0)[:2], path.at(path.length_mm)[:2]) < 1e-9  # round again
    dx, dy = path.at(10.0)[2:]
    assert math.hypot(dx, dy) == pytest.approx(1.0)
    # Every point within the arm's look-down reach of the default centre.
    r = np.hypot(*path.points_mm.T)
    assert r.min() > 180.0 and r.max() < 300.0


def test_a_circle_is_round_and_walks_are_seeded() -> None:
    circle = circle_path((240.0, 0.0), 50.0)
    assert circle.length_mm == pytest.approx(2 * math.pi * 50.0, rel=1e-4)
    assert math.dist(circle.at(circle.length_mm / 4)[:2], (240.0, 50.0)) < 0.1
    a, b, c = walk_path(3), walk_path(3), walk_path(4)
    assert np.array_equal(a.points_mm, b.points_mm)
    assert not np.array_equal(a.points_mm, c.points_mm)
    # Within its half extents (45, 80) of the centre, the spline's overshoot aside.
    off = np.abs(a.points_mm - np.asarray(DEFAULT_CENTRE_MM))
    assert off[:, 0].max() < 55.0 and off[:, 1].max() < 95.0


def test_waypoints_end_where_they_end() -> None:
    path = waypoints_path([(240.0, 0.0), (300.0, 0.0), (300.0, 40.0)])
    assert not path.closed and path.length_mm == pytest.approx(100.0)
    assert path.at(80.0)[:2] == pytest.approx((300.0, 20.0))
    assert path.at(500.0)[:2] == pytest.approx((300.0, 40.0))  # stays at the end


def test_bad_paths_are_refused() -> None:
    with pytest.raises(ConfigError, match="mover path 'spiral'; allowed: circle, eight, walk"):
        named_path("spiral")
    with pytest.raises(ConfigError, match="radius_mm"):
        circle_path(radius_mm=0.0)
    with pytest.raises(ConfigError, match="two or more"):
        waypoints_path([(0.0, 0.0)])
    with pytest.raises(ConfigError, match="shorter than 1 mm"):
        MoverPath([(0.0, 0.0), (0.1, 0.0)], closed=False)
    with pytest.raises(ConfigError, match=r"leaves the table at \(400, 0\) mm"):
        waypoints_path([(240.0, 0.0), (450.0, 0.0)]).check_on(track_scene("red"), 21.0)
