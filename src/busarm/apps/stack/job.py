"""Tag stacking (the vendor's game): blocks with AprilTags on their tops stacked at one
place on the table in tag-id order, the lowest id at the bottom.

``StackJob(robot).run()``, the same code on the twin and on hardware:

1. survey: the camera looks at the table from ``survey_mm`` over the blocks' tops on a
   few bearings (``TagView``); each tag gives its block's id, top centre, yaw and side
   (the side is the top's height over the table), not its colour;
2. the ids to stack (all seen, or those asked: refused before anything moves if one is
   not on the table) and the place (asked, or the free spot nearest an easy reach);
3. for each id, lowest first: stop cleanly if the tower would be taller than the arm
   can set a block on (its reach over the tower, with clearance, and the camera's look
   at the new top); else look at the block closer, take it straight down with the
   fingers opened from its measured side (``GraspPlanner``, ``descend_and_grip``),
   lift it as high as straight up reaches, carry it over the tower, turned to the block
   below, lower it until it rests there (``lower_and_release``) and let go. Where the
   tower stands by the arm's way to a block, the look there and the way down to it keep
   the tool ``TOWER_CLEAR_MM`` over the tower's top (``Keepout``), and the place is
   chosen where those looks exist for every block (the tower as tall as it is by then);
4. check by looking: the tower's top tag gives the top's height (the sides added up)
   and its offset from the tower's axis (the bottom block: from the place asked). A
   block off by more than ``max_offset_mm`` is taken from the top and placed again; one
   that fell is looked for on the table and stacked again; ``max_tries`` placements,
   then the run fails, saying why.

Any exception or Ctrl+C stops the arm where it is (MOVE_STOP); ``report`` keeps the
tower so far and why it stopped.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace

from busarm.apps.pick_sort.bins import BIN_RADIUS_MM
from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner
from busarm.apps.pick_sort.gripping import descend_and_grip, lower_and_release, still_holding
from busarm.apps.stack.report import StackedBlock, StackReport
from busarm.apps.stack.settings import StackSettings
from busarm.apps.stack.tag_view import Keepout, TagSighting, TagView
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import BusArmError, ConfigError, UnreachableError, why_stopped
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.twin.scene import Table
from busarm.units import check_int_range, place_text
from busarm.vision.tags import TAG_COUNT

__all__ = [
    "MAX_IDS",
    "PLACE_PROBE_MM",
    "StackJob",
    "check_ids",
    "check_place",
]


MAX_IDS = 20
PLACE_PROBE_MM = 30.0
"""The side of the block a place asked for is checked for (the reach of its first layer)."""
REACH_MARGIN_DEG = 2.0
"""A place over the tower keeps every joint this far inside its limits."""
ROOM_MM = 20.0
"""A finger pad's thickness and a clearance: what a place keeps free around the tower."""
SPOT_RADII_MM = (160.0, 140.0, 180.0, 200.0, 220.0)
SPOT_BEARINGS_DEG = (0.0, 12.0, -12.0, 24.0, -24.0, 36.0, -36.0, 48.0, -48.0, 60.0, -60.0)
"""Where a free place is looked for, the nearest to (160, 0) mm first (an easy reach)."""
ARM_CLEAR_MM = 70.0
"""A free place for a tower keeps this far aside from the arm's way to a block beyond it."""
TOWER_CLEAR_MM = 25.0
"""Looking at or coming down to a block by the tower, the tool keeps this high over its
top where it passes by (the fingers and the camera round the tool: ``_keepout``)."""
RISE_STEP_MM = 5.0
"""A carried block rises as high as straight up reaches, to this step."""
HEIGHT_TOLERANCE = 1 / 3
"""A top seen further than this part of its block's side from where it should be: the
block did not land on the tower (it fell, or leans)."""


class _Failed(Exception):
    """A block could not be stacked: the run fails with this reason."""


def check_ids(ids: Iterable[int] | None) -> list[int] | None:
    """The tag ids to stack, lowest first (None: every one seen); ConfigError for one out
    of 36h11's range, repeated ones or too many."""
    if ids is None:
        return None
    out = [check_int_range("tag id", i, 0, TAG_COUNT - 1) for i in ids]
    if not out:
        raise ConfigError("--tags is empty: give the tag ids to stack, e.g. 0,1,2")
    if len(set(out)) != len(out):
        raise ConfigError(f"--tags repeats an id: {','.join(map(str, out))}")
    if len(out) > MAX_IDS:
        raise ConfigError(f"--tags gives {len(out)} ids; at most {MAX_IDS}")
    return sorted(out)


def check_place(kin: ArmKinematics, table_z_mm: float, xy_mm: tuple[float, float], *,
                table: Table | None = None,
                bins: Mapping[str, tuple[float, float]] | None = None) -> tuple[float, float]:
    """``xy_mm`` if a tower may stand there: on the ``table`` (when known), off the
    ``bins``, where the arm sets a block straight down; else ConfigError saying why."""
    x, y = (float(v) for v in xy_mm)
    if not all(math.isfinite(v) for v in (x, y)):
        raise ConfigError(f"--at ({x}, {y}) must be two finite numbers (mm)")
    where = place_text((x, y))
    if table is not None and not table.contains(x, y, PLACE_PROBE_MM):
        raise ConfigError(
            f"--at {where} is off the table (x {table.x_min_mm:g}..{table.x_max_mm:g} mm, "
            f"y {table.y_min_mm:g}..{table.y_max_mm:g} mm, {PLACE_PROBE_MM:g} mm inside)")
    for color, (bx, by) in (bins or {}).items():
        if math.hypot(x - bx, y - by) < BIN_RADIUS_MM + PLACE_PROBE_MM:
            raise ConfigError(f"--at {where} is on the {color} tray at {place_text((bx, by))}")
    planner = GraspPlanner(kin, table_z_mm, PLACE_PROBE_MM, 60.0, 75.0)
    try:
        roll = planner.roll_squared_deg(x, y, 0.0)
        planner.check_path([(x, y, table_z_mm + 75.0), (x, y, planner.grasp_z_mm)], -90.0,
                           roll, REACH_MARGIN_DEG)
    except UnreachableError as exc:
        raise ConfigError(f"--at {where} is out of the arm's reach ({math.hypot(x, y):.0f} mm "
                          f"from the base): a block is not set down straight there: {exc}"
                          ) from None
    return x, y


class StackJob:
    """Stack the tagged blocks on ``robot``'s table (see the module docstring): ``ids``
    (default every tag seen) at ``at_mm`` (default a free spot); ``progress`` hears each
    step."""

    def __init__(self, robot: Robot, *, ids: Iterable[int] | None = None,
                 at_mm: tuple[float, float] | None = None,
                 settings: StackSettings | None = None, progress: Progress = quiet) -> None:
        self.robot, self.arm = robot, robot.arm
        self.settings = settings or StackSettings()
        self.ids = check_ids(ids)
        self.locator = robot.locator()
        self.table_z_mm = self.locator.table_z_mm
        self.table = robot.sim.scene.table if robot.sim is not None else None
        self.at_mm = None if at_mm is None else check_place(
            self.arm.kin, self.table_z_mm, at_mm, table=self.table, bins=robot.bins)
        pick = self.settings.pick
        self.view = TagView(self.arm, robot.camera, self.locator, pick.settle_s,
                            pick.joint_speed_deg_s)
        self.planner = GraspPlanner(self.arm.kin, self.table_z_mm, PLACE_PROBE_MM,
                                    pick.approach_mm, pick.carry_mm,
                                    pad_mm=self.arm.config.gripper.pad_mm)
        self.progress = progress
        self.clock = robot.clock
        self.on_table: dict[int, TagSighting] = {}
        """The tagged blocks standing on the table (not in the tower), as last seen."""
        self.report = StackReport()
        """The run's report as it goes (the tower so far, if it stops early)."""

    # ------------------------------------------------------------------ the run

    def run(self) -> StackReport:
        """Stack, go home; the report (also ``report``, kept when a stop raises)."""
        start = self.clock.now()
        self.report = report = StackReport()
        try:
            try:
                self._stack(report)
            except _Failed as exc:
                report.end, report.why = "failed", str(exc)
                self.progress(f"failed: {exc}")
            self.arm.open_gripper()
            self.arm.move_joints(self.arm.config.pose("home"),
                                 speed_deg_s=self.settings.pick.joint_speed_deg_s)
        except BaseException as exc:
            report.end, report.why = "stopped", why_stopped(exc)
            with contextlib.suppress(BusArmError, OSError):  # the port may be what failed
                self.arm.stop()
            raise
        finally:
            report.seconds = self.clock.now() - start
        return report

    def _stack(self, report: StackReport) -> None:
        """Survey, choose, then each block onto the tower in id order."""
        self.on_table = self.survey()
        report.ids = self._chosen(self.on_table)
        place = self.at_mm or self._free_spot(report.ids)
        self._check_free(place, report.ids)
        report.place_mm = place
        self.progress(f"stacking tags {', '.join(map(str, report.ids))} at {place_text(place)}")
        axis, top_z, below_yaw = place, self.table_z_mm, None
        for tag in report.ids:
            seen = self.on_table[tag]
            size = self.view.sizes[tag]
            why = self._too_tall(tag, size, axis, top_z)
            if why:
                report.end, report.why = "too tall", why
                self.progress(f"stopping: {why}")
                return
            block = StackedBlock(tag, size, (seen.x_mm, seen.y_mm))
            self.progress(f"taking tag {tag} ({size:.1f} mm) at {place_text(block.found_mm)}")
            top = self._stack_one(block, axis, top_z,
                                  seen.yaw_deg if below_yaw is None else below_yaw)
            report.tower.append(block)
            report.height_mm = top.top_z_mm - self.table_z_mm
            if len(report.tower) == 1:
                axis = (top.x_mm, top.y_mm)  # the tower's axis: where its bottom stands
            top_z, below_yaw = top.top_z_mm, top.yaw_deg
            self.progress(f"tag {tag} on the tower, {block.error_mm:.1f} mm off its axis; "
                          f"the tower is {report.height_mm:.1f} mm tall")
        report.end = "complete"

    # ------------------------------------------------------------------ seeing

    def survey(self, keepout: Keepout | None = None) -> dict[int, TagSighting]:
        """Every upright tagged block seen from the survey's views (the tool over
        ``keepout``: the tower), by id (the sighting nearest the middle of its view kept),
        each one's side measured."""
        s = self.settings
        found = self.view.survey(s.survey_bearings_deg, s.survey_radius_mm,
                                 self.table_z_mm + PLACE_PROBE_MM, s.survey_mm, keepout)
        for tag, t in found.items():
            self.view.sizes.setdefault(tag, t.size_mm)
        return found

    def _chosen(self, seen: Mapping[int, TagSighting]) -> list[int]:
        """The ids to stack: those asked, every one on the table (ConfigError if not,
        before any block is moved); else every one seen."""
        if self.ids is None:
            if not seen:
                raise _Failed("no tagged block seen on the table")
            return sorted(seen)
        missing = [i for i in self.ids if i not in seen]
        if missing:
            raise ConfigError(f"--tags {','.join(map(str, missing))}: not on the table (tags "
                              f"seen: {', '.join(map(str, seen)) or 'none'}); nothing was moved")
        return list(self.ids)

    def _free_spot(self, ids: Sequence[int]) -> tuple[float, float]:
        """The free place nearest an easy reach where the tower of ``ids`` may stand
        whole, out of the arm's way to the blocks beyond it if there is such a place
        (else the first free place: the tower stops where it would be too tall)."""
        free: list[tuple[float, float]] = []
        for radius, bearing in sorted(
                ((r, b) for r in SPOT_RADII_MM for b in SPOT_BEARINGS_DEG),
                key=lambda rb: math.dist(_polar(*rb), _polar(SPOT_RADII_MM[0], 0.0))):
            spot = _polar(radius, bearing)
            if self._blocked_by(spot, self.on_table) is not None:
                continue
            try:
                check_place(self.arm.kin, self.table_z_mm, spot, table=self.table,
                            bins=self.robot.bins)
            except ConfigError:
                continue
            free.append(spot)
        if not free:
            raise _Failed("no free place for the tower within easy reach: give --at X,Y")
        def clear_and_fits(p: tuple[float, float]) -> bool:
            return not self._in_the_way(p) and self._whole_tower_fits(p, ids)

        def fits(p: tuple[float, float]) -> bool:
            return self._whole_tower_fits(p, ids)

        for wanted in (clear_and_fits, fits):
            spot_found = next((p for p in free if wanted(p)), None)
            if spot_found is not None:
                return spot_found
        return free[0]

    def _in_the_way(self, spot: tuple[float, float]) -> bool:
        """Whether a tower at ``spot`` would stand under the arm reaching for a block
        farther out (the arm and its camera pass over what is nearer on its bearing)."""
        for t in self.on_table.values():
            reach = math.hypot(t.x_mm, t.y_mm)
            ux, uy = t.x_mm / reach, t.y_mm / reach
            along = spot[0] * ux + spot[1] * uy
            if 0.0 < along < reach and abs(spot[1] * ux - spot[0] * uy) < ARM_CLEAR_MM:
                return True
        return False

    def _whole_tower_fits(self, spot: tuple[float, float], ids: Sequence[int]) -> bool:
        """Whether every block of ``ids`` can be set on a tower at ``spot``, each looked at
        on the table with the tool over the tower as tall as it is by then."""
        top_z = self.table_z_mm
        for tag in ids:
            size = self.view.sizes[tag]
            if self._too_tall(tag, size, spot, top_z):
                return False
            keepout, seen = self._keepout(spot, top_z), self.on_table[tag]
            if keepout is not None and keepout.deck(seen.x_mm, seen.y_mm)[0]:
                try:
                    self.view.pose_for(seen.x_mm, seen.y_mm, seen.top_z_mm,
                                       self.settings.look_mm, keepout)
                except UnreachableError:
                    return False
            top_z += size
        return True

    def _keepout(self, axis: tuple[float, float], top_z: float) -> Keepout | None:
        """What the tool keeps clear of by the tower topped at ``top_z`` (None: no tower
        yet): its widest block's half diagonal, the open fingers round the tool and a
        clearance; ``TOWER_CLEAR_MM`` over its top."""
        if top_z <= self.table_z_mm:
            return None
        widest = max(self.view.sizes.values(), default=PLACE_PROBE_MM)
        pick, pad = self.settings.pick, self.arm.config.gripper.pad_mm[0]
        fingers = widest / 2 + pick.finger_clearance_mm + pad
        return Keepout(*axis, widest * math.sqrt(0.5) + fingers + ROOM_MM / 2,
                       top_z + TOWER_CLEAR_MM)

    def _blocked_by(self, spot: tuple[float, float], blocks: Mapping[int, TagSighting]
                    ) -> TagSighting | None:
        """A block standing where a tower at ``spot`` (and the fingers around it) needs
        room, or None."""
        widest = max(self.view.sizes.values(), default=PLACE_PROBE_MM)
        for t in blocks.values():
            if t.off_mm(*spot) < (t.size_mm + widest) * math.sqrt(0.5) + ROOM_MM:
                return t
        return None

    def _check_free(self, place: tuple[float, float], ids: Sequence[int]) -> None:
        """ConfigError (nothing moved yet) if a block stands where the tower goes."""
        there = self._blocked_by(place, self.on_table)
        if there is not None:
            raise ConfigError(f"--at {place_text(place)}: tag {there.tag_id}'s block stands "
                              f"there at {place_text((there.x_mm, there.y_mm))}: choose a free "
                              "place; nothing was moved")

    def _too_tall(self, tag: int, size: float, axis: tuple[float, float], top_z: float
                  ) -> str:
        """Why block ``tag`` is not to be set on the tower topped at ``top_z`` ("" if it
        may be): taller than allowed, beyond the arm's reach over it with clearance, or
        where the camera cannot look at its top."""
        s, z0 = self.settings, self.table_z_mm
        height = top_z + size - z0
        tall = f"the tower would be {height:.0f} mm tall with tag {tag} ({size:.1f} mm)"
        so_far = f"it stands {top_z - z0:.0f} mm tall"
        if s.max_height_mm is not None and height > s.max_height_mm:
            return f"{tall}, more than the {s.max_height_mm:g} mm allowed; {so_far}"
        x, y = axis
        try:
            roll = self.planner.roll_squared_deg(x, y, 0.0)
            self.planner.check_path([(x, y, self._carry_z(size, top_z)),
                                     (x, y, top_z + size / 2)], -90.0, roll, REACH_MARGIN_DEG)
            self.view.pose_for(x, y, top_z + size, s.look_mm)
        except UnreachableError as exc:
            return f"{tall}: more than the arm reaches over with clearance ({exc}); {so_far}"
        return ""

    def _carry_z(self, size: float, top_z: float) -> float:
        """The tool's height carrying a block of ``size``: its bottom clear of the tower's
        top and of every block on the table."""
        tallest = max((t.top_z_mm for t in self.on_table.values()), default=self.table_z_mm)
        return max(self.table_z_mm + self.settings.pick.carry_mm,
                   max(top_z, tallest) + size / 2 + self.settings.carry_clear_mm)

    # ------------------------------------------------------------------ one block

    def _stack_one(self, block: StackedBlock, axis: tuple[float, float], top_z: float,
                   yaw_deg: float) -> TagSighting:
        """Take ``block`` and set it on the tower topped at ``top_z`` (the table: the
        bottom one), turned to ``yaw_deg``, until it is seen there within
        ``max_offset_mm`` of ``axis``; its top as seen. _Failed after ``max_tries``
        placements."""
        s, tag = self.settings, block.tag_id
        source, stand_z = self.on_table[tag], self.table_z_mm
        tower = self._keepout(axis, top_z)
        for _ in range(s.max_tries):
            plan = self._take(block, source, stand_z, None if stand_z > self.table_z_mm
                              else tower)
            if stand_z == self.table_z_mm:
                self.on_table.pop(tag, None)
            block.placements += 1
            self._put(block, plan, axis, top_z, yaw_deg)
            seen = self.view.find(tag, *axis, top_z + block.size_mm, s.look_mm)
            expected = top_z + block.size_mm
            if seen is None or not seen.upright or abs(seen.top_z_mm - expected) > \
                    HEIGHT_TOLERANCE * block.size_mm:
                self.progress(f"tag {tag} is not on the tower: looking for it on the table")
                source, stand_z = self._fallen(tag, tower), self.table_z_mm
                continue
            block.seen_mm = (seen.x_mm, seen.y_mm, seen.top_z_mm)
            block.error_mm = seen.off_mm(*axis)
            if block.error_mm <= s.max_offset_mm:
                return seen
            self.progress(f"tag {tag} landed {block.error_mm:.1f} mm off the tower's axis: "
                          "placing it again")
            source, stand_z = seen, top_z
        raise _Failed(f"tag {tag} was not set on the tower within {s.max_offset_mm:g} mm of "
                      f"its axis in {s.max_tries} placements (last {block.error_mm:.1f} mm off)")

    def _fallen(self, tag: int, tower: Keepout | None) -> TagSighting:
        """Block ``tag``, fallen off the ``tower``, found upright on the table; _Failed if
        not."""
        self.on_table = {**self.on_table, **{
            t: v for t, v in self.survey(tower).items() if t == tag or t in self.on_table}}
        seen = self.on_table.get(tag)
        if seen is None or abs(seen.top_z_mm - self.table_z_mm - seen.size_mm) > 3.0:
            raise _Failed(f"tag {tag} fell off the tower and is not seen upright on the table")
        return seen

    def _take(self, block: StackedBlock, source: TagSighting, stand_z: float,
              tower: Keepout | None) -> GraspPlan:
        """Look at the block closer and take it straight down (``max_grasps`` tries), the
        tool over the ``tower`` where it passes by; the plan it was taken by. _Failed if
        it is not seen or not held."""
        s, tag = self.settings, block.tag_id
        pick = s.pick
        planner = replace(self.planner, table_z_mm=stand_z, block_mm=block.size_mm)
        missed = ""
        for _ in range(s.max_grasps):
            try:
                closer = self.view.find(tag, source.x_mm, source.y_mm,
                                        stand_z + block.size_mm, s.look_mm, tower)
            except UnreachableError as exc:
                raise _Failed(f"tag {tag} at {place_text((source.x_mm, source.y_mm))}: not "
                              f"looked at with the tool over the tower: {exc}") from None
            if closer is None or not closer.upright:
                raise _Failed(f"tag {tag} not seen upright at "
                              f"{place_text((source.x_mm, source.y_mm))} when looked at closer")
            others = [Footprint.square(t.x_mm, t.y_mm, t.size_mm, t.yaw_deg)
                      for t in self.on_table.values() if t.tag_id != tag]
            if tower is not None:  # the fingers come down clear of it
                others.append(Footprint.square(tower.x_mm, tower.y_mm, block.size_mm, 0.0))
            try:
                plan = planner.plan(closer.x_mm, closer.y_mm, closer.yaw_deg, others,
                                    pick.gaps_mm(block.size_mm))
            except UnreachableError as exc:
                raise _Failed(f"tag {tag} at {place_text((closer.x_mm, closer.y_mm))}: {exc}"
                              ) from None
            if plan.pitch_deg != -90.0:
                raise _Failed(f"tag {tag} at {place_text((closer.x_mm, closer.y_mm))} is "
                              "taken only tilted: set it nearer the arm")
            self.arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
            self._approach(plan, tower)
            self.arm.open_gripper(gap_mm=plan.gap_mm)
            block.grasps += 1
            missed = descend_and_grip(self.arm, plan, pick.line_speed_mm_s)
            if not missed:
                return plan
            self.progress(f"tag {tag}: {missed}; trying again")
            source = closer
        raise _Failed(f"tag {tag} not taken in {s.max_grasps} grasps: {missed}")

    def _approach(self, plan: GraspPlan, tower: Keepout | None) -> None:
        """The tool to ``plan``'s place above the block; by the ``tower`` (coming from the
        look over it), as high as its clearance first, then straight down."""
        pick = self.settings.pick
        x, y, z = plan.above
        if tower is not None and tower.clear_z_mm > z and \
                math.hypot(x - tower.x_mm, y - tower.y_mm) < 2 * tower.radius_mm:
            with contextlib.suppress(UnreachableError):  # (solved before anything moves)
                self.arm.move_to(x, y, tower.clear_z_mm, plan.pitch_deg, plan.roll_deg,
                                 speed_deg_s=pick.joint_speed_deg_s)
                self.arm.move_line(x, y, z, plan.pitch_deg, plan.roll_deg,
                                   speed_mm_s=pick.line_speed_mm_s)
                return
        self.arm.move_to(x, y, z, plan.pitch_deg, plan.roll_deg,
                         speed_deg_s=pick.joint_speed_deg_s)

    def _put(self, block: StackedBlock, plan: GraspPlan, axis: tuple[float, float],
             top_z: float, yaw_deg: float) -> None:
        """Carry the block taken by ``plan`` over the tower, turned to ``yaw_deg``, lower
        it until it rests on the top at ``top_z``, let go and rise."""
        pick, size = self.settings.pick, block.size_mm
        carry_z = self._carry_z(size, top_z)
        self.arm.move_line(*plan.lift, plan.pitch_deg, plan.roll_deg,
                           speed_mm_s=pick.line_speed_mm_s)
        # As high as straight up reaches (the rest on the way over: a tall tower may stand
        # higher than the lift, and a slanting rise would carry the block through it).
        z = carry_z
        while z > plan.lift[2]:
            try:  # (each line is planned before anything moves)
                self.arm.move_line(*plan.lift[:2], z, plan.pitch_deg, plan.roll_deg,
                                   speed_mm_s=pick.line_speed_mm_s)
                break
            except UnreachableError:
                z -= RISE_STEP_MM
        roll = self.planner.roll_squared_deg(*axis, yaw_deg)
        self.arm.move_to(*axis, carry_z, -90.0, roll, speed_deg_s=pick.joint_speed_deg_s)
        if not still_holding(self.arm):
            self.arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
            self.progress(f"tag {block.tag_id} slipped out on the way")
            return  # the check finds it gone, and looks for it on the table
        release = (*axis, top_z + size / 2 + self.settings.release_drop_mm)
        lower_and_release(self.arm, release, -90.0, roll, plan.gap_mm, pick.line_speed_mm_s / 2)
        self.arm.move_line(*axis, carry_z, -90.0, roll, speed_mm_s=pick.line_speed_mm_s)


def _polar(radius_mm: float, bearing_deg: float) -> tuple[float, float]:
    a = math.radians(bearing_deg)
    return radius_mm * math.cos(a), radius_mm * math.sin(a)
