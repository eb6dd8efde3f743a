"""Pick and place with the arm on the mobile base: blocks on the floor or on a low table
ahead of the robot, for navigation transport and for clearing a line.

Frames: what these functions take and give (``BlockSeen``, ``PlaceResult.where_m``,
``at_base_m``) is in the base frame, metres (x ahead, y left, the origin on the floor
under the base's centre; REP 103). The arm works in its own base frame, millimetres, on
the deck (``ChassisConfig.arm``): a surface ``height_m`` above the floor is at
``(height_m - arm.z_m) * 1000`` mm there (the JetAuto's floor at -145 mm).

- ``look_for_blocks``: the camera aimed at the surface ahead, left, right and near (look poses
  chosen from the kinematics and the hand-eye calibration: the camera's axis meets the
  surface there), each block located in mm (``BlockLocator`` on the surface's plane,
  frames averaged, merged across the looks by ``TableView``).
- ``pick_block``: the base slides (holonomic: no turning needed) so that the block sits
  where the arm takes it best, straight down at a comfortable reach clear of the chassis
  (``Reach``); a move of more than ``MAX_ALIGN_M`` is refused, and one the Lidar sees
  something in the way of too. Then a closer look (the camera straight over the block),
  the grasp (``GraspPlanner`` on the surface, the chassis and the other blocks kept off
  the fingers), the squeeze, the lift to above the deck, and the gripper's position says
  whether it holds. A miss is looked at again and tried again; a block moved meanwhile
  is looked for (close, then all round) and followed, or reported not found.
- ``place_block`` / ``put_aside``: set the held block down straight down (ahead, or beside
  the base's path), let go, rise, and look: ok only if a block of that colour is seen
  there.

The arm's config keeps its tool above its table (``table_z_mm``, the deck here); while
these run the arm reaches down to the surface (``Workspace.reaching``, in
busarm.apps.transport.workspace with the looks and the reach), and keeps off the chassis by
the grasp planner (the chassis is a neighbour no finger may touch) and by its travel
height (a held block passes over the deck).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.gripping import descend_and_grip, lower_and_release, still_holding
from busarm.apps.transport.workspace import (
    FLOOR,
    BlockSeen,
    Reach,
    Surface,
    Workspace,
    half_size_m,
    m_text,
    xy_mm,
)
from busarm.arm import Arm
from busarm.base.odometry import Pose2D
from busarm.errors import ConfigError, UnreachableError
from busarm.lidar.scan import to_points
from busarm.perception.locate import Sighting
from busarm.robot import Robot
from busarm.units import check_int_range

MAX_ALIGN_M = 0.3
"""Fine alignment moves the base this far at most (farther: drive there first)."""
ALIGNED_M = 0.005
"""A block this close to where the arm takes it best needs no move of the base."""
REALIGN_MM = 30.0
"""Seen closer this far from where the arm takes it best, the base moves again first."""
PATH_CLEAR_M = 0.03
"""The base moves only if the Lidar sees nothing this close to its footprint's way."""
FOUND_AGAIN_MM = 60.0
"""A block of the colour seen this close to where it was expected is the one."""
REFIND_M = 0.3
"""Looked for all round, a block of the colour this close to where it was is the one."""
PLACED_MM = 40.0
"""After a release, a block of the colour seen this close to the spot is the one put there."""
RELEASE_MM = 4.0
"""A block is let go with its bottom this high over the surface (it does not bounce)."""
ASIDE_M = 0.25
MIN_ASIDE_M = 0.19
"""``put_aside`` sets a block this far to the side of the base's centre line, or as far
as the arm reaches straight down, but no nearer than the second (off the base's path)."""
_HELD: weakref.WeakKeyDictionary[Arm, str] = weakref.WeakKeyDictionary()
"""The colour of the block each arm took (until it lets go)."""


@dataclass(frozen=True)
class PickResult:
    """``ok``: the gripper holds the block, lifted. ``attempts``: grasps tried;
    ``moved_base_m``: how far the fine alignment moved the base (odometry);
    ``seconds`` on the robot's clock."""

    ok: bool
    color: str
    attempts: int
    why: str = ""
    moved_base_m: float = 0.0
    seconds: float = 0.0


@dataclass(frozen=True)
class PlaceResult:
    """``ok``: let go, and a block of its colour seen where it was put: ``where_m`` (base
    frame, as seen; None if not seen). ``moved_base_m``: how far the base slid to reach
    the spot (odometry); ``seconds`` on the robot's clock."""

    ok: bool
    color: str | None
    where_m: tuple[float, float] | None
    why: str = ""
    seconds: float = 0.0
    moved_base_m: float = 0.0


# ---------------------------------------------------------------------- the API


def look_for_blocks(robot: Robot, surface: Surface, colors: Sequence[str] | None = None
                    ) -> list[BlockSeen]:
    """Every block of ``colors`` (default all) the wrist camera sees on ``surface`` ahead
    of the base and to its sides (base frame, m), nearest first."""
    ws = Workspace(robot, surface, colors)
    with ws.reaching():
        seen = ws.survey()
    return sorted(seen, key=lambda b: math.hypot(b.x_m, b.y_m))


def pick_block(robot: Robot, surface: Surface, block: BlockSeen, *,
               retries: int = 2) -> PickResult:
    """Take ``block`` (seen by ``look_for_blocks``) off ``surface``: see the module
    docstring. ``retries``: grasps tried again after a miss. Never ok unless the gripper,
    read back after the lift, holds something. UnreachableError (nothing moved) if the
    arm reaches no block on the surface."""
    check_int_range("retries", retries, 0, 10)
    ws = Workspace(robot, surface, [block.color])
    reach = ws.reach()
    job = _Pick(ws, reach, block.color)
    with ws.reaching():
        ok, why = job.run((block.x_m, block.y_m), retries)
    if ok:
        _HELD[ws.arm] = block.color
    return PickResult(ok, block.color, job.attempts, why, job.moved_m,
                      robot.clock.now() - job.began_s)


class _Pick:
    """One ``pick_block``: where the block is expected, how far the base moved, attempts."""

    def __init__(self, ws: Workspace, reach: Reach, color: str) -> None:
        self.ws, self.reach, self.color = ws, reach, color
        self.attempts = 0
        self.moved_m = 0.0
        self.began_s = ws.robot.clock.now()

    def run(self, at_m: tuple[float, float], retries: int) -> tuple[bool, str]:
        """Align, look, grasp until held or out of tries; (held, why not)."""
        ws, why = self.ws, ""
        goal_mm = (self.reach.comfortable_mm, 0.0)
        for _ in range(2 * (retries + 1) + 1):  # each pass grasps, or moves the base
            at_m, refused = self.align(at_m)
            if refused:
                return False, refused
            seen = ws.look_closer(self.color, *ws.to_arm_mm(*at_m))
            near = [s for s in seen if math.dist(xy_mm(s), ws.to_arm_mm(*at_m)) < FOUND_AGAIN_MM]
            if not near:
                found = self.find_again(at_m, seen)
                if found is None:
                    return False, (f"the {self.color} block is no longer near "
                                   f"{m_text(at_m)}: not seen there, nor within {REFIND_M:g} m "
                                   "of it looking all round")
                at_m = found
                continue
            target = near[0]
            at_m = ws.to_base_m(*xy_mm(target))
            if math.dist(xy_mm(target), goal_mm) > REALIGN_MM:
                continue  # (the odometry's slip, or it moved a little): line up again
            if self.attempts > retries:
                break
            self.attempts += 1
            why = self.take(target)
            if not why:
                return True, ""
        return False, why or "the block kept moving away"

    def align(self, at_m: tuple[float, float]) -> tuple[tuple[float, float], str]:
        """Slide the base so that the block at ``at_m`` comes to the comfortable reach
        (``_slide``): (where the block is expected now, "") or (``at_m``, why not:
        nothing moved)."""
        moved, why = _slide(self.ws, self.reach, at_m, f"the {self.color} block")
        self.moved_m += math.hypot(moved.x_m, moved.y_m)
        return _seen_from(moved, at_m), why

    def find_again(self, at_m: tuple[float, float], close: Sequence[Sighting]
                   ) -> tuple[float, float] | None:
        """Where the block expected at ``at_m`` is now (base frame): the nearest of its
        colour seen by the closer look, else looking all round, within ``REFIND_M``."""
        ws = self.ws

        def nearest(candidates: list[tuple[float, float]]) -> tuple[float, float] | None:
            near = [c for c in candidates if math.dist(c, at_m) < REFIND_M]
            return min(near, key=lambda c: math.dist(c, at_m)) if near else None

        return nearest([ws.to_base_m(*xy_mm(s)) for s in close]) or nearest(
            [(b.x_m, b.y_m) for b in ws.survey() if b.color == self.color])

    def take(self, target: Sighting) -> str:
        """Grasp, lift to the travel height, and read the gripper back; "" if it holds."""
        ws, s, arm = self.ws, self.ws.settings, self.ws.arm
        loc = target.location
        others = [Footprint.square(*xy_mm(v), ws.block_mm, v.location.yaw_deg)
                  for v in ws.view.seen if v is not target
                  and math.dist(xy_mm(v), xy_mm(target)) > ws.block_mm / 2]
        try:
            plan = ws.planner.plan(loc.x_mm, loc.y_mm, loc.yaw_deg, [ws.deck, *others],
                                   s.gaps_mm(ws.block_mm), ws.view.things)
        except UnreachableError as exc:
            return f"no grasp of it from here: {exc}"
        arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
        ws.rise_over_deck()
        arm.move_to(*plan.above, plan.pitch_deg, plan.roll_deg,
                    speed_deg_s=s.joint_speed_deg_s)
        arm.open_gripper(gap_mm=plan.gap_mm)
        missed = descend_and_grip(arm, plan, s.line_speed_mm_s)
        if missed:
            return missed
        arm.move_line(*plan.lift, plan.pitch_deg, plan.roll_deg, speed_mm_s=s.line_speed_mm_s)
        if not still_holding(arm):
            arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
            return "the block slipped out of the fingers during the lift"
        return ""


def place_block(robot: Robot, surface: Surface,
                at_base_m: tuple[float, float] | None = None) -> PlaceResult:
    """Set the held block down on ``surface`` at ``at_base_m`` (base frame, m; default
    straight ahead at the comfortable reach): straight down, let go, rise, and look; ok
    when a block of its colour is seen there. A spot the arm does not reach straight
    down from here is brought to the comfortable reach by sliding the base (as
    ``pick_block`` does; ``where_m`` is then in the base's frame where it ended)."""
    ws = Workspace(robot, surface)
    began = robot.clock.now()
    color = _HELD.get(ws.arm)
    reach = ws.reach()
    spot_m = ws.to_base_m(reach.comfortable_mm, 0.0) if at_base_m is None else at_base_m
    moved_m, why = 0.0, ""
    if not still_holding(ws.arm):
        _HELD.pop(ws.arm, None)
        why = "the gripper holds nothing to put down"
    elif not _reaches_down(ws, *ws.to_arm_mm(*spot_m)):
        moved, why = _slide(ws, reach, spot_m, "the spot")
        moved_m = math.hypot(moved.x_m, moved.y_m)
        spot_m = _seen_from(moved, spot_m)
    where = None
    if not why:
        with ws.reaching():
            where, why = _set_down(ws, ws.to_arm_mm(*spot_m), color)
    return PlaceResult(where is not None and not why, color, where, why,
                       robot.clock.now() - began, moved_m)


def _set_down(ws: Workspace, spot_mm: tuple[float, float], color: str | None
              ) -> tuple[tuple[float, float] | None, str]:
    """Carry the held block over ``spot_mm`` (arm frame) at the travel height, lower it,
    let go, rise, and look: (where a block of its colour is seen near the spot, base
    frame, or None; why not)."""
    s, arm = ws.settings, ws.arm
    x_mm, y_mm = spot_mm
    roll = ws.planner.roll_squared_deg(x_mm, y_mm, 0.0)
    above = (x_mm, y_mm, ws.z_mm + ws.travel_mm)
    ws.rise_over_deck()
    arm.move_to(*above, -90.0, roll, speed_deg_s=s.joint_speed_deg_s)
    if not still_holding(arm):
        _HELD.pop(arm, None)
        return None, "the block slipped out of the fingers on the way (nothing let go)"
    lower_and_release(arm, (x_mm, y_mm, ws.planner.grasp_z_mm + RELEASE_MM), -90.0, roll,
                      ws.block_mm + 2 * s.finger_clearance_mm, s.line_speed_mm_s)
    _HELD.pop(arm, None)
    arm.move_line(*above, -90.0, roll, speed_mm_s=s.line_speed_mm_s)
    near = [v for v in ws.look_closer(color, x_mm, y_mm)
            if math.dist(xy_mm(v), spot_mm) < PLACED_MM]
    if not near:
        what = f"{color} block" if color else "block"
        return None, (f"let go over {m_text(ws.to_base_m(*spot_mm))}, but no {what} is seen "
                      f"within {PLACED_MM:g} mm of it afterwards")
    return ws.to_base_m(*xy_mm(near[0])), ""


def put_aside(robot: Robot, surface: Surface, side: Literal["left", "right"]) -> PlaceResult:
    """Set the held block down beside the base's path (``ASIDE_M`` to the ``side`` of its
    centre line, or as far as the arm reaches straight down, at least ``MIN_ASIDE_M``),
    for clearing a line the base follows; as ``place_block``."""
    if side not in ("left", "right"):
        raise ConfigError(f"side {side!r}; allowed: left, right")
    ws = Workspace(robot, surface)
    sign = 1.0 if side == "left" else -1.0
    for aside in np.arange(ASIDE_M, MIN_ASIDE_M - 1e-9, -0.01).tolist():
        for ahead in np.arange(0.0, 0.16, 0.02).tolist():
            x_mm, y_mm = ws.to_arm_mm(ahead, sign * aside)
            if _reaches_down(ws, x_mm, y_mm):
                return place_block(robot, surface, (ahead, sign * aside))
    return PlaceResult(False, _HELD.get(robot.arm), None,
                       f"no spot {MIN_ASIDE_M:g}..{ASIDE_M:g} m to the {side} of the base's "
                       f"path is within the arm's straight-down reach on the {surface.name}")


# ---------------------------------------------------------------------- helpers


def _slide(ws: Workspace, reach: Reach, at_m: tuple[float, float], what: str
           ) -> tuple[Pose2D, str]:
    """Slide the base (no turn) so that ``at_m`` (base frame) comes to the comfortable
    reach: (where it went by the odometry, in the frame it had, "") or, refused with
    nothing moved, (no move, why): farther than ``MAX_ALIGN_M``, or the Lidar sees
    something in the way."""
    gx, gy = ws.to_base_m(reach.comfortable_mm, 0.0)
    dx, dy = at_m[0] - gx, at_m[1] - gy
    dist = math.hypot(dx, dy)
    still = Pose2D(0.0, 0.0, 0.0)
    if dist < ALIGNED_M:
        return still, ""
    if dist > MAX_ALIGN_M:
        return still, (f"{what} at {m_text(at_m)} is {dist:.2f} m from {m_text((gx, gy))}, where "
                       f"the arm reaches best; fine alignment moves the base at most "
                       f"{MAX_ALIGN_M:g} m: drive closer first")
    blocked = _in_the_way(ws, dx, dy)
    if blocked:
        return still, blocked
    assert ws.robot.base is not None
    return ws.robot.base.move_by(dx, dy, 0.0), ""


def _reaches_down(ws: Workspace, x_mm: float, y_mm: float) -> bool:
    """Whether a block is set down at (x, y) straight down and the tool rises to the
    travel height there, the fingers clear of the chassis."""
    try:
        plan = ws.planner.plan(x_mm, y_mm, 0.0, [ws.deck],
                               [ws.block_mm + 2 * ws.settings.finger_clearance_mm])
    except UnreachableError:
        return False
    return plan.pitch_deg == -90.0


def _in_the_way(ws: Workspace, dx_m: float, dy_m: float) -> str:
    """Why the base may not slide by (dx, dy): a Lidar return near its footprint's way
    ("" if none, or without a Lidar: it does not see lower than itself anyway)."""
    lidar = ws.robot.lidar
    if lidar is None:
        return ""
    points = to_points(lidar.read_scan(timeout_s=1.0), ws.chassis.lidar)
    half_x, half_y = half_size_m(ws.chassis)
    def clearance(t: float) -> npt.NDArray[np.float64]:  # from the footprint moved t of
        rel = np.abs(points - t * np.array([dx_m, dy_m]))  # the way (0 or less: inside)
        return np.asarray(np.maximum(rel[:, 0] - half_x, rel[:, 1] - half_y))

    start = clearance(0.0)
    points, start = points[start > 0.0], start[start > 0.0]  # not its own parts
    for t in np.linspace(0.1, 1.0, 10):
        # Near its way and nearer than where it stands: coming at it (not backing off).
        hit = (clearance(t) < PATH_CLEAR_M) & (clearance(t) < start)
        if hit.any():
            x, y = points[int(np.argmax(hit))]
            return (f"the Lidar sees something at {m_text((float(x), float(y)))}, within "
                    f"{PATH_CLEAR_M:g} m of the base's way: not sliding it by "
                    f"{m_text((dx_m, dy_m))}")
    return ""


def _seen_from(moved: Pose2D, at_m: tuple[float, float]) -> tuple[float, float]:
    """A point ``at_m`` of the base's frame, in its frame after it ``moved``."""
    here = Pose2D(*at_m, 0.0).relative_to(moved)
    return here.x_m, here.y_m


__all__ = ["FLOOR", "BlockSeen", "PickResult", "PlaceResult", "Reach", "Surface",
           "look_for_blocks", "pick_block", "place_block", "put_aside"]
