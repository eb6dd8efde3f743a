"""Pick-and-sort: look at the table, pick each coloured block, put it in its colour's bin.

One cycle per block, the same code on the twin and on hardware:

1. survey: the camera looks from one or more survey poses; blocks are located in mm
   (``BlockLocator``, averaged over frames) and merged across poses;
2. choose: reachable blocks of a colour that has a bin, nearest to the base first (or by
   colour); unknown colours and blocks out of reach are skipped with the reason; a block
   seen far off to the side or cut by the picture's edge is looked at again, facing it;
3. grasp (``GraspPlanner``): above the block at ``approach_mm``, the wrist roll squared
   to its faces, a straight descent to the grasp height, close, and the gripper's
   position says whether it holds something (no holding, no carrying: the block is
   looked for again). Where straight down does not reach (far out, or close to the
   base), the tool leans out or back and closes near level, along its own axis;
4. carry: straight up, over the bin at ``carry_mm``, check the block is still held,
   down, open, up;
5. verify: the next survey must not see the block where it was picked; at the end each
   bin is looked into.

Any exception or Ctrl+C stops the arm where it is, holding; ``PickSorter.report`` keeps
what was done, why it stopped and what the gripper holds, as read back.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from busarm.apps.footprint import Footprint
from busarm.apps.grasp import GraspPlan, GraspPlanner, NoClearGrasp
from busarm.apps.push import Push, PushPlanner
from busarm.errors import (
    BusArmError,
    ConfigError,
    ContactError,
    MotionTimeoutError,
    ServoFaultError,
    UnreachableError,
)
from busarm.robot import Robot
from busarm.robot.locate import Sighting
from busarm.robot.obstacles import Obstacle, refine
from busarm.units import check_int_range, check_range

FloatArray = npt.NDArray[np.float64]

SAME_BLOCK_MM = 20.0
"""Two sightings this close are the same block."""
BIN_RADIUS_MM = 45.0
"""A block seen this close to a bin's centre is in or at that bin: not to be picked."""
IN_BIN_MM = 35.0
"""A block whose centre is this close to its bin's centre is sorted: inside a 90 mm tray
(a cube squared to the walls fits with its centre up to 28 mm off along each axis; the
slots are 28 mm from the centre)."""
BIN_SLOTS_MM = ((-20.0, -20.0), (20.0, -20.0), (-20.0, 20.0), (20.0, 20.0))
"""Where blocks go in a bin (from its centre): 2 x 2, 10 mm apart (the camera sees them
apart when it checks the bin)."""
BIN_PLACES = (*((slot, 0) for slot in range(4)), (0, 1), (1, 1), (2, 1))
"""The places a bin takes, in order: (slot, layer). The second layer stands square on the
first, three blocks: a fourth would have a neighbour on both sides of both finger axes
(a 10 mm gap takes no finger pad), and a third layer would stand above the tray's walls
and the camera's view of it."""
STACK_DROP_MM = 3.0
"""A block for the second layer is let go this far above the first layer's tops."""
ORDERS = ("nearest", "colors")
OVER_THINGS_MM = 100.0
"""A carried block's bottom passes this high over things that are not blocks (a mug is
about 95 mm tall)."""
CARRY_CLEARANCE_MM = 25.0
"""A carry passing this close to such a thing goes over it."""
MAX_CYCLES = 150
"""Surveys a run makes at most (a cycle picks a block, or pushes one, or looks closer)."""
MAX_EXTRA_LOOKS = 3
"""A survey looks this many more times at most, facing blocks cut by its pictures' edges."""
HOLD_SLACK_MM = 4.0
"""A gripper this little wider than a block, squeezing one, holds it (pads give a little)."""


@dataclass(frozen=True)
class PickSortSettings:
    """Heights in mm above the table, speeds, and how hard to try."""

    approach_mm: float = 60.0
    carry_mm: float = 75.0
    release_mm: float = 45.0
    finger_clearance_mm: float = 10.0
    """Opening beyond the block on each side when grasping (its yaw is known to a few deg)."""
    min_finger_clearance_mm: float = 3.0
    """Between close neighbours the fingers open down to this beyond the block a side."""
    max_nudges: int = 2
    """Pushes a boxed-in block gets before it is skipped."""
    line_speed_mm_s: float = 200.0
    joint_speed_deg_s: float = 180.0
    max_attempts: int = 2
    survey_frames: int = 2
    order: str = "nearest"
    """Which block next: ``nearest`` to the base, or ``colors``: by colour in the bins'
    order, nearest first within a colour."""
    look_closer_beyond_deg: float = 20.0
    """A block seen further than this (bearing) from where the camera looked is looked at
    again, the camera turned to face it, before the grasp (the picture's edges are where
    the lens distorts most and a block is seen most from the side)."""
    settle_s: float = 0.2
    pause_above_c: float = 70.0
    """A servo this hot pauses the run (arm at home, gripper open) ..."""
    resume_below_c: float = 60.0
    """... until every servo is this cool again (LX servos cut out at 85 C by default)."""
    min_supply_v: float = 6.8
    """A supply this low stops the run cleanly (LX servos go silent near 6 V)."""
    max_pause_s: float = 600.0

    def __post_init__(self) -> None:
        if self.order not in ORDERS:
            raise ConfigError(f"order = {self.order!r}; allowed: {', '.join(ORDERS)}")
        if not self.resume_below_c < self.pause_above_c:
            raise ConfigError(f"resume_below_c {self.resume_below_c:g} must be below "
                              f"pause_above_c {self.pause_above_c:g}")
        for name, lo, hi in (("approach_mm", 20.0, 200.0), ("carry_mm", 30.0, 250.0),
                             ("finger_clearance_mm", 2.0, 40.0),
                             ("min_finger_clearance_mm", 1.0, 40.0),
                             ("pause_above_c", 40.0, 84.0),
                             ("resume_below_c", 30.0, 83.0), ("min_supply_v", 4.5, 12.0),
                             ("max_pause_s", 0.0, 3600.0),
                             ("release_mm", 20.0, 200.0), ("line_speed_mm_s", 10.0, 400.0),
                             ("look_closer_beyond_deg", 0.0, 180.0),
                             ("joint_speed_deg_s", 10.0, 180.0), ("settle_s", 0.0, 5.0)):
            check_range(name, getattr(self, name), lo, hi)
        for name, ilo, ihi in (("max_attempts", 1, 10), ("survey_frames", 1, 20),
                               ("max_nudges", 0, 10)):
            check_int_range(name, getattr(self, name), ilo, ihi)


@dataclass
class BlockOutcome:
    """What happened to one block."""

    color: str
    found_mm: tuple[float, float]
    outcome: str = "pending"
    """``sorted``, ``failed``, ``skipped`` or ``moved`` (gone from where it was seen after
    a missed grasp; if it is seen elsewhere, it has a record of its own there)."""
    reason: str = ""
    placed_mm: tuple[float, float] | None = None
    attempts: int = 0
    seconds: float = 0.0
    grasp_pitch_deg: float | None = None
    """The tool's pitch at the last grasp: -90 straight down, else tilted."""

    def to_dict(self) -> dict[str, object]:
        return {"color": self.color, "found_mm": [round(v, 1) for v in self.found_mm],
                "outcome": self.outcome, "reason": self.reason,
                "placed_mm": None if self.placed_mm is None else
                [round(v, 1) for v in self.placed_mm],
                "attempts": self.attempts, "seconds": round(self.seconds, 2),
                "grasp_pitch_deg": self.grasp_pitch_deg}


@dataclass
class RunReport:
    blocks: list[BlockOutcome] = field(default_factory=list)
    seconds: float = 0.0
    stopped: str = ""
    """Why the run stopped before the table was clear (empty if it did not)."""
    gripper: str = ""
    """The gripper's state when it stopped that way, as read back."""

    def totals(self) -> dict[str, object]:
        done = [b for b in self.blocks if b.outcome == "sorted"]
        cycle = float(np.median([b.seconds for b in done])) if done else math.nan
        return {"sorted": len(done),
                "failed": sum(b.outcome == "failed" for b in self.blocks),
                "skipped": sum(b.outcome == "skipped" for b in self.blocks),
                "moved": sum(b.outcome == "moved" for b in self.blocks),
                "median_cycle_s": round(cycle, 2), "seconds": round(self.seconds, 1)}


class PickSorter:
    """Sorts the blocks of ``colors`` the robot's wrist camera sees into their bins (the
    robot's, or ``bins``: colour -> (x, y) mm); a colour with no bin is left alone."""

    def __init__(self, robot: Robot, *, colors: Sequence[str] | None = None,
                 bins: dict[str, tuple[float, float]] | None = None,
                 survey_poses: Sequence[Sequence[float]] | None = None,
                 settings: PickSortSettings | None = None,
                 progress: Callable[[str], None] | None = None,
                 on_step: Callable[[str], None] | None = None,
                 on_pick: Callable[[Sighting], None] | None = None) -> None:
        arm = self.arm = robot.arm
        self.camera = robot.camera
        locator = self.locator = robot.locator(colors)
        where = robot.bins if bins is None else bins
        self.bins = {c: where[c] for c in locator.detector.colors if c in where}
        if not self.bins:
            raise ConfigError(f"no bin for any colour to sort ({', '.join(where) or 'none'} "
                              f"given): give --bins COLOUR=X,Y;...")
        self.settings = settings or PickSortSettings()
        poses = survey_poses if survey_poses is not None else [arm.config.pose("look")]
        self.survey_poses = [arm.config.check_joints(p) for p in poses]
        if not self.survey_poses:
            raise ConfigError("give at least one survey pose")
        self.progress = progress or (lambda _: None)
        # Called after each step of a cycle with its name (to take pictures, say).
        self.on_step = on_step or (lambda _: None)
        # Called with each block about to be picked (its survey is ``last_survey``).
        self.on_pick = on_pick or (lambda _: None)
        # Every wait and cycle time is on the arm's clock (a twin's simulated seconds).
        self.clock = arm.clock
        # The last survey's pictures and what was found in each (for reports).
        self.last_survey: list[tuple[npt.NDArray[np.uint8], list[Sighting]]] = []
        self.planner = GraspPlanner(arm.kin, locator.table_z_mm, locator.block_size_mm,
                                    self.settings.approach_mm, self.settings.carry_mm,
                                    pad_mm=arm.config.gripper.pad_mm)
        self.pusher = PushPlanner(self.planner, [Footprint.square(x, y, 2 * BIN_RADIUS_MM, 0.0)
                                                 for x, y in self.bins.values()])
        # Every block the last survey saw: the neighbours a grasp must keep clear of.
        self._seen: list[Sighting] = []
        # Things seen since the last survey began that are not blocks (cast on the table).
        self._obstacles: list[Footprint] = []
        self._things: list[Obstacle] = []  # the same, as seen (refined by each look)
        self._nudges: dict[int, int] = {}  # pushes per block record
        # Records seen boxed in when looked at closer, and how (until the table changes).
        self._boxed: dict[int, Sighting] = {}
        # Records of blocks pushed out of a group: (record, from, towards), until seen.
        self._pushed: dict[int, tuple[BlockOutcome, tuple[float, float],
                                      tuple[float, float]]] = {}
        self._placed: dict[str, int] = {}
        # Where the survey saw a block that was found elsewhere when looked at closer.
        self._aliases: dict[int, list[tuple[float, float]]] = {}
        # The colour of the block in the fingers, from a good grip to its release.
        self._holding: str | None = None
        self.report = RunReport()
        """The run's report as it goes (what was done so far, if it stops early)."""

    # ------------------------------------------------------------------ seeing

    def survey(self) -> list[Sighting]:
        """Every block seen from the survey poses, merged (averaged per pose), then from
        poses turned to face what was cut by a picture's edge (the table may reach beyond
        the survey's pictures). A block seen from several poses keeps its best sighting:
        whole rather than cut, then the one nearest the middle of its picture (in
        bearing)."""
        seen: list[tuple[tuple[bool, float], Sighting]] = []
        self.last_survey = []
        self._obstacles, self._things = [], []
        looked: list[float] = []
        for pose in self.survey_poses:
            self._merge(seen, pose)
            looked.append(pose[0])
        for _ in range(MAX_EXTRA_LOOKS):
            cut = [v for _, v in seen if not v.whole and all(
                abs(_bearing_deg(v) - b) > self.settings.look_closer_beyond_deg
                for b in looked)]
            if not cut:
                break
            bearing = _bearing_deg(cut[0])
            looked.append(bearing)
            try:
                pose = self.arm.config.check_joints((bearing, *self.survey_poses[0][1:]))
            except ConfigError:  # the base cannot turn that far
                continue
            self._merge(seen, pose)
        self.on_step("survey")
        return [sighting for _, sighting in seen]

    def _merge(self, seen: list[tuple[tuple[bool, float], Sighting]],
               pose: Sequence[float]) -> None:
        """Look from ``pose`` and merge what is found into ``seen`` (see ``survey``)."""
        image, found = self._look(pose)
        self.last_survey.append((image, found))
        for new in found:
            rank = (not new.whole, abs(_bearing_deg(new) - pose[0]))
            # A cut blob's location is rough: it may lie further from the whole one.
            radius = SAME_BLOCK_MM if new.whole else 2 * SAME_BLOCK_MM
            for i, (old_rank, old) in enumerate(seen):
                if _same_block(old.color, old.location.x_mm, old.location.y_mm, new,
                               radius if old.whole else 2 * SAME_BLOCK_MM):
                    if rank < old_rank:
                        seen[i] = (rank, new)
                    break
            else:
                seen.append((rank, new))

    def _look(self, pose: Sequence[float]) -> tuple[npt.NDArray[np.uint8], list[Sighting]]:
        """The blocks seen from ``pose`` (frames averaged), and the last picture."""
        s, arm = self.settings, self.arm
        arm.move_joints(pose, speed_deg_s=s.joint_speed_deg_s)
        self.clock.sleep(s.settle_s)
        pictures = [(self.camera.read().image, arm.read_joints_deg())
                    for _ in range(s.survey_frames)]
        # Things that are not blocks, for the fingers and pushes to keep off.
        self._things = refine(self._things, self.locator.obstacles(
            *pictures[-1], [(x, y, 2 * BIN_RADIUS_MM) for x, y in self.bins.values()]))
        self._obstacles = [Footprint(o.corners) for o in self._things]
        return pictures[-1][0], self.locator.locate_averaged(pictures)

    def look_closer(self, target: Sighting, *, always: bool = False) -> Sighting | None:
        """The block as seen with the camera turned to face it, if the survey saw it more
        than ``look_closer_beyond_deg`` off to the side or cut by the picture's edge (or
        ``always``); else ``target`` itself. None if it is not seen whole there when
        looked at again."""
        s, arm = self.settings, self.arm
        x, y = target.location.x_mm, target.location.y_mm
        bearing = _bearing_deg(target)
        pose = min(self.survey_poses, key=lambda p: abs(bearing - p[0]))
        if target.whole and abs(bearing - pose[0]) <= s.look_closer_beyond_deg and not always:
            return target
        try:
            facing = arm.config.check_joints((bearing, *pose[1:]))
        except ConfigError:  # the base cannot turn that far: the survey's sighting it is
            return target if target.whole else None
        image, found = self._look(facing)
        self.last_survey = [(image, found)]
        self.on_step("closer")
        # The neighbours a grasp keeps clear of, as seen from here where seen whole.
        self._seen = [v for v in found if v.whole] + [
            old for old in self._seen if not any(
                v.whole and _same_block(old.color, old.location.x_mm, old.location.y_mm, v,
                                        (1 if old.whole else 3) * SAME_BLOCK_MM)
                for v in found)]

        # Cut by the picture's edge, it was seen only in part (or a group of touching
        # blocks was): the nearest whole block of its colour about there is the one.
        radius = (2 if target.whole else 3) * SAME_BLOCK_MM
        same = sorted((v for v in found if v.whole and not self._in_a_bin(v)
                       and _same_block(target.color, x, y, v, radius)),
                      key=lambda v: _off_mm(v, x, y))
        return same[0] if same else None

    # ------------------------------------------------------------------ moving

    def _still_holding(self) -> bool:
        """Whether the gripper still stands short of closed (a dropped block lets it close)."""
        g = self.arm.config.gripper
        return abs(self.arm.read_gripper_pulses() - g.closed_pulses) > g.holding_margin_pulses

    def check_servos(self) -> None:
        """Pause while a servo is too hot (arm at home, gripper open); a supply too low for
        the servos stops the run with ServoFaultError."""
        s, arm = self.settings, self.arm
        deadline = self.clock.now() + s.max_pause_s
        paused = False
        while True:
            states = arm.bus.read_states(arm.config.servo_ids)
            low = [st for st in states if st.vin_v < s.min_supply_v]
            if low:
                raise ServoFaultError(
                    f"servo {low[0].servo_id} reads {low[0].vin_v:.2f} V, below "
                    f"{s.min_supply_v:g} V: charge or change the battery", low[0].servo_id)
            hot = max(states, key=lambda st: st.temp_c)
            limit = s.resume_below_c if paused else s.pause_above_c
            if hot.temp_c < limit:
                if paused:
                    self.progress(f"servos cool again ({hot.temp_c} C): going on")
                return
            if not paused:
                self.progress(f"servo {hot.servo_id} at {hot.temp_c} C: pausing until every "
                              f"servo is below {s.resume_below_c:g} C")
                arm.open_gripper()
                arm.move_joints(arm.config.pose("home"), speed_deg_s=s.joint_speed_deg_s)
                paused = True
            if self.clock.now() > deadline:
                raise ServoFaultError(f"servo {hot.servo_id} still at {hot.temp_c} C after "
                                      f"{s.max_pause_s:g} s of rest", hot.servo_id)
            self.clock.sleep(2.0)

    def _bin_spot(self, color: str) -> tuple[float, float, int, float]:
        """Where in the bin the next block of ``color`` goes (``BIN_PLACES``): x, y, its
        layer (0, 1), and the wrist roll that squares it to the bin's walls with the
        fingers clear of the blocks already beside it in that layer."""
        bx, by = self.bins[color]
        k = self._placed.get(color, 0)
        if k >= self.bin_capacity:
            raise ConfigError(f"the {color} bin is full ({self.bin_capacity} blocks)")
        self._placed[color] = k + 1
        slot, layer = BIN_PLACES[k]
        dx, dy = BIN_SLOTS_MM[slot]
        beside = [BIN_SLOTS_MM[other] for other, lay in BIN_PLACES[:k] if lay == layer]
        square = self.planner.roll_squared_deg(bx + dx, by + dy, 0.0)

        def along_neighbours(roll: float) -> float:
            """How much the fingers would close towards a block beside (0: across)."""
            axis = math.radians(self.planner.finger_axis_deg(bx + dx, by + dy, roll))
            return max((abs(math.cos(axis) * (ox - dx) + math.sin(axis) * (oy - dy))
                        / math.hypot(ox - dx, oy - dy) for ox, oy in beside), default=0.0)

        rolls = []
        for roll in (square, square + 90.0, square - 90.0):
            try:
                rolls.append((round(along_neighbours(roll), 3), abs(roll), roll))
            except UnreachableError:
                continue
        roll = min(rolls)[2] if rolls else square
        return bx + dx, by + dy, layer, roll

    @property
    def bin_capacity(self) -> int:
        """How many blocks a bin takes (``BIN_PLACES``)."""
        return len(BIN_PLACES)

    def _retreat(self) -> None:
        """After a move that met something: stop and hold, then go straight up from
        where the arm stopped (the next survey moves on from there)."""
        self.arm.stop()
        self._rise()

    def _rise(self) -> None:
        """Straight up from where the tool is to above the tallest block carried, so that
        the next joint move sweeps over what stands on the table."""
        arm, s = self.arm, self.settings
        tool = arm.read_pose()
        up = self.locator.table_z_mm + s.carry_mm + self.locator.block_size_mm
        if tool.z_mm < up:
            try:
                arm.move_line(tool.x_mm, tool.y_mm, up, tool.pitch_deg, tool.roll_deg,
                              speed_mm_s=s.line_speed_mm_s / 2)
            except UnreachableError:  # not straight up from here: nearly, joint by joint
                arm.move_to(tool.x_mm, tool.y_mm, up, tool.pitch_deg, tool.roll_deg,
                            speed_deg_s=s.joint_speed_deg_s / 2)

    def nudge(self, target: Sighting) -> Push | None:
        """Drag a boxed-in block out of its group (``PushPlanner``): the closed fingers
        pressed on its top, moved along the push, lifted again; the push, or None (nothing
        moved) if the arm cannot push it anywhere."""
        arm, s = self.arm, self.settings
        loc = target.location
        push = self.pusher.plan(loc.x_mm, loc.y_mm, loc.yaw_deg, self._neighbours(target),
                                self._gaps(), self._obstacles)
        if push is None:
            return None
        how = "" if push.frees else " (a grasp may not clear it even there)"
        self.progress(f"{target.color} at {_mm(push.start)} is boxed in: pushing it "
                      f"to {_mm(push.end)}{how}")
        above, on_top, pushed, lifted = push.path
        pitch, roll = push.pitch_deg, push.roll_deg
        arm.grip()  # closed: the pads side by side press on the block's top
        try:
            arm.move_to(*above, pitch, roll, speed_deg_s=s.joint_speed_deg_s)
            # Pressing on the block, the fingers never get quite where they are sent:
            # these two moves (streamed in their time) are not waited for to arrive, only
            # to settle.
            for point in (on_top, pushed):
                arm.move_line(*point, pitch, roll, speed_mm_s=s.line_speed_mm_s / 4,
                              wait=False)
                self.clock.sleep(s.settle_s)
            arm.move_line(*lifted, pitch, roll, speed_mm_s=s.line_speed_mm_s)
        except (MotionTimeoutError, UnreachableError) as exc:  # met something, or the
            # fingers held back by the block left the line's reach: up, and look again
            self.progress(f"the push stopped short ({exc}): backing off")
            self._retreat()
        if self._obstacles:  # the way back to the survey could sweep into one
            self._rise()
        self.on_step("nudge")
        return push

    def pick_and_place(self, target: Sighting
                       ) -> tuple[bool, str, tuple[float, float] | None, GraspPlan]:
        """One grasp-carry-release cycle; (holding was seen, why not, where it was put, the
        grasp plan)."""
        arm, s = self.arm, self.settings
        z0 = self.locator.table_z_mm
        plan = self._plan(target)
        pitch, roll = plan.pitch_deg, plan.roll_deg
        # Open no wider than the neighbours allow (the plan chose it).
        gap = plan.gap_mm
        arm.open_gripper(wait=False, gap_mm=gap)
        try:
            arm.move_to(*plan.above, pitch, roll, speed_deg_s=s.joint_speed_deg_s)
        except MotionTimeoutError as exc:  # the arm met something on its way: an event
            self._retreat()
            return False, f"blocked on the way to it ({exc}): backed off", None, plan
        arm.open_gripper(gap_mm=gap)
        self.on_step("above")
        try:  # watched: fingers landing on something stop, back off, and try again later
            arm.move_line_guarded(*plan.grasp, pitch, roll, speed_mm_s=s.line_speed_mm_s)
        except ContactError as exc:
            if not exc.backed_off:
                raise  # stopped and holding where it touched: not for a retry
            arm.open_gripper(wait=False, gap_mm=gap)
            x, y, z = exc.tool_mm
            return (False, f"blocked on the way down at ({x:.0f}, {y:.0f}, {z:.0f}) mm "
                           f"({exc.joint} stopped short): backed off", None, plan)
        self._holding = target.color  # from the squeeze on: the reading says if it holds
        grip = arm.grip()
        self.on_step("grip")
        if not grip.is_holding:
            self._holding = None
            arm.open_gripper(wait=False, gap_mm=gap)
            arm.move_line(*plan.above, pitch, roll, speed_mm_s=s.line_speed_mm_s)
            return (False, f"the gripper closed on nothing ({grip.position_pulses} pulses)",
                    None, plan)
        arm.move_line(*plan.lift, pitch, roll, speed_mm_s=s.line_speed_mm_s)
        self.on_step("lift")
        bx, by, layer, square = self._bin_spot(target.color)
        # A second layer: carried higher over the first, set down just above it (a drop
        # from the first layer's height would bounce it off).
        size = self.locator.block_size_mm
        carry_z = z0 + s.carry_mm + layer * size
        release_z = z0 + (s.release_mm if layer == 0 else size + STACK_DROP_MM + size / 2)
        if self._thing_on_the_way(plan.lift[:2], (bx, by)):
            # Something that is not a block (of a height not known) near the way: over it
            # at the height of the tallest cup a desk has.
            carry_z = max(carry_z, z0 + OVER_THINGS_MM + size / 2)
            # (Not straight up from here: it rises on the way over.)
            with contextlib.suppress(UnreachableError):
                arm.move_line(*plan.lift[:2], carry_z, pitch, roll,
                              speed_mm_s=s.line_speed_mm_s)
        arm.move_to(bx, by, carry_z, -90.0, square, speed_deg_s=s.joint_speed_deg_s)
        self.on_step("carry")
        if not self._still_holding():
            self._holding = None
            arm.open_gripper(wait=False, gap_mm=gap)
            self._placed[target.color] -= 1
            return False, "the block slipped out during the carry", None, plan
        try:
            arm.move_line(bx, by, release_z, -90.0, square, speed_mm_s=s.line_speed_mm_s)
        except MotionTimeoutError:  # it rests on something in the bin: let go there
            arm.stop()
        self._holding = None  # from the release on (an open gripper reads as open)
        arm.open_gripper(gap_mm=gap)
        self.on_step("release")
        arm.move_line(bx, by, carry_z, -90.0, square, speed_mm_s=s.line_speed_mm_s)
        return True, "", (bx, by), plan

    def _thing_on_the_way(self, start: Sequence[float], end: Sequence[float]) -> bool:
        """Whether a thing that is not a block lies near the carry from ``start`` to
        ``end`` (x, y mm): the way taken as the base turns, bearing and radius changing
        evenly."""
        if not self._obstacles:
            return False
        (r0, a0), (r1, a1) = ((math.hypot(x, y), math.atan2(y, x)) for x, y in (start, end))
        turn = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
        size = self.locator.block_size_mm
        for t in np.linspace(0.0, 1.0, 40):
            r, a = r0 + (r1 - r0) * t, a0 + turn * t
            here = Footprint.square(r * math.cos(a), r * math.sin(a), size, 0.0)
            if any(here.overlaps(o, CARRY_CLEARANCE_MM) for o in self._obstacles):
                return True
        return False

    def verify_bins(self, report: RunReport) -> None:
        """Look into each bin a block was put in: a block reported sorted but not found
        there (it bounced out, say) is reported failed instead."""
        arm = self.arm
        look = arm.config.pose("look")
        for color, (bx, by) in self.bins.items():
            sorted_here = [b for b in report.blocks if b.color == color and b.outcome == "sorted"]
            if not sorted_here:
                continue
            bearing = math.degrees(math.atan2(by, bx))
            pose = (bearing, *look[1:])
            try:
                arm.config.check_joints(pose)
            except ConfigError:
                continue  # no look at it from here: the release is trusted
            _, found = self._look(pose)
            inside = [v for v in found if v.color == color
                      and math.hypot(v.location.x_mm - bx, v.location.y_mm - by) < IN_BIN_MM]
            # A block of the second layer hides the one it stands on: the camera sees one
            # block a place at most.
            seen = len(inside) + max(0, len(sorted_here) - len(BIN_SLOTS_MM))
            for missing in sorted_here[seen:]:
                missing.outcome = "failed"
                missing.reason = "not in its bin when the bins were checked (it fell out?)"
                self.progress(f"{color} block from {_mm(missing.found_mm)}: not in its bin")

    # ------------------------------------------------------------------ the job

    def run(self, *, max_cycles: int = MAX_CYCLES) -> RunReport:
        """Sort until the table shows no block that can be sorted (or ``max_cycles``
        surveys have been made); the whole report.

        On an error or Ctrl+C the arm is stopped where it is, holding, ``self.report``
        says why and what the gripper reads, and the exception goes on up.
        """
        start = self.clock.now()
        self.report = report = RunReport()
        self._holding = None
        try:
            why = f"not done when the run's {max_cycles} cycles were up"
            for _ in range(max_cycles):
                if not self._cycle(report):
                    why = "not seen again"
                    break
            for outcome in report.blocks:
                if outcome.outcome == "pending":
                    outcome.outcome, outcome.reason = "failed", why
            self.verify_bins(report)
        except BaseException as exc:
            report.stopped = ("interrupted (Ctrl+C)" if isinstance(exc, KeyboardInterrupt)
                              else f"{type(exc).__name__}: {exc}")
            report.gripper = self._stop_and_read_gripper()
            raise
        finally:
            report.seconds = self.clock.now() - start
        return report

    def _cycle(self, report: RunReport) -> bool:
        """Survey, then pick and place the next block; False if there is none to pick."""
        seen = self._seen = self.survey()
        for outcome in report.blocks:
            # Missed, and no longer where it was: someone moved it. It is looked for
            # afresh (a new record if it is seen elsewhere).
            if outcome.outcome == "pending" and outcome.attempts and not any(
                    _same_block(outcome.color, *outcome.found_mm, s) for s in seen):
                outcome.outcome = "moved"
                outcome.reason = "not where it was after a missed grasp: it was moved"
        candidates: list[tuple[tuple[int, float], Sighting, BlockOutcome]] = []
        boxed_in: list[tuple[BlockOutcome, str, Sighting]] = []
        # A blob split into touching blocks is in a bin if any of them is (blocks side by
        # side in a bin can look like one blob).
        binned = {id(v.detection) for v in seen if v.detection is not None and self._in_a_bin(v)}
        for sighting in seen:
            if self._in_a_bin(sighting) or id(sighting.detection) in binned:
                continue  # sorted already
            outcome = self._outcome_for(sighting, report)
            if outcome.outcome != "pending":
                continue
            reason = self._why_not(sighting)
            if reason:
                outcome.outcome, outcome.reason = "skipped", reason
                self.progress(f"skip {sighting.color} at {_mm(outcome.found_mm)}: {reason}")
                continue
            if id(outcome) in self._boxed:  # seen closer since, and boxed in there
                boxed_in.append((outcome, "no grasp clears its neighbours, seen closer",
                                 self._boxed[id(outcome)]))
                continue
            if sighting.whole:
                try:
                    self._plan(sighting)
                except NoClearGrasp as exc:  # perhaps once a neighbour has gone
                    boxed_in.append((outcome, str(exc), sighting))
                    continue
            distance = math.hypot(sighting.location.x_mm, sighting.location.y_mm)
            rank = list(self.bins).index(sighting.color) if self.settings.order == "colors" else 0
            candidates.append(((rank, distance), sighting, outcome))
        if not candidates:
            # Every block left is boxed in by its neighbours: push one out of the group,
            # then look again; one pushed too often is skipped.
            for outcome, _, sighting in boxed_in:
                if self._nudges.get(id(outcome), 0) < self.settings.max_nudges:
                    self._nudges[id(outcome)] = self._nudges.get(id(outcome), 0) + 1
                    # Its neighbours as seen facing it (the survey may see a group as one).
                    fresh = self.look_closer(sighting, always=True)
                    push = self.nudge(fresh) if fresh is not None else None
                    if push is not None:  # the record follows it (_outcome_for)
                        self._pushed[id(outcome)] = (outcome, outcome.found_mm, push.end)
                        self._boxed.pop(id(outcome), None)
                        return True
            for outcome, why, _ in boxed_in:
                outcome.outcome, outcome.reason = "skipped", why
                self.progress(f"skip {outcome.color} at {_mm(outcome.found_mm)}: {why}")
            return False
        _, target, outcome = min(candidates, key=lambda c: c[0])
        self.check_servos()
        t0 = self.clock.now()
        closer = self.look_closer(target)
        reason = self._why_not(closer) if closer is not None else ""
        if reason:  # seen better, it is out of reach after all
            outcome.outcome, outcome.reason = "skipped", reason
            self.progress(f"skip {target.color} at {_mm(outcome.found_mm)}: {reason}")
            return True
        outcome.attempts += 1
        if closer is None:
            held, why, placed = False, "not seen whole when looked at closer", None
        else:
            # Where it is, as seen closer: it is looked for there from now on (and where
            # the survey saw it, while it waits).
            here = (closer.location.x_mm, closer.location.y_mm)
            if math.dist(here, outcome.found_mm) > SAME_BLOCK_MM:
                self._aliases.setdefault(id(outcome), []).append(outcome.found_mm)
            outcome.found_mm = here
            self.on_pick(closer)
            try:
                held, why, placed, plan = self.pick_and_place(closer)
                outcome.grasp_pitch_deg = plan.pitch_deg
            except NoClearGrasp as exc:  # seen closer, the neighbours are in the way:
                held, why, placed = False, str(exc), None  # no attempt; boxed in
                outcome.attempts -= 1
                self._boxed[id(outcome)] = closer
            except MotionTimeoutError as exc:  # a move met something: back off, go on
                self._retreat()
                if self._holding is not None:  # let it go: it is looked for afresh
                    self._holding = None
                    self.arm.open_gripper()
                held, why, placed = False, f"a move met something ({exc}): backed off", None
        outcome.seconds += self.clock.now() - t0
        if held:
            self._boxed.clear()  # a neighbour gone may have freed them
            outcome.outcome, outcome.placed_mm = "sorted", placed
            self.progress(f"{target.color} from {_mm(outcome.found_mm)} into its bin "
                          f"({outcome.seconds:.1f} s)")
        elif outcome.attempts >= self.settings.max_attempts:
            outcome.outcome, outcome.reason = "failed", why
            self.progress(f"{target.color} at {_mm(outcome.found_mm)}: gave up: {why}")
        else:
            self.progress(f"{target.color} at {_mm(outcome.found_mm)}: {why}; looking again")
        return True

    def _stop_and_read_gripper(self) -> str:
        """Stop and hold the arm (a Ctrl+C between moves has stopped nothing yet); what the
        gripper holds, as read back."""
        g = self.arm.config.gripper
        try:
            self.arm.stop()
            pulses = self.arm.read_gripper_pulses()
        except BusArmError as exc:
            return f"unknown: the bus did not answer ({exc})"
        gap_mm = g.gap_mm_at(pulses)
        said = f"{gap_mm:.0f} mm apart, {pulses} pulses"
        if abs(pulses - g.closed_pulses) <= g.holding_margin_pulses:
            lost = f", the {self._holding} block lost" if self._holding else ""
            return f"closed, empty{lost} ({said})"
        if self._holding and gap_mm <= self.locator.block_size_mm + HOLD_SLACK_MM:
            return f"holding a {self._holding} block ({said})"
        return f"open ({said})"

    def _in_a_bin(self, sighting: Sighting) -> bool:
        return any(math.hypot(sighting.location.x_mm - bx, sighting.location.y_mm - by)
                   < BIN_RADIUS_MM for bx, by in self.bins.values())

    def _outcome_for(self, sighting: Sighting, report: RunReport) -> BlockOutcome:
        """The record of this block: one already made where it was seen, or a new one."""
        for outcome in report.blocks:
            if _same_block(outcome.color, *outcome.found_mm, sighting):
                if outcome.outcome == "sorted":
                    # Sorted, yet seen where it was: it did not go (a slip). Try again.
                    outcome.outcome, outcome.placed_mm = "pending", None
                self._pushed.pop(id(outcome), None)
                return outcome
        for outcome in report.blocks:  # seen where the survey saw it, not as seen closer
            if outcome.outcome == "pending" and any(
                    _same_block(outcome.color, x, y, sighting)
                    for x, y in self._aliases.get(id(outcome), ())):
                return outcome
        here = np.array([sighting.location.x_mm, sighting.location.y_mm])
        for key, (outcome, start, end) in list(self._pushed.items()):
            # A pushed block ends somewhere along its push: the record goes there too.
            a, b = np.asarray(start), np.asarray(end)
            t = float(np.clip(np.dot(here - a, b - a) / max(np.dot(b - a, b - a), 1e-9), 0, 1))
            if outcome.color == sighting.color and float(
                    np.linalg.norm(here - (a + t * (b - a)))) < 2 * SAME_BLOCK_MM:
                del self._pushed[key]
                outcome.found_mm = (float(here[0]), float(here[1]))
                return outcome
        outcome = BlockOutcome(sighting.color, (sighting.location.x_mm, sighting.location.y_mm))
        report.blocks.append(outcome)
        return outcome

    def _why_not(self, sighting: Sighting) -> str:
        """Why this block is not to be picked ("" if it is)."""
        if sighting.color not in self.bins:
            return f"no bin for {sighting.color}"
        if self._placed.get(sighting.color, 0) >= self.bin_capacity:
            return f"bin full: the {sighting.color} bin holds {self.bin_capacity} blocks"
        if not sighting.whole:
            return ""  # where it is, and so whether it is reached, is known after a closer look
        if not sighting.reachable:
            return sighting.reason or "out of reach"
        try:
            self._plan(sighting)
        except NoClearGrasp:
            return ""  # reachable: whether its neighbours leave room is decided each cycle
        except UnreachableError as exc:
            return str(exc)
        return ""

    def _plan(self, target: Sighting) -> GraspPlan:
        """A grasp of ``target`` that keeps the fingers off every other block seen."""
        loc = target.location
        return self.planner.plan(loc.x_mm, loc.y_mm, loc.yaw_deg, self._neighbours(target),
                                 self._gaps(), self._obstacles)

    def _neighbours(self, target: Sighting) -> list[Footprint]:
        """The footprints of every other block the last survey saw."""
        loc, size = target.location, self.locator.block_size_mm
        return [Footprint.square(v.location.x_mm, v.location.y_mm, size, v.location.yaw_deg)
                for v in self._seen
                if not _same_block(target.color, loc.x_mm, loc.y_mm, v)
                and _off_mm(v, loc.x_mm, loc.y_mm) > size / 2]

    def _gaps(self) -> list[float]:
        """How far apart the fingers may open for a grasp, widest first."""
        s, size = self.settings, self.locator.block_size_mm
        return [size + 2 * c for c in (s.finger_clearance_mm,
                                       (s.finger_clearance_mm + s.min_finger_clearance_mm) / 2,
                                       s.min_finger_clearance_mm)]


def _mm(xy: tuple[float, float]) -> str:
    """A place on the table as the progress lines say it: ``(208, -124) mm``."""
    return f"({xy[0]:.0f}, {xy[1]:.0f}) mm"


def _same_block(color: str, x_mm: float, y_mm: float, seen: Sighting,
                radius_mm: float = SAME_BLOCK_MM) -> bool:
    """Whether ``seen`` is the block of ``color`` seen at (x, y) before."""
    return seen.color == color and _off_mm(seen, x_mm, y_mm) < radius_mm


def _off_mm(seen: Sighting, x_mm: float, y_mm: float) -> float:
    return math.hypot(seen.location.x_mm - x_mm, seen.location.y_mm - y_mm)


def _bearing_deg(seen: Sighting) -> float:
    return math.degrees(math.atan2(seen.location.y_mm, seen.location.x_mm))

