"""Pick and place with the arm on the mobile base (busarm.apps.transport.mobile_pick) on the arena
twin, through the real path: ``Robot.open(RobotConfig(TwinSpec(arena=...,
controller=BoardSettings())))`` drives the chassis through the simulated controller
board, the arm through its servos' bytes, and sees with the wrist camera (calibrated by
our own flows). The truth (the chassis's pose, the block bodies, the fingers, what
touched the chassis) is read only here.

The table arm's shoulder stops at horizontal (0 deg, the vendor's IK limit), so from the
JetAuto's deck its fingertips would go down to 105 mm below the arm's base, 40 mm above
the floor; on the deck the arm gets its shoulder servo's travel down to +30 deg (pulse 0;
busarm.arm.config.deck_mounted), with which the floor is reached.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from busarm.apps.pick_sort.gripping import descend_and_grip
from busarm.apps.pick_sort.look_poses import AIM_MM, TOOL_CLEAR_MM, look_pose
from busarm.apps.transport import mobile_pick
from busarm.apps.transport.mobile_pick import (
    FLOOR,
    MAX_ALIGN_M,
    MIN_ASIDE_M,
    BlockSeen,
    Surface,
    look_for_blocks,
    pick_block,
    place_block,
    put_aside,
)
from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import ArmConfig, deck_mounted, load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError, UnreachableError
from busarm.robot import ArmSpec, CameraSpec, Robot, RobotConfig
from busarm.sim.spec import BoardSettings
from busarm.twin.arena import Arena, Room, Solid, StartPose, arena_from_toml
from busarm.twin.arena_gen import random_arena
from busarm.twin.spec import TwinSpec
from busarm.twin.twin import Twin

pytestmark = pytest.mark.slow  # whole mobile picks on the twin

SHOULDER_SERVO_END_DEG = 30.0
"""The shoulder servo's end of travel (pulse 0), past the vendor's IK limit of 0 deg."""
HALF_WIDTH_M = 0.131
"""Half the JetAuto's width, its wheels included (mobile_pick's footprint of it)."""
NO_IMAGE = np.zeros((1, 1, 3), np.uint8)


@pytest.fixture(scope="module")
def calibration(twin_calibration: tuple[Path, Path]) -> tuple[Path, Path]:
    """The twin's camera calibration (tests/conftest.py): the wrist camera and its mount
    are the same on the arena's robot as on the table's."""
    return twin_calibration


@contextmanager
def robot_in(arena: Arena, calibration: tuple[Path, Path], config: ArmConfig | None = None
             ) -> Iterator[tuple[Robot, Twin]]:
    with Robot.open(RobotConfig(TwinSpec(arena=arena, controller=BoardSettings()),
                                ArmSpec(config=config),
                                camera=CameraSpec(intrinsics=calibration[0],
                                                  hand_eye=calibration[1]))) as robot:
        assert robot.twin is not None
        yield robot, robot.twin


def true_pose(twin: Twin) -> Pose2D:
    twin.sync()
    assert twin.mobile is not None
    with twin.lock:
        return twin.mobile.pose(twin.data)


def block_at(twin: Twin, index: int) -> tuple[float, float, float]:
    """Where block ``index``'s body really is (arena frame, m)."""
    twin.sync()
    with twin.lock:
        x, y, z = (float(v) for v in twin.data.xpos[twin.model.body(f"block{index}").id])
    return x, y, z


def in_base_frame(twin: Twin, x_m: float, y_m: float) -> tuple[float, float]:
    here = Pose2D(x_m, y_m, 0.0).relative_to(true_pose(twin))
    return here.x_m, here.y_m


def move_block(twin: Twin, index: int, x_m: float, y_m: float) -> None:
    """A hand puts block ``index`` down at (x, y) of the arena, square to it, at rest."""
    mj, model, data = twin.mujoco, twin.model, twin.data
    with twin.lock:
        joint = model.joint(f"block{index}")
        adr, dof = int(joint.qposadr[0]), int(joint.dofadr[0])
        data.qpos[adr:adr + 7] = (x_m, y_m, 0.015, 1.0, 0.0, 0.0, 0.0)
        data.qvel[dof:dof + 6] = 0.0
        mj.mj_forward(model, data)


def arena_facing(seed: int, distance_m: float, left_m: float) -> tuple[Arena, int]:
    """Seeded arena ``seed`` with the robot's start moved to face its first floor block
    ``distance_m`` ahead and ``left_m`` to the left, with room to move round it (walls,
    boxes, tables and other blocks well away): (the arena, the block's index)."""
    arena = random_arena(seed)
    index = next(i for i, b in enumerate(arena.blocks) if b.on is None)
    block = arena.blocks[index]
    r = arena.room
    for heading in range(0, 360, 10):
        h = math.radians(heading)
        x = block.x_m - distance_m * math.cos(h) + left_m * math.sin(h)
        y = block.y_m - distance_m * math.sin(h) - left_m * math.cos(h)
        if min(x - r.x_min_m, r.x_max_m - x, y - r.y_min_m, r.y_max_m - y) < 0.6:
            continue
        if any(s.footprint().distance_from_mm(x * 1000, y * 1000) < 500
               for s in (*arena.tables, *arena.boxes)):
            continue
        if any(math.dist((b.x_m, b.y_m), p) < 0.4 for i, b in enumerate(arena.blocks)
               if i != index for p in ((x, y), (block.x_m, block.y_m))):
            continue
        try:
            return replace(arena, start=StartPose(x, y, float(heading))), index
        except ConfigError:
            continue
    raise AssertionError(f"no clear start facing a floor block in arena {seed}")


def the_block(seen: list[BlockSeen], color: str, x_m: float, y_m: float) -> BlockSeen:
    return min((b for b in seen if b.color == color),
               key=lambda b: math.hypot(b.x_m - x_m, b.y_m - y_m))


def held(robot: Robot, twin: Twin, index: int) -> bool:
    """The block is truly in the fingers: off the floor, between them, closed on it."""
    x, y, z = block_at(twin, index)
    bx, by = in_base_frame(twin, x, y)
    tool = robot.arm.read_pose()
    between = math.hypot(bx - tool.x_mm / 1000, by - tool.y_mm / 1000) < 0.02
    return z > 0.1 and between and 25.0 < twin.finger_gap_mm() < 32.0


# ---------------------------------------------------------------------- look poses


@pytest.mark.parametrize(("surface_z_mm", "distance_mm", "camera_mm", "tilt_deg"), [
    (-145.0, 400.0, 420.0, 45.0), (-145.0, 185.0, 250.0, 15.0), (15.0, 235.0, 250.0, 15.0),
])
def test_a_look_pose_aims_the_camera_at_the_point(surface_z_mm: float, distance_mm: float,
                                                  camera_mm: float, tilt_deg: float) -> None:
    cfg = deck_mounted(load_arm_config())
    kin = ArmKinematics.from_config(replace(cfg, table_z_mm=surface_z_mm))
    assert cfg.camera is not None
    cam2link = CameraMount.from_config(cfg.camera).cam2link
    joints = look_pose(kin, cam2link, surface_z_mm, distance_mm, camera_mm, tilt_deg,
                       (146.0, 30.0))
    cam = kin.frames(joints)[3] @ cam2link
    origin, axis = cam[:3, 3], cam[:3, 2]
    t = (surface_z_mm - origin[2]) / axis[2]
    hit = origin + t * axis
    assert math.hypot(hit[0] - distance_mm, hit[1]) < AIM_MM
    assert math.degrees(math.acos(-axis[2])) <= tilt_deg + 1e-6
    assert abs(origin[2] - surface_z_mm - camera_mm) < 100.0
    assert kin.fk(joints).z_mm >= surface_z_mm + TOOL_CLEAR_MM
    with pytest.raises(UnreachableError, match="no look pose aims the camera at 900 mm"):
        look_pose(kin, cam2link, surface_z_mm, 900.0, camera_mm, tilt_deg)


# ---------------------------------------------------------------------- the floor


@pytest.mark.parametrize(("seed", "distance_m", "left_m", "put"), [
    (2, 0.42, 0.08, "0.2 m right"), (5, 0.33, -0.06, "aside left")])
def test_a_floor_block_is_picked_then_put_down_where_the_look_says(
        calibration: tuple[Path, Path], seed: int, distance_m: float, left_m: float,
        put: str) -> None:
    arena, index = arena_facing(seed, distance_m, left_m)
    color = arena.blocks[index].color
    with robot_in(arena, calibration) as (robot, twin):
        seen = look_for_blocks(robot, FLOOR)
        block = the_block(seen, color, distance_m, left_m)
        assert math.hypot(block.x_m - distance_m, block.y_m - left_m) < 0.01
        assert block.image.shape == (480, 640, 3)
        picked = pick_block(robot, FLOOR, block)
        assert picked.ok, picked.why
        assert (picked.color, picked.attempts) == (color, 1)
        assert held(robot, twin, index)
        # The base slid to line it up (about its distance less the reach, the offset).
        assert 0.1 < picked.moved_base_m < MAX_ALIGN_M
        picked_at = block_at(twin, index)
        if put == "0.2 m right":
            tool = robot.arm.read_pose()
            heading = true_pose(twin).yaw_rad
            placed = place_block(robot, FLOOR, (tool.x_mm / 1000, tool.y_mm / 1000 - 0.2))
        else:
            placed = put_aside(robot, FLOOR, "left")
        assert placed.ok, placed.why
        assert placed.color == color and placed.where_m is not None
        x, y, z = block_at(twin, index)
        truth = in_base_frame(twin, x, y)
        assert z == pytest.approx(0.015, abs=0.003)  # on the floor, upright
        assert math.dist(truth, placed.where_m) < 0.02
        assert twin.finger_gap_mm() > 32.0  # let go
    if put == "0.2 m right":  # 0.2 m to the right of where it was held, as the base faced
        dx, dy = x - picked_at[0], y - picked_at[1]
        right = dx * math.sin(heading) - dy * math.cos(heading)
        ahead = dx * math.cos(heading) + dy * math.sin(heading)
        assert right == pytest.approx(0.2, abs=0.02) and abs(ahead) < 0.02
    else:  # off the base's path: beside it, clear of its side
        assert truth[1] > MIN_ASIDE_M - 0.01
        assert truth[1] - 0.015 > HALF_WIDTH_M + 0.03


def test_a_block_moved_after_the_look_is_found_again_and_taken(
        calibration: tuple[Path, Path]) -> None:
    arena, index = arena_facing(3, 0.4, 0.0)
    color = arena.blocks[index].color
    with robot_in(arena, calibration) as (robot, twin):
        block = the_block(look_for_blocks(robot, FLOOR, [color]), color, 0.4, 0.0)
        # A hand moves it 9 cm to the left and 3 cm farther after the look.
        x, y, _ = block_at(twin, index)
        h = true_pose(twin).yaw_rad
        move_block(twin, index, x + 0.03 * math.cos(h) - 0.09 * math.sin(h),
                   y + 0.03 * math.sin(h) + 0.09 * math.cos(h))
        picked = pick_block(robot, FLOOR, block)
        assert picked.ok, picked.why
        assert held(robot, twin, index)


def test_a_grasp_that_closes_on_nothing_is_looked_at_again_and_retried(
        calibration: tuple[Path, Path], monkeypatch: pytest.MonkeyPatch) -> None:
    arena, index = arena_facing(2, 0.4, 0.0)
    color = arena.blocks[index].color
    with robot_in(arena, calibration) as (robot, twin):
        block = the_block(look_for_blocks(robot, FLOOR, [color]), color, 0.4, 0.0)
        descents: list[bool] = []

        def snatched(arm: Any, plan: Any, speed_mm_s: float, **kwargs: Any) -> str:
            # The first time the fingers come down, a hand puts the block 7 cm to the side.
            if not descents:
                x, y, _ = block_at(twin, index)
                h = true_pose(twin).yaw_rad
                move_block(twin, index, x - 0.07 * math.sin(h), y + 0.07 * math.cos(h))
            why = descend_and_grip(arm, plan, speed_mm_s, **kwargs)
            descents.append(not why)
            return why

        monkeypatch.setattr(mobile_pick, "descend_and_grip", snatched)
        picked = pick_block(robot, FLOOR, block)
        assert descents == [False, True]  # closed on nothing, then on the block
        assert picked.ok and picked.attempts == 2, picked.why
        assert held(robot, twin, index)


def test_a_block_taken_away_is_reported_not_found_and_not_picked(
        calibration: tuple[Path, Path]) -> None:
    arena, index = arena_facing(3, 0.4, 0.0)
    color = arena.blocks[index].color
    with robot_in(arena, calibration) as (robot, twin):
        block = the_block(look_for_blocks(robot, FLOOR, [color]), color, 0.4, 0.0)
        pose = true_pose(twin)  # put behind the robot, where no look of it sees
        away = (pose.x_m - 0.45 * math.cos(pose.yaw_rad), pose.y_m - 0.45 * math.sin(pose.yaw_rad))
        move_block(twin, index, *away)
        picked = pick_block(robot, FLOOR, block)
        assert not picked.ok
        assert picked.attempts == 0
        assert f"the {color} block is no longer near" in picked.why
        assert "not seen there, nor within 0.3 m of it" in picked.why
        assert block_at(twin, index)[2] == pytest.approx(0.015, abs=0.003)  # still on the floor
        assert twin.finger_gap_mm() > 32.0  # the fingers never closed on it
        placed = place_block(robot, FLOOR)  # nothing to put down: nothing moves
        assert not placed.ok and placed.why == "the gripper holds nothing to put down"


def test_on_the_deck_the_shoulder_turns_down_to_its_servos_end() -> None:
    table_arm = load_arm_config()
    on_deck = deck_mounted(table_arm)
    changed = [(a.name, a.max_deg, b.max_deg) for a, b in zip(table_arm.joints, on_deck.joints,
                                                             strict=True) if a != b]
    assert changed == [("shoulder_pitch", 0.0, pytest.approx(SHOULDER_SERVO_END_DEG))]
    shoulder = on_deck.joint("shoulder_pitch")
    assert shoulder.pulses_from_angle_deg(shoulder.max_deg) == pytest.approx(0.0)
    with pytest.raises(ConfigError, match="no joint 'hip'"):
        deck_mounted(table_arm, "hip")
    twin = Twin(arena=Arena(room=Room(-1.0, 2.0, -1.5, 1.5), name="empty"))
    try:
        assert twin.config.joint("shoulder_pitch").max_deg == pytest.approx(
            SHOULDER_SERVO_END_DEG)
    finally:
        twin.close()


def test_fine_alignment_refuses_far_moves_and_things_in_the_way(
        calibration: tuple[Path, Path]) -> None:
    # A box beside the robot on its left, 9 cm from its side: seen by the Lidar.
    arena = Arena(room=Room(-1.0, 2.0, -1.5, 1.5), boxes=(Solid(0.1, 0.32, 0.2, 0.2, 0.3),),
                  name="box on the left")
    with robot_in(arena, calibration) as (robot, twin):
        far = pick_block(robot, FLOOR, BlockSeen("red", 0.9, -0.1, 0.0, NO_IMAGE))
        assert not far.ok and far.attempts == 0 and far.moved_base_m == 0.0
        assert far.why == ("the red block at (0.90, -0.10) m is 0.72 m from (0.18, 0.00) m, "
                           "where the arm reaches best; fine alignment moves the base at most "
                           "0.3 m: drive closer first")
        left = pick_block(robot, FLOOR, BlockSeen("green", 0.3, 0.09, 0.0, NO_IMAGE))
        assert not left.ok and left.attempts == 0
        assert left.why.startswith("the Lidar sees something at (")
        assert "within 0.03 m of the base's way: not sliding it by (0.11, 0.09) m" in left.why
        assert math.hypot(true_pose(twin).x_m, true_pose(twin).y_m) < 1e-3  # never moved
        # Away from the box it slides (then finds no block there: there is none).
        right = pick_block(robot, FLOOR, BlockSeen("green", 0.3, -0.09, 0.0, NO_IMAGE))
        assert not right.ok and right.attempts == 0
        assert right.why.startswith("the green block is no longer near")
        moved = true_pose(twin)
        assert right.moved_base_m == pytest.approx(math.hypot(0.115, 0.09), abs=0.01)
        assert moved.y_m == pytest.approx(-0.09, abs=0.01)
        assert twin.mobile is not None and twin.mobile.contacts == []
    with pytest.raises(ConfigError, match=r"height_m = -0\.1 m is out of range"):
        Surface("pit", -0.1)
    with pytest.raises(ConfigError, match="side 'back'; allowed: left, right"):
        put_aside(robot, FLOOR, "back")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="retries"):
        pick_block(robot, FLOOR, BlockSeen("red", 0.3, 0.0, 0.0, NO_IMAGE), retries=-1)


# ---------------------------------------------------------------------- a table

TABLE_ARENA = """
format = "busarm.arena"
version = 1
name = "a table ahead"
room = { x_min_m = -1.0, x_max_m = 2.0, y_min_m = -1.5, y_max_m = 1.5 }
start = { x_m = 0.1, y_m = 0.0, yaw_deg = 0.0 }

[[tables]]
x_m = 0.75
y_m = 0.0
size_x_m = 0.4
size_y_m = 0.6
height_m = 0.16

[[blocks]]
color = "blue"
x_m = 0.62
y_m = -0.05
yaw_deg = 12.0
on = 0
"""


def test_a_table_block_is_picked_by_the_shipped_arm(calibration: tuple[Path, Path]) -> None:
    # The table's edge 0.45 m ahead of the base's centre; the block 7 cm behind it.
    arena = arena_from_toml(TABLE_ARENA, "a table ahead")
    table = Surface("table", arena.tables[0].height_m)
    with robot_in(arena, calibration) as (robot, twin):
        block = the_block(look_for_blocks(robot, table), "blue", 0.52, -0.05)
        assert math.hypot(block.x_m - 0.52, block.y_m + 0.05) < 0.01
        picked = pick_block(robot, table, block)
        assert picked.ok, picked.why
        assert held(robot, twin, 0)
        assert block_at(twin, 0)[2] > arena.tables[0].height_m + 0.05  # off the table
        placed = place_block(robot, table)  # straight ahead, at the comfortable reach
        assert placed.ok and placed.where_m is not None, placed.why
        x, y, z = block_at(twin, 0)
        assert math.dist(in_base_frame(twin, x, y), placed.where_m) < 0.02
        assert z == pytest.approx(arena.tables[0].height_m + 0.015, abs=0.003)
        assert twin.mobile is not None and twin.mobile.contacts == []  # never touched it
