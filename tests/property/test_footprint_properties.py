"""Footprints on the table and grasps that keep their fingers off the neighbours."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlanner, NoClearGrasp
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics

CONFIG = load_arm_config()
PLANNER = GraspPlanner(ArmKinematics.from_config(CONFIG), 0.0, 30.0, 60.0, 75.0,
                       pad_mm=CONFIG.gripper.pad_mm)
GAPS = (50.0, 43.0, 36.0)


def _inside(poly: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which points lie strictly inside a convex polygon (counter-clockwise corners)."""
    edges = np.roll(poly, -1, axis=0) - poly
    rel = points[:, None, :] - poly[None, :, :]
    cross = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]
    return np.all(cross > 1e-6, axis=1)


def _share_area(a: Footprint, b: Footprint) -> bool:
    """Brute force: a point of a fine grid over one strictly inside both."""
    for p, q in ((a, b), (b, a)):
        lo, hi = p.corners.min(axis=0), p.corners.max(axis=0)
        grid = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], 81),
                                    np.linspace(lo[1], hi[1], 81)), -1).reshape(-1, 2)
        if np.any(_inside(p.corners, grid) & _inside(q.corners, grid)):
            return True
    return False


squares = st.tuples(st.floats(-60, 60), st.floats(-60, 60), st.floats(10, 40),
                    st.floats(-180, 180))


@settings(max_examples=200, deadline=None)
@given(a=squares, b=squares)
def test_overlap_agrees_with_a_brute_force_check(a: tuple[float, ...],
                                                 b: tuple[float, ...]) -> None:
    fa, fb = Footprint.square(*a), Footprint.square(*b)
    if fa.overlaps(fb):
        # Either they clearly share area, or they only graze: less deep than the grid's
        # spacing (under 0.75 mm; any strip 1.5 mm wide holds a grid point).
        assert _share_area(fa, fb) or fa.overlaps(fb, margin_mm=-1.5) is False
    else:
        assert not _share_area(fa, fb)


@settings(max_examples=100, deadline=None)
@given(x=st.floats(-100, 100), y=st.floats(-100, 100), side=st.floats(10, 40),
       yaw=st.floats(-180, 180), gap=st.floats(0.0, 20.0))
def test_touching_is_allowed_and_a_margin_is_kept(x: float, y: float, side: float,
                                                  yaw: float, gap: float) -> None:
    a = Footprint.square(x, y, side, yaw)
    u = np.array([math.cos(math.radians(yaw)), math.sin(math.radians(yaw))])
    b = Footprint.square(x + (side + gap) * u[0], y + (side + gap) * u[1], side, yaw)
    assert not a.overlaps(b)  # side by side, ``gap`` apart (0: touching)
    assert a.overlaps(b, margin_mm=gap + 0.1)
    assert not a.overlaps(b, margin_mm=max(0.0, gap - 0.1))


def _row(x: float, y: float, yaw: float, n: int, step: float = 30.0) -> list[Footprint]:
    u = (math.cos(math.radians(yaw)), math.sin(math.radians(yaw)))
    return [Footprint.square(x + k * step * u[0], y + k * step * u[1], 30.0, yaw)
            for k in range(n)]


@pytest.mark.parametrize("yaw", [0.0, 20.0, -35.0])
def test_every_block_of_a_touching_row_has_a_grasp_across_the_row(yaw: float) -> None:
    row = _row(150.0, -45.0, yaw, 4)
    for k, block in enumerate(row):
        c = block.corners.mean(axis=0)
        others = row[:k] + row[k + 1:]
        plan = PLANNER.plan(float(c[0]), float(c[1]), yaw, others, GAPS)
        for pad in PLANNER.pads(plan, plan.gap_mm):
            assert not any(pad.overlaps(o, PLANNER.margin_mm) for o in others)


def test_a_block_boxed_in_on_both_axes_has_no_clear_grasp() -> None:
    group = _row(160.0, -15.0, 0.0, 2) + _row(160.0, 15.0, 0.0, 2)  # touching 2 x 2
    with pytest.raises(NoClearGrasp, match="a finger would land on the block at"):
        PLANNER.plan(160.0, -15.0, 0.0, group[1:], GAPS)


def test_neighbours_16_mm_away_are_cleared_by_opening_less() -> None:
    # Neighbours 16 mm away on all four sides: only a narrow opening fits between them
    # (10 mm pads, 3 mm beside the block, 2.5 mm from the neighbour).
    near = [Footprint.square(180.0 + dx, dy, 30.0, 0.0)
            for dx, dy in ((46.0, 0.0), (-46.0, 0.0), (0.0, 46.0), (0.0, -46.0))]
    plan = PLANNER.plan(180.0, 0.0, 0.0, near, (50.0, 36.0))
    assert plan.gap_mm == 36.0
    with pytest.raises(NoClearGrasp):
        PLANNER.plan(180.0, 0.0, 0.0, near, (50.0,))
