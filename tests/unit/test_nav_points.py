"""Named points files, frontiers and map cropping: the small pure pieces of the mobile jobs."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.nav.frontiers import find_frontiers
from busarm.nav.grid import GridSpec, OccupancyGrid, cropped
from busarm.nav.points import (
    NamedPoint,
    NamedPoints,
    load_points,
    points_from_toml,
    save_points,
)

GOOD = """
format = "busarm.points"
version = 1
name = "test room"
map = "room.yaml"

[points.shelf]
x_m = 1.2
y_m = -0.4
yaw_deg = 90.0

[points.table-2]
x_m = 0.0
y_m = 1.0
surface_m = 0.22
"""


def test_a_points_file_reads_with_its_map_beside_it(tmp_path: Path) -> None:
    path = tmp_path / "points.toml"
    path.write_text(GOOD)
    points = load_points(path)
    assert points.map_path == tmp_path / "room.yaml"
    shelf = points.get("shelf")
    assert (shelf.pose.x_m, shelf.pose.y_m) == (1.2, -0.4)
    assert math.isclose(shelf.pose.yaw_rad, math.pi / 2)
    assert points.get("table-2").surface_m == 0.22
    with pytest.raises(ConfigError, match="no point 'kitchen'.*shelf, table-2"):
        points.get("kitchen")


@pytest.mark.parametrize(("change", "message"), [
    (("x_m = 1.2", "x_m = 1e9"), r"points.shelf.x_m.*1000"),
    (("yaw_deg = 90.0", "yaw = 90.0"), r"unknown key\(s\) yaw"),
    (("surface_m = 0.22", "surface_m = 2.0"), r"surface_m.*0.5"),
    (("[points.shelf]", "[points.9shelf]"), "a point's name"),
    (('version = 1', 'version = 2'), "version: 2; this busarm reads version 1"),
    (('map = "room.yaml"', 'map = 3'), "map: must be a map file's path"),
    (("x_m = 0.0", "x_m = 'zero'"), r"points.table-2.x_m"),
])
def test_a_bad_points_file_gives_one_error_naming_the_key(change: tuple[str, str],
                                                         message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        points_from_toml(GOOD.replace(*change), "p.toml")


@settings(max_examples=40, deadline=None)
@given(st.dictionaries(
    st.from_regex(r"[a-z][a-z0-9_-]{0,10}", fullmatch=True),
    st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-179, 179), st.floats(0, 0.5)),
    min_size=1, max_size=5))
def test_points_survive_a_round_trip_through_their_file(
        values: dict[str, tuple[float, float, float, float]]) -> None:
    points = NamedPoints("round trip 'quoted' \"name\"", {
        k: NamedPoint(k, Pose2D(x, y, math.radians(yaw)), s)
        for k, (x, y, yaw, s) in values.items()})
    back = points_from_toml(_saved(points))
    assert back.name == points.name and set(back.points) == set(points.points)
    for k, p in points.points.items():
        q = back.points[k]
        assert abs(q.pose.x_m - p.pose.x_m) < 1e-4 and abs(q.pose.y_m - p.pose.y_m) < 1e-4
        assert abs(math.degrees(q.pose.yaw_rad - p.pose.yaw_rad)) < 0.01
        assert abs(q.surface_m - p.surface_m) < 1e-4


def _saved(points: NamedPoints) -> str:
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "p.toml"
        save_points(path, points, "map.yaml")
        return path.read_text()


def _room_seen_from(x_m: float) -> OccupancyGrid:
    """A 4 x 2 m room whose left part (x < ``x_m``) has been seen free, walls around it."""
    grid = OccupancyGrid(GridSpec.covering(-1, 5, -1, 3, 0.05))
    xs, ys = np.meshgrid(np.arange(0.025, x_m, 0.05), np.arange(0.025, 2.0, 0.05))
    rows, cols = grid.spec.cells(np.column_stack([xs.ravel(), ys.ravel()]))
    grid.log_odds[rows, cols] = -2.0
    for wall in ([(x, -0.025) for x in np.arange(0.0, x_m, 0.05)]
                 + [(x, 2.025) for x in np.arange(0.0, x_m, 0.05)]
                 + [(-0.025, y) for y in np.arange(-0.05, 2.1, 0.05)]):
        r, c = grid.spec.cells(np.array([wall]))
        grid.log_odds[r, c] = 3.0
    return grid


def test_the_frontier_is_where_the_seen_floor_meets_the_unseen() -> None:
    frontiers = find_frontiers(_room_seen_from(1.5))
    assert len(frontiers) == 1
    f = frontiers[0]
    assert abs(f.x_m - 1.475) < 0.03 and abs(f.y_m - 1.0) < 0.05
    assert 1.8 <= f.length_m <= 2.1  # the room's width, 2 m
    assert find_frontiers(_room_seen_from(1.5), min_length_m=3.0) == []


def test_a_cropped_map_keeps_every_known_cell_where_it_was() -> None:
    grid = _room_seen_from(1.5)
    small = cropped(grid, margin_m=0.1)
    assert small.spec.width < grid.spec.width and small.spec.height < grid.spec.height
    assert np.count_nonzero(small.log_odds) == np.count_nonzero(grid.log_odds)
    probe = np.array([[0.525, 1.025], [-0.025, 0.525], [1.425, 2.025]])
    r1, c1 = grid.spec.cells(probe)
    r2, c2 = small.spec.cells(probe)
    assert np.array_equal(grid.log_odds[r1, c1], small.log_odds[r2, c2])
    empty = OccupancyGrid(GridSpec.covering(0, 1, 0, 1, 0.1))
    assert cropped(empty) is empty
