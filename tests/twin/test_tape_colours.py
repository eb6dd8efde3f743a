"""Tape of every colour through the wrist camera on the arena twin's renders (issue 33).

The robot opens on the arena twin behind its board with the twin's camera calibration
made by our own flows (``twin_calibration``), looks ahead (``look_ahead``) and takes a
frame, as ``LineFollowJob`` does; neither reads the twin's truth, which the tests then
compare with: the arena's tape centreline and block put into the base frame by the
chassis's true pose. Each tape is the twin's (``LINE_COLORS``; white on the dark floor),
with a block of the tape's own colour standing on it (a red one on black or white tape).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from test_floor_view import distance_to

from busarm.apps.line_follow.floor_look import floor_camera, look_ahead
from busarm.apps.line_follow.job import LineFollowJob
from busarm.apps.line_follow.tape_camera import TapeHidingCamera, tape_hidden
from busarm.apps.transport.mobile_pick import FLOOR
from busarm.apps.transport.workspace import Workspace
from busarm.bench.line import family_arena
from busarm.errors import ConfigError, NavigationError
from busarm.robot import CameraSpec, Robot, RobotConfig
from busarm.sim.spec import BoardSettings
from busarm.twin.arena import LINE_COLORS, Arena, ArenaBlock, FloorLine, Room, Solid, StartPose
from busarm.twin.arena_gen import loop_points, random_arena
from busarm.twin.spec import TwinSpec
from busarm.vision.tape_colour import measure_tape, without_tape

Points = npt.NDArray[np.float64]
BLOCK_AHEAD_M = 0.35
"""The block stands on the tape this far along it from the start."""


def taped(colour: str, aside_m: float = 0.0) -> Arena:
    """Seeded arena 1 taped in ``colour`` (white on the dark floor), its floor blocks
    replaced by one block on the tape ``BLOCK_AHEAD_M`` ahead of the start (``aside_m``
    to its left)."""
    arena = random_arena(1, floor_blocks=0)
    pts = arena.lines[0].points_m
    k = (len(pts) // 2 + round(BLOCK_AHEAD_M / 0.02)) % len(pts)
    (ax, ay), (bx, by) = pts[k - 1], pts[(k + 1) % len(pts)]
    along = math.atan2(by - ay, bx - ax)
    x = round(pts[k][0] - aside_m * math.sin(along), 4)
    y = round(pts[k][1] + aside_m * math.cos(along), 4)
    block = ArenaBlock(colour if colour not in ("black", "white") else "red", x, y, 25.0)
    return dataclasses.replace(
        arena, lines=(dataclasses.replace(arena.lines[0], color=colour),),
        floor="dark" if colour == "white" else "light",
        blocks=(*(b for b in arena.blocks if b.on is not None), block))


def layout_9_white() -> tuple[Arena, StartPose]:
    """Line bench layout 9 taped white, its red block last, and a pose on the tape 0.28 m
    before the block, facing along the tape (the block then lies on the tape's edge)."""
    arena = family_arena(9, 3, "white")
    red = next(b for b in arena.blocks if b.on is None and b.color == "red")
    pts = np.array(arena.lines[0].points_m)
    k = int(np.argmin(np.hypot(pts[:, 0] - red.x_m, pts[:, 1] - red.y_m))) - 14
    (ax, ay), (bx, by) = pts[k - 1], pts[k + 1]
    others = tuple(b for b in arena.blocks if b is not red)
    return (dataclasses.replace(arena, blocks=(*others, red)),
            StartPose(float(pts[k, 0]), float(pts[k, 1]),
                      math.degrees(math.atan2(by - ay, bx - ax))))


def set_down(robot: Robot, pose: StartPose) -> None:
    """Put the chassis at ``pose`` (the twin's truth, as a person carries the robot)."""
    twin = robot.twin
    assert twin is not None
    with twin.lock:
        for name, value in (("chassis_x", pose.x_m), ("chassis_y", pose.y_m),
                            ("chassis_yaw", math.radians(pose.yaw_deg))):
            joint = twin.model.joint(name)
            twin.data.qpos[joint.qposadr[0]] = value
            twin.data.qvel[joint.dofadr[0]] = 0.0
        twin.mujoco.mj_forward(twin.model, twin.data)


def in_base(arena: Arena, points: Points, at: StartPose | None = None) -> Points:
    """Arena points in the base frame of the robot at ``at`` (its start: it has not
    moved)."""
    s = arena.start if at is None else at
    c, si = math.cos(math.radians(s.yaw_deg)), math.sin(math.radians(s.yaw_deg))
    d = np.asarray(points, dtype=np.float64) - [s.x_m, s.y_m]
    return np.column_stack([d[:, 0] * c + d[:, 1] * si, -d[:, 0] * si + d[:, 1] * c])


@pytest.mark.parametrize("colour", list(LINE_COLORS))
def test_every_tape_is_measured_followed_and_kept_apart_from_blocks(
        colour: str, twin_calibration: tuple[Path, Path]) -> None:
    arena = taped(colour)
    tape = in_base(arena, np.array([*arena.lines[0].points_m, arena.lines[0].points_m[0]]))
    block = in_base(arena, np.array([[arena.blocks[-1].x_m, arena.blocks[-1].y_m]]))[0]
    intrinsics, hand_eye = twin_calibration
    with Robot.open(RobotConfig(TwinSpec(arena=arena, controller=BoardSettings()),
                                camera=CameraSpec(intrinsics=intrinsics,
                                                  hand_eye=hand_eye))) as robot:
        look_ahead(robot)
        camera = floor_camera(robot)
        image = robot.camera.read().image
        # The first look: the tape's colour, not told.
        look = measure_tape(image, camera.intrinsics, camera.cam_to_floor, mask=camera.mask)
        assert look is not None and look.name == colour, look and look.text()
        # Followed by that colour: where the tape truly is, stepping over the block.
        sighting = camera.find_line(image, look.colour)
        assert sighting is not None and sighting.colour == colour
        assert np.max(distance_to(tape, sighting.points_m)) < 0.01
        assert sighting.length_m > 0.4
        # The blocks and the things in the way: the tape is neither; the block on it is
        # found where it stands.
        ws = Workspace(robot, FLOOR, ["red", "green", "blue", "yellow"])
        clean = (image if colour in ("black", "white") else
                 without_tape(image, sighting, camera.intrinsics, camera.cam_to_floor,
                              camera.mask))
        found = [ws.seen(s, clean) for s in ws.locator.locate(clean, camera.joints_deg)]
        assert [b.color for b in found] == [arena.blocks[-1].color]
        assert math.dist((found[0].x_m, found[0].y_m), block) < 0.015
        assert ws.locator.obstacles(image, camera.joints_deg,
                                    blocks=ws.locator.locate(clean, camera.joints_deg)) == []


def test_a_tape_colour_that_is_not_known_is_refused(twin_calibration: tuple[Path, Path]
                                                    ) -> None:
    with Robot.open(RobotConfig(TwinSpec(arena=taped("blue"), controller=BoardSettings()),
                                camera=CameraSpec(intrinsics=twin_calibration[0],
                                                  hand_eye=twin_calibration[1]))) as robot:
        before = robot.arm.read_joints_deg()
        with pytest.raises(ConfigError, match=r"^tape colour 'purple': allowed: black, "
                                              r"white, red, green, blue, yellow$"):
            LineFollowJob(robot, tape="purple")
        assert robot.arm.read_joints_deg() == before  # nothing moved


def test_a_lost_line_is_reported_as_lost_not_as_an_obstacle(
        twin_calibration: tuple[Path, Path]) -> None:
    """Blue tape that ends with a box 0.25 m beyond its end: the tape runs out, the box
    is in the Lidar's stop range straight ahead, and the line is lost: that is what is
    done (looked for, turning) and said, not a stop for the box (issue 33: "something
    0.49 m ahead ... stayed in the base's way for 30 s")."""
    pts = loop_points((0.0, 0.0), (0.8, 0.55), 2, 0.0, 0.0)
    order = pts[len(pts) // 2:] + pts[: len(pts) // 2]
    (ax, ay), (bx, by) = order[-1], order[1]
    line = FloorLine(tuple(order[:40]), 0.03, color="blue")
    (ex, ey), (fx, fy) = order[38], order[39]
    heading = math.atan2(fy - ey, fx - ex)
    box = Solid(round(fx + 0.35 * math.cos(heading), 3), round(fy + 0.35 * math.sin(heading), 3),
                0.2, 0.2, 0.3, math.degrees(heading))
    arena = Arena(room=Room(-1.5, 1.5, -1.2, 1.2), boxes=(box,), lines=(line,),
                  start=StartPose(order[0][0], order[0][1],
                                  math.degrees(math.atan2(by - ay, bx - ax))),
                  name="blue tape ending before a box")
    with Robot.open(RobotConfig(TwinSpec(arena=arena, controller=BoardSettings()),
                                camera=CameraSpec(intrinsics=twin_calibration[0],
                                                  hand_eye=twin_calibration[1]))) as robot:
        job = LineFollowJob(robot, laps=1.0, obstacle_wait_s=2.0, colors=[])
        with pytest.raises(NavigationError, match=(
                r"^the line is lost: not seen for 1\.\d s, nor turning 90 deg each way at ")):
            job.run()
        assert robot.base is not None and robot.base.command.is_zero
        assert robot.twin is not None and robot.twin.mobile is not None
        assert robot.twin.mobile.contacts == []
    assert job.report.tape == "blue" and job.report.tape_measured
    assert job.report.stops == [] and job.report.searches == 1


@pytest.mark.parametrize("colour", ["red", "white"])
def test_a_close_look_at_a_block_on_the_tape_sees_the_block(
        colour: str, twin_calibration: tuple[Path, Path]) -> None:
    """The pick's closer look, straight above a red block on red tape (on the edge of
    white tape: line bench layout 9's): through the tape-hiding camera the block is seen
    whole where it stands (the tape beside it is painted out of the picture; through the
    robot's own camera the block and the red tape are one blob, and the white tape's edge
    is taken for the block's side: no block); the robot's own camera is back after."""
    arena, place = (taped("red"), None) if colour == "red" else layout_9_white()
    block = in_base(arena, np.array([[arena.blocks[-1].x_m, arena.blocks[-1].y_m]]), place)[0]
    intrinsics, hand_eye = twin_calibration
    with Robot.open(RobotConfig(TwinSpec(arena=arena, controller=BoardSettings()),
                                camera=CameraSpec(intrinsics=intrinsics,
                                                  hand_eye=hand_eye))) as robot:
        if place is not None:
            set_down(robot, place)
        own = robot.camera
        plain = Workspace(robot, FLOOR, ["red"])
        assert plain.look_closer("red", *plain.to_arm_mm(*block)) == []  # block and tape: one
        with tape_hidden(robot, colour):
            assert isinstance(robot.camera, TapeHidingCamera)
            ws = Workspace(robot, FLOOR, ["red"])  # as the pick makes it, meanwhile
            seen = ws.look_closer("red", *ws.to_arm_mm(*block))
        assert robot.camera is own
    assert len(seen) == 1
    at = ws.to_base_m(seen[0].location.x_mm, seen[0].location.y_mm)
    assert math.dist(at, block) < 0.01
    assert seen[0].location.size_mm == pytest.approx(30.0, abs=4.0)
