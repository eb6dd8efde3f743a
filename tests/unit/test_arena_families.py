"""The rooms of the mobile benchmarks (busarm.twin.arena_families): each family draws what
it says, every room is sound (checked, its points reachable, a way between its things),
and inner walls go through arena files and into the twin's model."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError
from busarm.twin.arena import Room, Solid, arena_from_toml, arena_to_toml
from busarm.twin.arena_families import FAMILIES, INNER_WALL_M, transport_task
from busarm.twin.arena_tasks import map_in_arena, transport_points, true_map_surfaces

SEEDS = st.integers(0, 100_000)
FEW = settings(max_examples=12, deadline=None)


def _points(family: str, seed: int) -> tuple[Room, tuple[float, float], tuple[float, float]]:
    task = transport_task(family, seed)
    _, index, spot = transport_points(task.arena, Pose2D(), seed,
                                      place_within=task.place_within,
                                      min_trip_m=task.min_trip_m)
    block = task.arena.blocks[index]
    return task.arena.room, (block.x_m, block.y_m), spot


@FEW
@given(st.sampled_from(sorted(FAMILIES)), SEEDS)
def test_every_room_is_sound_and_the_same_for_the_same_seed(family: str, seed: int) -> None:
    task = transport_task(family, seed)
    assert task == transport_task(family, seed)
    back = arena_from_toml(arena_to_toml(task.arena))
    assert back == replace(task.arena, seed=None, source=back.source)  # its walls too
    room, block, spot = _points(family, seed)  # a stand in front of each, or ConfigError
    assert math.dist(block, spot) >= task.min_trip_m
    if task.place_within is not None:
        r = task.place_within
        assert r.x_min_m <= spot[0] <= r.x_max_m and r.y_min_m <= spot[1] <= r.y_max_m


def _gaps_y(walls: tuple[Solid, ...], x_m: float, room: Room) -> list[float]:
    """The open lengths along a wall line at ``x_m`` (its door or corridor)."""
    spans = sorted((w.y_m - w.size_y_m / 2, w.y_m + w.size_y_m / 2) for w in walls
                   if abs(w.x_m - x_m) < 1e-6)
    edges = [room.y_min_m, *[v for span in spans for v in span], room.y_max_m]
    return [b - a for a, b in zip(edges[::2], edges[1::2], strict=True) if b - a > 1e-6]


@FEW
@given(SEEDS)
def test_a_doorway_is_0_6_to_0_7_m_and_the_carry_goes_through_it(seed: int) -> None:
    task = transport_task("doorway", seed)
    walls = task.arena.walls
    assert len(walls) == 2 and all(math.isclose(w.size_x_m, INNER_WALL_M) for w in walls)
    x = walls[0].x_m
    gaps = _gaps_y(walls, x, task.arena.room)
    assert len(gaps) == 1 and 0.6 <= gaps[0] <= 0.7 + 1e-9
    _, block, spot = _points("doorway", seed)
    assert (block[0] - x) * (spot[0] - x) < 0  # on either side of the wall


@FEW
@given(SEEDS)
def test_a_corridor_is_0_8_to_1_2_m_wide_and_joins_the_two_rooms(seed: int) -> None:
    task = transport_task("corridor", seed)
    walls = task.arena.walls
    assert len(walls) == 2
    x0, x1 = walls[0].x_m - walls[0].size_x_m / 2, walls[0].x_m + walls[0].size_x_m / 2
    assert 1.5 - 1e-6 <= x1 - x0 <= 3.0 + 1e-6
    gaps = _gaps_y(walls, walls[0].x_m, task.arena.room)
    assert len(gaps) == 1 and 0.8 <= gaps[0] <= 1.2 + 1e-9
    _, block, spot = _points("corridor", seed)
    assert (block[0] < x0 and spot[0] > x1) or (block[0] > x1 and spot[0] < x0)


@FEW
@given(SEEDS)
def test_the_corner_block_stands_0_15_to_0_35_m_from_two_walls(seed: int) -> None:
    room, block, spot = _points("corner", seed)
    off_x = min(block[0] - room.x_min_m, room.x_max_m - block[0])
    off_y = min(block[1] - room.y_min_m, room.y_max_m - block[1])
    assert 0.15 - 1e-4 <= off_x <= 0.35 + 1e-4 and 0.15 - 1e-4 <= off_y <= 0.35 + 1e-4
    assert min(spot[0] - room.x_min_m, room.x_max_m - spot[0]) <= 0.6
    assert min(spot[1] - room.y_min_m, room.y_max_m - spot[1]) <= 0.6


@FEW
@given(SEEDS)
def test_big_rooms_are_big_and_sparse_and_long_carries_are_long(seed: int) -> None:
    big = transport_task("big", seed).arena
    w, h = big.room.size_m
    assert 7.0 <= w <= 10.0 and 5.0 <= h <= 8.0
    assert 1 <= len(big.tables) + len(big.boxes) <= 2 and not big.walls
    room, block, spot = _points("long", seed)
    assert room.size_m[0] >= 11.0 and math.dist(block, spot) >= 8.0


@FEW
@given(SEEDS)
def test_a_symmetric_room_has_one_thing_without_a_twin(seed: int) -> None:
    arena = transport_task("symmetric", seed).arena
    r = arena.room
    cx, cy = (r.x_min_m + r.x_max_m) / 2, (r.y_min_m + r.y_max_m) / 2
    solids = [*arena.tables, *arena.boxes]
    alone = [s for s in solids if not any(
        math.isclose(t.x_m, 2 * cx - s.x_m, abs_tol=1e-3)
        and math.isclose(t.y_m, 2 * cy - s.y_m, abs_tol=1e-3)
        and (t.size_x_m, t.size_y_m, t.height_m) == (s.size_x_m, s.size_y_m, s.height_m)
        for t in solids if t is not s)]
    assert len(alone) == 1  # (a seed whose pairs found no room is a bare room and it)


def test_inner_walls_are_on_the_true_map() -> None:
    arena = transport_task("doorway", 3).arena
    wall = arena.walls[0]
    face = np.array([[wall.x_m + wall.size_x_m / 2 + 0.1, wall.y_m]])
    assert true_map_surfaces(arena, Pose2D(), face)[0] == pytest.approx(0.1, abs=1e-6)


def test_a_map_turned_from_its_room_is_found_turned() -> None:
    from busarm.nav.grid import GridSpec, OccupancyGrid

    arena = transport_task("corner", 1).arena
    origin = Pose2D(0.3, -0.2, 0.4)
    turn = Pose2D(0.02, -0.01, math.radians(1.5))  # the map's own frame, off the origin
    spec = GridSpec.covering(-8, 8, -8, 8, 0.025)
    grid = OccupancyGrid(spec)
    r = arena.room
    xs = np.arange(r.x_min_m, r.x_max_m, 0.02)
    ys = np.arange(r.y_min_m, r.y_max_m, 0.02)
    walls = np.concatenate([np.column_stack([xs, np.full_like(xs, r.y_min_m)]),
                            np.column_stack([xs, np.full_like(xs, r.y_max_m)]),
                            np.column_stack([np.full_like(ys, r.x_min_m), ys]),
                            np.column_stack([np.full_like(ys, r.x_max_m), ys])])
    from busarm.nav.mapping import compose, inverse, transform_points

    in_map = transform_points(inverse(compose(origin, turn)), walls)
    rows, cols = spec.cells(in_map)
    grid.log_odds[rows, cols] = 4.0
    found = map_in_arena(arena, grid, origin)
    truth = compose(origin, turn)
    assert math.dist((found.x_m, found.y_m), (truth.x_m, truth.y_m)) < 0.02
    assert abs(math.degrees(found.yaw_rad - truth.yaw_rad)) < 0.2


@pytest.mark.parametrize(("family", "seed", "words"), [
    ("attic", 0, "room family 'attic': give one of standard, doorway"),
    ("big", -1, "seed -1: give a whole number 0 or more")])
def test_a_bad_family_or_seed_is_one_clear_error(family: str, seed: int, words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        transport_task(family, seed)
