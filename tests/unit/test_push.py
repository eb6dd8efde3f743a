"""Pushes that free a boxed-in block (busarm.apps.pick_sort.push): the pushed block's path stays off
the other blocks, the bins and the obstacles, its end is a block side (or one and a half)
away, and a push that says it frees the block leaves it graspable."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlanner
from busarm.apps.pick_sort.push import BIN_KEEP_OFF_MM, SLIDE_MM, Push, PushPlanner
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics

CONFIG = load_arm_config()
BLOCK_MM = 30.0
GRASPS = GraspPlanner(ArmKinematics.from_config(CONFIG), 0.0, BLOCK_MM, 60.0, 75.0,
                      pad_mm=CONFIG.gripper.pad_mm)
BIN = Footprint.square(60.0, 180.0, 90.0, 0.0)
PLANNER = PushPlanner(GRASPS, bins=(BIN,))
SHRUNK_MM = BLOCK_MM - 2 * SLIDE_MM
"""The pushed block's footprint as the planner checks it (it may slide along a neighbour)."""
CHECK_STEP_MM = 0.5
"""The pushed block is checked at points this far apart along its path."""

Pose = tuple[float, float, float]

# A touching 2 x 2 group of cubes centred at (190, -20) mm.
GROUP: tuple[Pose, ...] = (
    (175.0, -35.0, 0.0), (205.0, -35.0, 0.0), (175.0, -5.0, 0.0), (205.0, -5.0, 0.0))


def _square(pose: Pose, side_mm: float = BLOCK_MM) -> Footprint:
    return Footprint.square(pose[0], pose[1], side_mm, pose[2])


def _along(push: Push, yaw_deg: float) -> list[Footprint]:
    """The pushed block's shrunk footprint at points every ``CHECK_STEP_MM`` along the push
    (its start excluded: it is where it was, touching its neighbours)."""
    (x0, y0), (x1, y1) = push.start, push.end
    steps = max(1, math.ceil(math.dist(push.start, push.end) / CHECK_STEP_MM))
    return [Footprint.square(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t, SHRUNK_MM, yaw_deg)
            for t in np.linspace(1.0 / steps, 1.0, steps).tolist()]


def _first_hit(push: Push, yaw_deg: float, things: Sequence[Footprint],
               margin_mm: float = 0.0) -> tuple[float, float] | None:
    """Where along the push (block centre, mm) the shrunk block first comes closer than
    ``margin_mm`` to one of ``things``."""
    for here in _along(push, yaw_deg):
        if any(here.overlaps(t, margin_mm) for t in things):
            centre = here.corners.mean(axis=0)
            return float(centre[0]), float(centre[1])
    return None


def _others(poses: Sequence[Pose], i: int) -> list[Footprint]:
    return [_square(p) for j, p in enumerate(poses) if j != i]


@pytest.mark.parametrize("corner", range(len(GROUP)))
def test_a_corner_of_a_touching_group_is_pushed_free_clear_of_the_others(corner: int) -> None:
    x, y, yaw = GROUP[corner]
    others = _others(GROUP, corner)
    push = PLANNER.plan(x, y, yaw, others)
    assert push is not None
    assert push.frees
    assert push.start == pytest.approx((x, y))
    assert math.dist(push.start, push.end) == pytest.approx(BLOCK_MM, abs=1e-6)
    assert _first_hit(push, yaw, others) is None, push
    # The tool presses on the block's start, drags it to its end (at the block's top).
    assert push.path[1][:2] == pytest.approx(push.start)
    assert push.path[2][:2] == pytest.approx(push.end)
    # Afterwards a grasp clears the neighbours (it did not before).
    GRASPS.plan(push.end[0], push.end[1], yaw, neighbours=others)


@pytest.mark.parametrize("corner", range(len(GROUP)))
def test_a_corner_seen_a_little_into_its_neighbours_is_still_pushed_away_from_them(
        corner: int) -> None:
    """Sightings are off by a millimetre or so: a corner block seen 1.5 mm into the group
    (its footprint overlapping its neighbours' even shrunk by SLIDE_MM) once had no push
    at all. It is pushed, away from every neighbour it overlaps, and ends clear of all."""
    x0, y0, yaw = GROUP[corner]
    cx, cy = 190.0, -20.0  # the group's middle
    x, y = x0 + math.copysign(1.5, cx - x0), y0 + math.copysign(1.5, cy - y0)
    others = _others(GROUP, corner)
    shrunk = Footprint.square(x, y, SHRUNK_MM, yaw)
    touching = [o for o in others if o.overlaps(shrunk)]
    assert touching  # the case in question
    push = PLANNER.plan(x, y, yaw, others)
    assert push is not None and push.frees
    (sx, sy), (ex, ey) = push.start, push.end
    for o in touching:
        ox, oy = o.centre_mm
        assert (ex - sx) * (sx - ox) + (ey - sy) * (sy - oy) > 0.0, push  # away from it
    end = Footprint.square(ex, ey, SHRUNK_MM, yaw)
    assert not any(end.overlaps(o) for o in others), push
    assert math.dist((ex, ey), (cx, cy)) > math.dist((sx, sy), (cx, cy))


@settings(max_examples=25, deadline=None)
@given(st.data())
def test_every_push_keeps_off_the_other_blocks_and_the_bins(data: st.DataObject) -> None:
    n = data.draw(st.integers(2, 4), label="blocks")
    poses: list[Pose] = []
    for _ in range(n):
        x = data.draw(st.floats(150.0, 230.0), label="x")
        y = data.draw(st.floats(-80.0, 80.0), label="y")
        yaw = data.draw(st.floats(-40.0, 40.0), label="yaw")
        poses.append((x, y, yaw))
    squares = [_square(p) for p in poses]
    assume(not any(a.overlaps(b) for k, a in enumerate(squares) for b in squares[k + 1:]))
    i = data.draw(st.integers(0, n - 1), label="pushed")
    x, y, yaw = poses[i]
    others = _others(poses, i)
    push = PLANNER.plan(x, y, yaw, others)
    if push is None:
        return
    assert push.start == pytest.approx((x, y))
    length = math.dist(push.start, push.end)
    assert min(abs(length - 30.0), abs(length - 45.0)) < 1e-6, length
    hit = _first_hit(push, yaw, others)
    assert hit is None, f"the pushed block meets another block at {hit}: {push}"
    hit = _first_hit(push, yaw, [BIN], BIN_KEEP_OFF_MM - 1e-6)
    assert hit is None, f"the pushed block comes near the bin at {hit}: {push}"
    if push.frees:
        GRASPS.plan(push.end[0], push.end[1], yaw, neighbours=others)


@pytest.mark.parametrize("corner", range(len(GROUP)))
def test_an_obstacle_where_the_push_would_go_is_kept_off(corner: int) -> None:
    x, y, yaw = GROUP[corner]
    others = _others(GROUP, corner)
    preferred = PLANNER.plan(x, y, yaw, others)
    assert preferred is not None
    # A big thing (not a block) right where the preferred push would leave the block.
    ex, ey = preferred.end
    obstacle = Footprint.square(ex + (ex - x) * 0.5, ey + (ey - y) * 0.5, 40.0, 0.0)
    assert _square((ex, ey, yaw)).overlaps(obstacle)
    push = PLANNER.plan(x, y, yaw, others, obstacles=[obstacle])
    if push is None:
        return
    assert push.end != pytest.approx(preferred.end)
    end = Footprint.square(push.end[0], push.end[1], SHRUNK_MM, yaw)
    assert not end.overlaps(obstacle, BIN_KEEP_OFF_MM - 1e-6), push
    assert _first_hit(push, yaw, [obstacle]) is None, push
    assert _first_hit(push, yaw, others) is None, push


def test_a_block_walled_in_by_obstacles_is_not_pushed_into_them() -> None:
    x, y, yaw = GROUP[0]
    others = _others(GROUP, 0)
    # Walls on the two open sides of the corner block, close enough that no push fits.
    walls = [Footprint.rectangle(x - 30.0, y, 10.0, 200.0, 0.0),
             Footprint.rectangle(x, y - 30.0, 200.0, 10.0, 0.0)]
    assert not any(_square(GROUP[0]).overlaps(w, BIN_KEEP_OFF_MM) for w in walls)
    assert PLANNER.plan(x, y, yaw, others, obstacles=walls) is None
    # Without the walls it is pushed.
    assert PLANNER.plan(x, y, yaw, others) is not None


def test_a_corner_grazed_between_two_checked_points_is_seen() -> None:
    # Found by test_every_push_keeps_off_the_other_blocks_and_the_bins: checking the block
    # only every 3 mm along the push, the planner once missed the turned neighbour's corner
    # it crosses at x 172.2..173.9 mm (the shrunk block 0.12 mm into it, the cubes 1.12 mm).
    others = [Footprint.square(150.0, 0.0, 30.0, 0.0), Footprint.square(150.0, -70.0, 30.0, 14.0),
              Footprint.square(180.0, 0.0, 30.0, 0.0)]
    push = PLANNER.plan(150.0, -37.0, 4.0, others)
    # (Only towards the base is the block's way clear; there the arm reaches it only
    # leaning back, with a pad on the block at -70 mm: no push at all is right too.)
    hit = None if push is None else _first_hit(push, 4.0, others)
    assert hit is None, f"the pushed block meets another block at {hit}: {push}"
