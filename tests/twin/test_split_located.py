"""Touching blocks of one colour make one blob; the locator splits it into its blocks by
their top faces (busarm.perception.split) and locates each. On the twin, lit from the side (the
side faces bright on one side, dark on the other, shadows cast): as many sightings as
blocks, each within ``TOLERANCE_MM`` of a block, one to one. Scored against the twin's
truth, which the locator never reads."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.scene import DEFAULT_BINS, Block, Lighting, Scene
from busarm.twin.spec import TwinSpec

SIDE_MM = 30.0
TOUCH_GAP_MM = 0.03
"""Blocks drawn as touching stand this far apart (as busarm.twin.clutter has them): the
twin refuses blocks that interpenetrate."""
TOLERANCE_MM = 3.5
"""The worst seen: 3.2 mm, a block of the staggered cluster lit from +y (azimuth 90)."""
AZIMUTHS_DEG = (-90.0, 0.0, 90.0, 180.0)
"""Where the key light shines from (low, strong: long shadows, one side bright)."""

Points = list[tuple[float, float]]


def _apart(points: Points, yaw_deg: float) -> Points:
    """The blocks at ``points`` (all turned ``yaw_deg``), each that would interpenetrate
    one before it moved out along the block's axis it overlaps least on, until they
    touch (``TOUCH_GAP_MM`` apart)."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    uv = [(x * c + y * s, -x * s + y * c) for x, y in points]
    for i in range(1, len(uv)):
        for j in range(i):
            du, dv = uv[i][0] - uv[j][0], uv[i][1] - uv[j][1]
            over_u, over_v = SIDE_MM - abs(du), SIDE_MM - abs(dv)
            if over_u > 0 and over_v > 0:
                if over_u <= over_v:
                    uv[i] = (uv[i][0] + math.copysign(over_u + TOUCH_GAP_MM, du), uv[i][1])
                else:
                    uv[i] = (uv[i][0], uv[i][1] + math.copysign(over_v + TOUCH_GAP_MM, dv))
    return [(u * c - v * s, u * s + v * c) for u, v in uv]


def _row(x_mm: float, y_mm: float, yaw_deg: float, n: int) -> Points:
    """``n`` blocks in a touching row along ``yaw_deg``, centred at (x, y)."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    step = SIDE_MM + TOUCH_GAP_MM
    return [(x_mm + (k - (n - 1) / 2) * step * c, y_mm + (k - (n - 1) / 2) * step * s)
            for k in range(n)]


GROUPS: dict[str, tuple[str, Points, float]] = {
    # A touching pair, one slid 3.7 mm along the other's face.
    "pair": ("red", _apart([(200.0, 150.0), (230.0, 150.0)], -7.0), -7.0),
    # Two side by side 3 mm apart, a third on the next row touching both, shifted.
    "cluster": ("green", _apart([(158.0, -214.0), (191.0, -215.0), (172.0, -185.0)], -1.0),
                -1.0),
    "row": ("blue", _row(200.0, 40.0, 25.0, 3), 25.0),
}


@pytest.fixture(scope="module")
def calibration(twin_calibration: tuple[Path, Path]) -> tuple[Path, Path]:
    """The twin's camera calibration, made once per run by our flows (tests/conftest.py)."""
    return twin_calibration


def _matched(got: Points, truth: Points) -> list[float]:
    """The distances (mm) of the one-to-one pairing of ``got`` with ``truth`` (same
    length) whose largest distance is smallest."""
    return min((sorted(math.dist(g, t) for g, t in zip(got, order, strict=True))
                for order in itertools.permutations(truth)), key=lambda d: d[-1])


def test_the_groups_touch() -> None:
    # The set-up is what it says: one blob each. Every block touches another, or nearly
    # (the cluster's third block touches the first; the second, 1 mm lower at yaw -1, it
    # misses by under 0.5 mm), and in each group blocks touch (the twin allows no closer).
    for color, points, yaw in GROUPS.values():
        scene = Scene(blocks=tuple(Block(color, x, y, yaw) for x, y in points))
        gaps = {(i, j): _gap_mm(a, b, yaw) for i, a in enumerate(scene.blocks)
                for j, b in enumerate(scene.blocks) if i < j}
        assert min(gaps.values()) <= TOUCH_GAP_MM + 1e-6, (color, gaps)
        for i in range(len(points)):
            assert min(g for pair, g in gaps.items() if i in pair) < 0.5, (color, i, gaps)


def _gap_mm(a: Block, b: Block, yaw_deg: float) -> float:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    dx, dy = b.x_mm - a.x_mm, b.y_mm - a.y_mm
    du, dv = abs(dx * c + dy * s), abs(-dx * s + dy * c)
    return max(du - SIDE_MM, dv - SIDE_MM)


def _cases() -> Iterator[object]:
    for name in GROUPS:
        for azimuth in AZIMUTHS_DEG:
            yield pytest.param(name, azimuth, id=f"{name}-az{azimuth:g}")


@pytest.mark.parametrize(("name", "azimuth_deg"), list(_cases()))
def test_touching_blocks_are_located_one_by_one(calibration: tuple[Path, Path], name: str,
                                                azimuth_deg: float) -> None:
    color, points, yaw = GROUPS[name]
    light = Lighting(intensity=1.0, key_azimuth_deg=azimuth_deg, key_elevation_deg=35.0,
                     key_share=0.35, color_temp_k=5000.0)
    scene = Scene(blocks=tuple(Block(color, x, y, yaw) for x, y in points),
                  bins=DEFAULT_BINS[:3], lighting=light)
    cx = sum(x for x, _ in points) / len(points)
    cy = sum(y for _, y in points) / len(points)
    with Robot.open(RobotConfig(TwinSpec(scene=scene),
                                camera=CameraSpec(intrinsics=calibration[0],
                                                  hand_eye=calibration[1]))) as robot:
        look = robot.arm.config.pose("look")
        facing = robot.arm.config.check_joints((math.degrees(math.atan2(cy, cx)), *look[1:]))
        robot.arm.move_joints(facing)
        robot.clock.sleep(0.3)
        image = robot.camera.read().image
        joints = robot.arm.read_joints_deg()
        sightings = robot.locator().locate(image, joints)
        assert robot.twin is not None
        truth = [(b.x_mm, b.y_mm) for b in robot.twin.blocks() if b.color == color]
    assert len(truth) == len(points)
    got = [(s.location.x_mm, s.location.y_mm) for s in sightings if s.color == color]
    seen = [(round(x, 1), round(y, 1)) for x, y in got]
    assert len(got) == len(truth), f"{len(got)} sightings of {len(truth)} blocks: {seen}"
    assert all(s.whole for s in sightings if s.color == color), seen
    errors = _matched(got, truth)
    assert errors[-1] <= TOLERANCE_MM, (
        f"errors {[round(e, 2) for e in errors]} mm; seen {seen}, truth "
        f"{[(round(x, 1), round(y, 1)) for x, y in truth]}")


def test_a_pair_seen_off_to_the_side_is_two_blocks_not_one_thing(
        calibration: tuple[Path, Path]) -> None:
    # Two touching blocks in a row seen off the picture's middle from low (the clutter
    # family's seed 1): their blob, with the sides the camera sees, is large enough for
    # four, and the split makes four. The two that explain nothing the others do not are
    # dropped before the split is judged; judged with them, it explained too little, the
    # blob was judged one thing ("not square: 61 x 30 mm") and both blocks left alone.
    yaw = -44.37
    points = [(169.73, -52.92), (191.83, -73.27)]
    light = Lighting(intensity=0.87, key_azimuth_deg=35.6, key_elevation_deg=76.23,
                     key_share=0.25, color_temp_k=4980.0)
    scene = Scene(blocks=tuple(Block("red", x, y, yaw) for x, y in points),
                  bins=DEFAULT_BINS[:3], lighting=light)
    with Robot.open(RobotConfig(TwinSpec(scene=scene),
                                camera=CameraSpec(intrinsics=calibration[0],
                                                  hand_eye=calibration[1]))) as robot:
        # The sorter's oblique look (camera tilted, low) at a block 55 deg away from them.
        robot.arm.move_joints(robot.arm.config.check_joints((35.52, -42.48, 62.4, 15.12, 0.0)))
        robot.clock.sleep(0.3)
        found = robot.locator().find_in(robot.camera.read().image,
                                        robot.arm.read_joints_deg())
        assert robot.twin is not None
        truth = [(b.x_mm, b.y_mm) for b in robot.twin.blocks()]
    assert not found.not_blocks, found.not_blocks
    got = [(s.location.x_mm, s.location.y_mm) for s in found.blocks]
    assert len(got) == 2, got
    assert _matched(got, truth)[-1] <= TOLERANCE_MM, (got, truth)
