"""Occupancy grids from scans, and the ROS map_server files they are kept in."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.map_files import (
    PIXEL_FREE,
    PIXEL_OCCUPIED,
    PIXEL_UNKNOWN,
    grid_pixels,
    load_map,
    read_pgm,
    save_map,
)


def room_scan(sensor: Pose2D, half_m: float = 1.0, beams: int = 360
              ) -> tuple[np.ndarray, np.ndarray]:
    """Bearings and ranges of a square room (-half..half) seen from ``sensor``."""
    bearings = np.linspace(0, 2 * math.pi, beams, endpoint=False)
    world = bearings + sensor.yaw_rad
    c, s = np.cos(world), np.sin(world)
    with np.errstate(divide="ignore", over="ignore"):
        tx = np.where(c > 0, (half_m - sensor.x_m) / c, (-half_m - sensor.x_m) / c)
        ty = np.where(s > 0, (half_m - sensor.y_m) / s, (-half_m - sensor.y_m) / s)
    return bearings, np.minimum(np.abs(tx), np.abs(ty))


def test_a_room_scan_marks_its_walls_occupied_and_the_inside_free() -> None:
    grid = OccupancyGrid(GridSpec.covering(-1.5, 1.5, -1.5, 1.5, 0.05))
    for _ in range(5):
        grid.insert(Pose2D(0.2, -0.1, 0.3), *room_scan(Pose2D(0.2, -0.1, 0.3)))
    p = grid.probability
    spec = grid.spec
    rows, cols = spec.cells([(0.0, 0.0), (0.5, 0.5), (-0.7, 0.3)])
    assert (p[rows, cols] < 0.2).all()  # inside: free
    rows, cols = spec.cells([(1.0 + 0.01, 0.0), (-1.0 + 0.01, 0.3), (0.4, 1.0 + 0.01)])
    assert (p[rows, cols] > 0.8).all()  # on the walls: occupied
    rows, cols = spec.cells([(1.4, 1.4), (-1.4, 0.0)])
    assert np.allclose(p[rows, cols], 0.5)  # behind the walls: unknown


def test_a_beam_with_no_return_clears_nothing_unless_asked_to() -> None:
    grid = OccupancyGrid(GridSpec.covering(-4, 4, -4, 4, 0.1))
    grid.insert(Pose2D(), [0.0], [math.nan])  # a dropout at a wall must not open it
    assert not grid.log_odds.any()
    grid.insert(Pose2D(), [0.0], [math.nan], no_return_clears_m=3.0)
    assert grid.log_odds.max() == 0.0 and grid.log_odds.min() < 0.0
    rows, cols = grid.spec.cells([(2.5, 0.0), (3.5, 0.0)])
    assert grid.log_odds[rows[0], cols[0]] < 0 and grid.log_odds[rows[1], cols[1]] == 0


def test_a_moved_obstacle_is_unlearnt() -> None:
    grid = OccupancyGrid(GridSpec.covering(-2, 2, -2, 2, 0.05))
    for _ in range(20):  # a box 0.5 m ahead, seen often
        grid.insert(Pose2D(), [0.0], [0.5])
    rows, cols = grid.spec.cells([(0.51, 0.0)])
    assert grid.probability[rows[0], cols[0]] > 0.95
    for _ in range(30):  # gone: the beam now reaches 1.5 m
        grid.insert(Pose2D(), [0.0], [1.5])
    assert grid.probability[rows[0], cols[0]] < 0.1


@settings(max_examples=40, deadline=None)
@given(st.floats(-0.8, 0.8), st.floats(-0.8, 0.8), st.floats(-math.pi, math.pi))
def test_every_hit_lands_in_an_occupied_cell_and_never_frees_a_hit(
        x: float, y: float, yaw: float) -> None:
    sensor = Pose2D(x, y, yaw)
    bearings, ranges = room_scan(sensor, beams=90)
    grid = OccupancyGrid(GridSpec.covering(-1.2, 1.2, -1.2, 1.2, 0.05))
    grid.insert(sensor, bearings, ranges)
    ends = np.stack([x + ranges * np.cos(bearings + yaw), y + ranges * np.sin(bearings + yaw)],
                    axis=1)
    rows, cols = grid.spec.cells(ends)
    assert (grid.log_odds[rows, cols] > 0).all()


def test_the_map_files_round_trip_as_map_server_writes_them(tmp_path: Path) -> None:
    grid = OccupancyGrid(GridSpec.covering(-1.5, 1.5, -1.2, 1.2, 0.05))
    grid.insert(Pose2D(0.1, 0.0, 0.0), *room_scan(Pose2D(0.1, 0.0, 0.0)))
    pgm = save_map(tmp_path / "room.yaml", grid)
    assert pgm == tmp_path / "room.pgm"
    text = (tmp_path / "room.yaml").read_text()
    assert "image: room.pgm" in text and "mode: trinary" in text and "resolution: 0.05" in text
    pixels = read_pgm(pgm)
    assert pixels.shape == (grid.spec.height, grid.spec.width)
    assert set(np.unique(pixels)) <= {PIXEL_OCCUPIED, PIXEL_FREE, PIXEL_UNKNOWN}
    # The picture's first row is the highest y.
    assert np.array_equal(pixels, grid_pixels(grid)) and np.array_equal(
        pixels[::-1], grid_pixels(grid)[::-1])
    back = load_map(tmp_path / "room.yaml")
    assert back.spec == grid.spec
    assert np.array_equal(grid_pixels(back), pixels)
    p = grid.probability
    assert (back.log_odds[p >= 0.65] > 0).all() and (back.log_odds[p <= 0.196] < 0).all()
    assert (back.log_odds[(p > 0.196) & (p < 0.65)] == 0).all()


@pytest.mark.parametrize(("yaml_text", "said"), [
    ("image: m.pgm\nresolution: 0\norigin: [0, 0, 0]\noccupied_thresh: 0.65\n"
     "free_thresh: 0.2\n", "resolution = 0; allowed: a number 0.005..1"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\noccupied_thresh: 0.65\n"
     "free_thresh: 0.2\n", "origin = [0, 0]; allowed: [x, y, yaw]"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\noccupied_thresh: 0.65\n"
     "free_thresh: 0.2\n", "only maps with yaw 0"),
    ("[1, 2", "not valid YAML"),
    ("image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 0.65\n"
     "free_thresh: 0.2\n", "cannot read it"),
])
def test_a_bad_map_file_is_one_error(tmp_path: Path, yaml_text: str, said: str) -> None:
    (tmp_path / "m.pgm").write_bytes(b"P5\n2 2\n255\n" + bytes([0, 254, 205, 254]))
    (tmp_path / "m.yaml").write_text(yaml_text)
    with pytest.raises(ConfigError, match=f"map file .*{re.escape(said)}"):
        load_map(tmp_path / "m.yaml")


def test_a_picture_that_is_not_a_pgm_is_refused(tmp_path: Path) -> None:
    (tmp_path / "m.pgm").write_bytes(b"P6\n2 2\n255\n" + bytes(12))
    with pytest.raises(ConfigError, match="not an 8-bit binary PGM"):
        read_pgm(tmp_path / "m.pgm")
    (tmp_path / "m.pgm").write_bytes(b"P5\n4 4\n255\n" + bytes(3))
    with pytest.raises(ConfigError, match="4 x 4 pixels, but 3 bytes"):
        read_pgm(tmp_path / "m.pgm")
