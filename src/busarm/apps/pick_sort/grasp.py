"""Grasps of cubes on a table: straight down where the arm reaches, else tilted, the
fingers squared to the cube's faces and every point of each straight move checked for
reach. Pure geometry: no bus, no camera."""

from __future__ import annotations

import contextlib
import itertools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.footprint import Footprint
from busarm.arm.chain import Joints
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import UnreachableError
from busarm.units import check_range, place_text

__all__ = [
    "CLEARANCE_MARGIN_MM",
    "LINE_CHECK_MM",
    "MAX_CLOSING_TILT_DEG",
    "MAX_TILTED_TURN_DEG",
    "ROLL_STEP_DEG",
    "SWEEP_SAMPLES",
    "TILTED_PITCHES_DEG",
    "FloatArray",
    "GraspPlan",
    "GraspPlanner",
    "NoClearGrasp",
    "Thing",
]


FloatArray = npt.NDArray[np.float64]

TILTED_PITCHES_DEG = (-75.0, -60.0, -45.0, -30.0, -105.0, -120.0)
"""Tool pitches tried, in order, where straight down does not reach: leaning out for far
blocks, leaning back towards the base for near ones."""
MAX_CLOSING_TILT_DEG = 20.0
"""A tilted grasp's fingers close along a line at most this far from level, so the pads
lie flat enough on the block's upright sides. (Leaning far, that leaves little room to
turn the wrist: the fingers close nearly across the arm's bearing.)"""
MAX_TILTED_TURN_DEG = 30.0
"""A block left more than this off square to the fingers is not taken tilted (they would
meet its edges)."""
ROLL_STEP_DEG = 2.0
"""The wrist rolls tried for a tilted grasp are this far apart."""
CLEARANCE_MARGIN_MM = 2.5
"""How far a finger pad keeps from a neighbour: the survey's localisation error (p95 about
2 mm, docs/benchmarks.md) and a little."""
LINE_CHECK_MM = 2.0
"""Points this far apart are checked for reach along each straight move of a grasp plan
(more densely than ``Arm.move_line`` solves them, so a plan that passes does not fail on
the way)."""


SWEEP_SAMPLES = 5
"""A pad's swept volume is checked against a thing at points about 4 mm apart (its width
over 4): thinner than a pen with the margin on both sides."""


class Thing(Protocol):
    """Something that is not a block: what it stands on (``corners``, N x 2 mm, convex)
    and whether it may come within a margin of points in space (a ``Footprint`` may be
    any height; ``busarm.perception.obstacles.Obstacle`` knows its cameras' cones)."""

    @property
    def corners(self) -> FloatArray: ...

    @property
    def centre_mm(self) -> tuple[float, float]: ...

    def reaches(self, points_mm: FloatArray, margin_mm: float) -> bool: ...


@dataclass(frozen=True)
class GraspPlan:
    """How to take one block: the tool's pitch and roll and three tool points (mm, base
    frame): the straight approach starts ``above`` it, closes at ``grasp``, lifts to
    ``lift``."""

    pitch_deg: float
    roll_deg: float
    above: tuple[float, float, float]
    grasp: tuple[float, float, float]
    lift: tuple[float, float, float]
    gap_mm: float = 0.0
    """How far apart the fingers open for it (0: not chosen yet)."""


class NoClearGrasp(UnreachableError):
    """Every grasp that reaches the block would put a finger on a neighbour."""


@dataclass(frozen=True)
class GraspPlanner:
    """Grasps of cubes ``block_mm`` wide on a table at ``table_z_mm``, for an arm: pure
    geometry (no bus), the fingertips at the cube's half height."""

    kin: ArmKinematics
    table_z_mm: float
    block_mm: float
    approach_mm: float
    """How far before the grasp the straight approach starts (along the tool's axis)."""
    carry_mm: float
    """The height above the table the block is lifted to."""
    pad_mm: tuple[float, float, float] = (10.0, 16.0, 36.0)
    """A finger pad's thickness, width and length (``GripperConfig.pad_mm``)."""
    margin_mm: float = CLEARANCE_MARGIN_MM
    """How far a finger must stay from a neighbour (where things are is known this well)."""

    def __post_init__(self) -> None:
        check_range("table_z_mm", self.table_z_mm, -500.0, 500.0, "mm")
        check_range("block_mm", self.block_mm, 5.0, 100.0, "mm")
        check_range("approach_mm", self.approach_mm, 5.0, 300.0, "mm")
        check_range("carry_mm", self.carry_mm, self.block_mm, 300.0, "mm")

    @property
    def grasp_z_mm(self) -> float:
        return self.table_z_mm + self.block_mm / 2

    def roll_squared_deg(self, x_mm: float, y_mm: float, yaw_deg: float) -> float:
        """The wrist roll that squares the fingers (closing along the tool's y) to a block
        at ``yaw_deg`` (modulo 90), the smallest such turn."""
        a0 = self.finger_axis_deg(x_mm, y_mm, 0.0)
        a1 = self.finger_axis_deg(x_mm, y_mm, 10.0)
        sign = 1.0 if (a1 - a0 + 180.0) % 360.0 - 180.0 > 0 else -1.0
        return ((yaw_deg - a0) * sign + 45.0) % 90.0 - 45.0

    def finger_axis_deg(self, x_mm: float, y_mm: float, roll_deg: float) -> float:
        """The direction (deg, base frame) the fingers close along, straight down over
        (x, y) at this wrist roll; UnreachableError if the arm cannot be there so."""
        kin = self.kin
        return _finger_axis_deg(
            kin.fk_matrix(kin.ik_best(x_mm, y_mm, self.grasp_z_mm, -90.0, roll_deg)))

    def plan(self, x_mm: float, y_mm: float, yaw_deg: float,
             neighbours: Sequence[Footprint] = (),
             gaps_mm: Sequence[float] = (), obstacles: Sequence[Thing] = ()
             ) -> GraspPlan:
        """The first grasp that reaches the block and keeps both fingers off its
        ``neighbours`` all the way down (with ``margin_mm``): straight down with the
        fingers squared to the block, along one face pair then the other; else tilted
        (``TILTED_PITCHES_DEG``), closing level, the approach along the tool's axis; for
        each, the fingers opened ``gaps_mm`` apart (widest first; default: the block and
        10 mm a side), wider by as much as the pads lean in over the block
        (``GraspPlan.gap_mm``: the opening). ``obstacles``: things that are not blocks
        (see ``Thing``), kept off all the way from ``above``. Raises NoClearGrasp naming
        what is in the way if every reaching grasp is blocked, UnreachableError saying
        why none reaches."""
        gaps = sorted(gaps_mm or (self.block_mm + 20.0,), reverse=True)
        blocked = ""
        for plan in self._reaching(x_mm, y_mm, yaw_deg):
            wider = self._wider_mm(plan, yaw_deg)
            for gap in gaps:
                hit = (self._first_hit(plan, gap + wider, neighbours)
                       or self._first_thing(plan, gap + wider, obstacles))
                if hit is None:
                    return replace(plan, gap_mm=gap + wider)
                blocked = blocked or (f"a finger would land on the {hit[2]} at "
                                      f"{place_text(hit[:2])}")
        if blocked:
            raise NoClearGrasp(f"no grasp clears its neighbours: {blocked}")
        raise UnreachableError(self._why_unreachable(x_mm, y_mm, yaw_deg))

    def _wider_mm(self, plan: GraspPlan, yaw_deg: float) -> float:
        """How much wider than a gap between upright pads the fingers open for ``plan``
        to leave the block the same room: pads that close along an axis tilted phi from
        level (a tilted grasp) lean in over the block's top edge, and pads theta off
        square meet its corners, so the block reaches s/2 (cos phi (cos theta + sin
        theta) + sin phi) from the grasp along the closing axis, not s/2 (opened the
        least a sorter offers, 3 mm a side, a pad tilted 15 deg landed on the edge)."""
        kin = self.kin
        m = kin.fk_matrix(kin.ik_best(*plan.grasp, plan.pitch_deg, plan.roll_deg))
        tilt = _closing_tilt_rad(m)
        turn = math.radians(abs((_finger_axis_deg(m) - yaw_deg + 45.0) % 90.0 - 45.0))
        reach = math.cos(tilt) * (math.cos(turn) + math.sin(turn)) + math.sin(tilt)
        return max(0.0, self.block_mm * (reach - 1.0))

    def out_of_reach(self, x_mm: float, y_mm: float, yaw_deg: float,
                     beyond_mm: float = 0.0) -> str:
        """"out of reach (D mm from the base; reach R mm)" if the block at (x, y), or as
        much as ``beyond_mm`` farther out (where one seen only in part may be), is beyond
        the farthest grasp on its bearing; "" if not."""
        dist_mm = math.hypot(x_mm, y_mm)
        reach = self.reach_mm(x_mm, y_mm, yaw_deg)
        if reach is None or dist_mm + beyond_mm <= reach:
            return ""
        where = f"{dist_mm:.0f} mm from the base" + (
            "" if dist_mm > reach else f" as seen, up to {dist_mm + beyond_mm:.0f} mm")
        return f"out of reach ({where}; reach {reach:.0f} mm)"

    def reach_mm(self, x_mm: float, y_mm: float, yaw_deg: float) -> float | None:
        """How far from the base, on the bearing of (x, y), a grasp reaches a block at
        ``yaw_deg`` (the farthest one, to 1 mm); None if none does on that bearing."""
        dist_mm = math.hypot(x_mm, y_mm)
        if dist_mm < 1.0:
            return None
        ux, uy = x_mm / dist_mm, y_mm / dist_mm

        def reaches(r_mm: float) -> bool:
            return next(self._reaching(ux * r_mm, uy * r_mm, yaw_deg), None) is not None

        lo_mm = self.kin.max_reach_mm  # inwards to a grasp that reaches, then halve the gap
        while lo_mm > 0.0 and not reaches(lo_mm):
            lo_mm -= 10.0
        if lo_mm <= 0.0:
            return None
        hi_mm = lo_mm + 10.0
        while hi_mm - lo_mm > 1.0:
            mid_mm = (lo_mm + hi_mm) / 2
            lo_mm, hi_mm = (mid_mm, hi_mm) if reaches(mid_mm) else (lo_mm, mid_mm)
        return lo_mm

    def _reaching(self, x_mm: float, y_mm: float, yaw_deg: float) -> Iterator[GraspPlan]:
        """Every grasp that reaches, best first: straight down (both face pairs), then
        tilted."""
        z0, zg = self.table_z_mm, self.grasp_z_mm
        grasp, lift = (x_mm, y_mm, zg), (x_mm, y_mm, z0 + self.carry_mm)
        try:
            squared = self.roll_squared_deg(x_mm, y_mm, yaw_deg)
        except UnreachableError:
            squared = None
        if squared is not None:
            for roll in (squared, squared + 90.0, squared - 90.0):
                plan = GraspPlan(-90.0, roll, (x_mm, y_mm, z0 + self.approach_mm), grasp, lift)
                try:
                    self._check_plan(plan)
                except UnreachableError:
                    continue
                yield plan
        for pitch in TILTED_PITCHES_DEG:
            for roll, turn, m in self._level_rolls(x_mm, y_mm, yaw_deg, pitch):
                if turn > MAX_TILTED_TURN_DEG:
                    continue
                back = m[:3, 2] * self.approach_mm  # back along the tool's axis
                above = (x_mm - back[0], y_mm - back[1], zg - back[2])
                plan = GraspPlan(pitch, roll, above, grasp, lift)
                try:
                    self._check_plan(plan)
                except UnreachableError:
                    continue
                yield plan

    def pads(self, plan: GraspPlan, gap_mm: float, *, tall: bool = False) -> list[Footprint]:
        """What the two finger pads cover on the table on their way down to ``plan``'s
        grasp, opened ``gap_mm`` apart, while they are low enough to meet a block (or,
        ``tall``, anything: all the way from ``above``)."""
        return [Footprint.hull(p[:, :2]) for p in self._pad_sweeps(plan, gap_mm, tall, 2)]

    def _pad_sweeps(self, plan: GraspPlan, gap_mm: float, tall: bool, samples: int
                    ) -> list[FloatArray]:
        """Points (N x 3, mm) of each pad's volume swept on its way down (see ``pads``):
        ``samples`` a side along its thickness and width, and about as densely along
        its length and its slide."""
        t, w, length = self.pad_mm
        kin = self.kin
        m = kin.fk_matrix(kin.ik_best(*plan.grasp, plan.pitch_deg, plan.roll_deg))
        x_axis, y_axis, back = m[:3, 0], m[:3, 1], -m[:3, 2]
        tip = np.asarray(plan.grasp, dtype=float)
        top = math.inf if tall else self.table_z_mm + self.block_mm + self.margin_mm
        low = top - tip[2]  # how far above the tips a thing reaches
        rise = float(back[2])
        # Only the part of a pad below a neighbour's top can meet it; while descending the
        # pads slide along the tool's axis (straight down: they stay where they are).
        reach = min(length, low / rise) if rise > 1e-6 else length
        slide = min(self.approach_mm, low / rise) if rise > 1e-6 else self.approach_mm
        step = max(w / max(samples - 1, 1), 1e-6)
        a, b = np.linspace(-t / 2, t / 2, samples), np.linspace(-w / 2, w / 2, samples)
        c = np.linspace(0.0, reach, max(2, math.ceil(reach / step) + 1))
        d = np.linspace(0.0, slide, max(2, math.ceil(slide / step) + 1))
        grid = np.stack(np.meshgrid(a, b, c, d, indexing="ij"), axis=-1).reshape(-1, 4)
        across: FloatArray = np.outer(grid[:, 0], y_axis)
        along: FloatArray = np.outer(grid[:, 1], x_axis)
        offsets: FloatArray = across + along + np.outer(grid[:, 2] + grid[:, 3], back)
        half: FloatArray = (gap_mm / 2 + t / 2) * y_axis
        return [tip + side * half + offsets for side in (-1.0, 1.0)]

    def _first_hit(self, plan: GraspPlan, gap_mm: float, neighbours: Sequence[Footprint]
                   ) -> tuple[float, float, str] | None:
        """The centre of the first neighbour a pad would meet, and "block", or None."""
        for pad in self.pads(plan, gap_mm) if neighbours else ():
            for other in neighbours:
                if pad.overlaps(other, self.margin_mm):
                    centre = other.corners.mean(axis=0)
                    return float(centre[0]), float(centre[1]), "block"
        return None

    def _first_thing(self, plan: GraspPlan, gap_mm: float, things: Sequence[Thing]
                     ) -> tuple[float, float, str] | None:
        """The centre of the first thing (not a block) that may be in a pad's way all the
        way down from ``above``, and "thing", or None: a pad's sweep over what the thing
        stands on is checked point by point against where the thing may be."""
        if not things:
            return None
        sweeps: list[FloatArray] | None = None
        for pad, index in zip(self.pads(plan, gap_mm, tall=True), (0, 1), strict=True):
            for thing in things:
                if not pad.overlaps(Footprint(thing.corners), self.margin_mm):
                    continue
                sweeps = sweeps or self._pad_sweeps(plan, gap_mm, True, SWEEP_SAMPLES)
                if thing.reaches(sweeps[index], self.margin_mm):
                    x, y = thing.centre_mm
                    return x, y, "thing"
        return None

    def _why_unreachable(self, x_mm: float, y_mm: float, yaw_deg: float) -> str:
        """Why no grasp reaches the block (straight down, and tilted)."""
        z0, zg = self.table_z_mm, self.grasp_z_mm
        grasp = (x_mm, y_mm, zg)
        lift = (x_mm, y_mm, z0 + self.carry_mm)
        try:
            roll = self.roll_squared_deg(x_mm, y_mm, yaw_deg)
            self._check_plan(GraspPlan(-90.0, roll, (x_mm, y_mm, z0 + self.approach_mm),
                                       grasp, lift))
            top_down_failure = "reaches"  # not expected: plan() found it reaching
        except UnreachableError as exc:
            top_down_failure = str(exc)
        turned = ""
        for pitch in TILTED_PITCHES_DEG:
            level = next(iter(self._level_rolls(x_mm, y_mm, yaw_deg, pitch)), None)
            if level is not None and level[1] > MAX_TILTED_TURN_DEG:
                turned = (f"; tilted, the fingers would meet it {level[1]:.0f} deg off "
                          f"square (at most {MAX_TILTED_TURN_DEG:g})")
        return f"no grasp reaches it: straight down {top_down_failure}{turned or '; nor tilted'}"

    def _level_rolls(self, x_mm: float, y_mm: float, yaw_deg: float, pitch_deg: float
                     ) -> list[tuple[float, float, FloatArray]]:
        """At a tilted pitch, for each of the block's two face pairs: the roll whose pads
        lie flattest on its faces (the least angle between the closing axis and the
        faces' normal: off square about the vertical and tilted from level, at most
        ``MAX_CLOSING_TILT_DEG``), as (roll, degrees still off square, the tool's pose),
        flattest first; empty if the pitch does not reach. (Pads tilted from the faces
        take the block by two edges, and lean in over its top edge on the way down.)"""
        kin = self.kin
        reached: list[tuple[float, Joints]] = []
        for roll in np.arange(-90.0, 90.5, ROLL_STEP_DEG).tolist():
            with contextlib.suppress(UnreachableError):
                reached.append((roll, kin.ik_best(x_mm, y_mm, self.grasp_z_mm, pitch_deg, roll)))
        if not reached:
            return []
        # The tool's poses in one batch.
        poses = kin.fk_matrix_batch(np.asarray([j for _, j in reached]))
        best: dict[int, tuple[float, float, float, FloatArray]] = {}
        for k, (roll, _) in enumerate(reached):
            m: FloatArray = poses[k]
            tilt = _closing_tilt_rad(m)
            if math.degrees(tilt) > MAX_CLOSING_TILT_DEG:
                continue
            off = (_finger_axis_deg(m) - yaw_deg + 45.0) % 180.0 - 45.0  # -45..135
            pair, turn = (0, abs(off)) if off < 45.0 else (1, abs(off - 90.0))
            flat = math.acos(math.cos(tilt) * math.cos(math.radians(turn)))
            if pair not in best or flat < best[pair][0] - 1e-9:
                best[pair] = (flat, float(roll), turn, m.copy())
        return [(roll, turn, m) for _, roll, turn, m in sorted(best.values(),
                                                               key=lambda r: r[0])]

    def _check_plan(self, plan: GraspPlan) -> None:
        """Every point of the plan's straight moves within reach (UnreachableError)."""
        self.check_path([plan.above, plan.grasp, plan.lift], plan.pitch_deg, plan.roll_deg)

    def check_path(self, points: Sequence[tuple[float, float, float]], pitch_deg: float,
                   roll_deg: float, margin_deg: float = 0.0) -> None:
        """Every point of the straight moves through ``points`` (mm) within reach at this
        tool pitch and roll, each joint ``margin_deg`` inside its limits; UnreachableError
        if not."""
        for a, b in itertools.pairwise(points):
            steps = math.ceil(math.dist(a, b) / LINE_CHECK_MM)
            for t in np.linspace(0.0, 1.0, steps + 1):
                x, y, z = (p + (q - p) * t for p, q in zip(a, b, strict=True))
                joints = self.kin.ik_best(x, y, z, pitch_deg, roll_deg)
                for name, q, (lo, hi) in zip(self.kin.joint_names, joints,
                                             self.kin.limits_deg, strict=True):
                    if not lo + margin_deg <= q <= hi - margin_deg:
                        raise UnreachableError(
                            f"({x:.1f}, {y:.1f}, {z:.1f}) mm needs {name} = {q:.1f} deg, "
                            f"within {margin_deg:g} deg of its limits {lo:g}..{hi:g} deg")


def _closing_tilt_rad(tool: FloatArray) -> float:
    """How far from level the fingers close (the tool's y against the table)."""
    return math.asin(min(1.0, abs(float(tool[2, 1]))))


def _finger_axis_deg(tool: FloatArray) -> float:
    """The direction (deg, base frame) the fingers close along: the tool's y seen from above."""
    return math.degrees(math.atan2(tool[1, 1], tool[0, 1]))
