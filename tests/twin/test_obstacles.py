"""Things on the table that are not blocks (busarm.perception.obstacles), as the locator finds
them in the wrist camera's picture of a cluttered twin table from the look pose: every
distractor in view is covered by an obstacle, and a table with none shows no big
phantom (shadows are not things). Scored against the twin's scene, which the locator never
reads."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest

from busarm.perception.obstacles import Obstacle
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.twin.clutter import clutter_scene
from busarm.twin.scene import Distractor, Scene
from busarm.twin.spec import TwinSpec

COLORS = ("red", "green", "blue")
SEEDS = (2, 30, 45)
BIN_SIDE_MM = 90.0
IN_VIEW_BEARING_DEG = 35.0
IN_VIEW_RADIUS_MM = (120.0, 280.0)
"""Distractors whose centre lies within this bearing and radius are in the look pose's
picture (checked again by projecting the centre)."""
NEAR_MM = 5.0
"""A distractor's centre lies inside an obstacle, or at most this far outside it."""
PHANTOM_MM = 15.0
"""On a table with no distractors, no obstacle is bigger than this both ways."""


def _scene(seed: int, distractors: int | None = None) -> Scene:
    return clutter_scene(seed, 9, COLORS, distractors=distractors)


def _in_view(d: Distractor) -> bool:
    bearing = math.degrees(math.atan2(d.y_mm, d.x_mm))
    r = math.hypot(d.x_mm, d.y_mm)
    return (abs(bearing) <= IN_VIEW_BEARING_DEG
            and IN_VIEW_RADIUS_MM[0] <= r <= IN_VIEW_RADIUS_MM[1])


@dataclass(frozen=True)
class Look:
    """What the locator made of one look at a scene."""

    scene: Scene
    obstacles: list[Obstacle]
    image_size: tuple[int, int]
    """(width, height) px."""
    pixel: Callable[[float, float, float], tuple[float, float]]
    """Where a point (mm, base frame) lies in the picture."""
    table_z_mm: float


@pytest.fixture(scope="module")
def calibration(twin_calibration: tuple[Path, Path]) -> tuple[Path, Path]:
    """The twin's camera calibration, made once per run by our flows (tests/conftest.py)."""
    return twin_calibration


@pytest.fixture(scope="module")
def look(calibration: tuple[Path, Path]) -> Callable[[int, int | None], Look]:
    """Look at clutter scene ``seed`` (with ``distractors``) from the look pose, once."""
    seen: dict[tuple[int, int | None], Look] = {}

    def at(seed: int, distractors: int | None = None) -> Look:
        if (seed, distractors) not in seen:
            seen[seed, distractors] = _look(calibration, _scene(seed, distractors))
        return seen[seed, distractors]

    return at


def _look(calibration: tuple[Path, Path], scene: Scene) -> Look:
    with Robot.open(RobotConfig(TwinSpec(scene=scene),
                                camera=CameraSpec(intrinsics=calibration[0],
                                                  hand_eye=calibration[1]))) as robot:
        robot.arm.move_joints(robot.arm.config.pose("look"))
        robot.clock.sleep(0.3)
        image: npt.NDArray[np.uint8] = robot.camera.read().image
        joints = robot.arm.read_joints_deg()
        locator = robot.locator()
        obstacles = locator.obstacles(
            image, joints, [(x, y, BIN_SIDE_MM) for x, y in robot.bins.values()],
            locator.locate(image, joints))
        base2cam = np.linalg.inv(locator.cam2base(joints))
        intrinsics = robot.require_camera_calibration().intrinsics
        table_z = robot.config.table_z_mm

    def pixel(x: float, y: float, z: float) -> tuple[float, float]:
        p = base2cam @ np.array([x, y, z, 1.0])
        u, v = intrinsics.pixels_from_camera_points(p[None, :3])[0]
        return float(u), float(v)

    return Look(scene, obstacles, (image.shape[1], image.shape[0]), pixel, table_z)


def _distance_outside_mm(obstacle: Obstacle, x: float, y: float) -> float:
    """How far (x, y) lies outside the obstacle's outline (negative: inside)."""
    return -cv2.pointPolygonTest(obstacle.corners.astype(np.float32).reshape(-1, 1, 2),
                                 (x, y), True)


def _cases() -> list[object]:
    out: list[object] = []
    for seed in SEEDS:
        for i, d in enumerate(_scene(seed).distractors):
            if not _in_view(d):
                continue
            if d.color == "grey" and d.height_mm < 20.0:
                # Known limit (docs/benchmarks.md): a low mid-grey thing is seen 0.6-0.7 of
                # the table's brightness, as bright as a shadow, and is not found.
                continue
            out.append(pytest.param(seed, i, id=f"seed{seed}-{d.shape}{i}"))
    return out


@pytest.mark.parametrize(("seed", "index"), _cases())
def test_a_distractor_in_view_is_an_obstacle(look: Callable[[int, int | None], Look],
                                             seed: int, index: int) -> None:
    seen = look(seed, None)
    d = seen.scene.distractors[index]
    u, v = seen.pixel(d.x_mm, d.y_mm, seen.table_z_mm)
    w, h = seen.image_size
    assert 0 <= u < w and 0 <= v < h, f"{d} is not in the picture: ({u:.0f}, {v:.0f}) px"
    outside = [_distance_outside_mm(o, d.x_mm, d.y_mm) for o in seen.obstacles]
    found = [(round(o.centre_mm[0]), round(o.centre_mm[1])) for o in seen.obstacles]
    assert outside, f"no obstacle at all; {d.shape} at ({d.x_mm}, {d.y_mm}) mm missed"
    assert min(outside) <= NEAR_MM, (
        f"{d.shape} {d.color} at ({d.x_mm}, {d.y_mm}) mm lies {min(outside):.1f} mm outside "
        f"the nearest obstacle; obstacles at {found}")


def test_every_seed_has_a_distractor_in_view() -> None:
    # The cases above are not vacuous: each seed puts something in the picture.
    for seed in SEEDS:
        assert any(_in_view(d) for d in _scene(seed).distractors), seed


@pytest.mark.parametrize("seed", SEEDS)
def test_a_table_without_distractors_shows_no_big_phantom(
        look: Callable[[int, int | None], Look], seed: int) -> None:
    seen = look(seed, 0)
    assert not seen.scene.distractors
    big = []
    for o in seen.obstacles:
        (_, _), (a, b), _ = cv2.minAreaRect(o.corners.astype(np.float32))
        if min(a, b) > PHANTOM_MM:
            big.append((o.centre_mm, round(a, 1), round(b, 1)))
    assert not big, f"phantom obstacles (centre mm, sides mm): {big}"
