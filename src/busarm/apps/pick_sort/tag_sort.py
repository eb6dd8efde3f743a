"""Sorting by tag (the vendor's game): each block with an AprilTag (36h11) on its top goes
to the place its tag id is mapped to (``SortRule(by="tag")``), whatever its colour.

``TagSortJob(robot).run()``, the same code on the twin and on hardware:

1. survey: the camera looks down at the table from a few bearings (``TagView``, as tag
   stacking does); each tag gives its block's id, top centre, yaw and side. A tag covers
   most of a block's top, so its colour is not what finds it;
2. each block, the nearest to the base first: its place by its id (none: left, said
   why), looked at closer, taken with the fingers opened from its measured side
   (``GraspPlanner``, ``descend_and_grip``), carried to its bin's next free place
   (``BinPlaces``) and let go;
3. a grasp that closed on nothing looks again (``max_grasps`` grasps a block); blocks
   the survey did not see are looked for once more before the run ends.

Any exception or Ctrl+C stops the arm where it is (MOVE_STOP); ``report`` keeps what was
done. The report is pick-and-sort's (``RunReport``), each block named by its tag.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.bins import BinPlaces
from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner, NoClearGrasp
from busarm.apps.pick_sort.gripping import descend_and_grip, lower_and_release, still_holding
from busarm.apps.pick_sort.outcomes import BlockOutcome, RunReport
from busarm.apps.pick_sort.rules import SortRule
from busarm.apps.stack.settings import StackSettings
from busarm.apps.stack.tag_view import TagSighting, TagView
from busarm.errors import (
    BusArmError,
    ConfigError,
    MotionTimeoutError,
    UnreachableError,
    why_stopped,
)
from busarm.perception.locate import Sighting
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.units import place_text

__all__ = [
    "TagSortJob",
]


PROBE_MM = 30.0
"""The side a survey's look aims over (a block's top about this high over the table)."""
IN_BIN_MM = 45.0
"""A tag seen this near a bin's centre is on a block in that bin: sorted already."""


class TagSortJob:
    """Sort ``robot``'s tagged blocks into ``bins`` (default the robot's: name -> x, y mm)
    by ``rule`` (by tag; default tag ``i`` to the ``i``-th bin round them); ``progress``
    hears each step, ``on_survey`` what each ``survey()`` saw (by tag id)."""

    def __init__(self, robot: Robot, *, rule: SortRule | None = None,
                 bins: Mapping[str, tuple[float, float]] | None = None,
                 settings: StackSettings | None = None, progress: Progress = quiet,
                 on_survey: Callable[[Mapping[int, TagSighting]], None] | None = None
                 ) -> None:
        self.rule = rule or SortRule("tag")
        if not self.rule.reads_tags:
            raise ConfigError(f"TagSortJob sorts by tag, not by {self.rule.by} (PickSorter)")
        self.robot, self.arm = robot, robot.arm
        self.settings = settings or StackSettings()
        self.bins = self.rule.places(robot.bins if bins is None else bins, ())
        self.locator = robot.locator()
        self.table_z_mm = self.locator.table_z_mm
        pick = self.settings.pick
        self.view = TagView(self.arm, robot.camera, self.locator, pick.settle_s,
                            pick.joint_speed_deg_s)
        self.planner = GraspPlanner(self.arm.kin, self.table_z_mm, PROBE_MM, pick.approach_mm,
                                    pick.carry_mm, pad_mm=self.arm.config.gripper.pad_mm)
        self.places = BinPlaces(self.bins, self.planner)
        self.progress = progress
        self.on_survey = on_survey or (lambda _: None)
        self.clock = robot.clock
        self.report = RunReport()
        """The run's report as it goes (what was done so far, if it stops early)."""

    def __repr__(self) -> str:
        return f"TagSortJob({self.rule!r}, bins={', '.join(self.bins)})"

    @property
    def last_survey(self) -> list[tuple[npt.NDArray[np.uint8], list[Sighting]]]:
        """The last picture the camera took (no block in it found by colour)."""
        return [] if self.view.last_image is None else [(self.view.last_image, [])]

    def run(self) -> RunReport:
        """Sort every tagged block seen, go home; the report (also ``report``)."""
        start = self.clock.now()
        self.report = report = RunReport()
        try:
            self._sort(report)
            self.arm.move_joints(self.arm.config.pose("home"),
                                 speed_deg_s=self.settings.pick.joint_speed_deg_s)
        except BaseException as exc:
            report.stopped = why_stopped(exc)
            with contextlib.suppress(BusArmError, OSError):  # the port may be what failed
                self.arm.stop()
                gap = self.arm.config.gripper.gap_mm_at(self.arm.read_gripper_pulses())
                report.gripper = f"{gap:.0f} mm apart"
            raise
        finally:
            report.seconds = self.clock.now() - start
        return report

    # ------------------------------------------------------------------ seeing

    def survey(self) -> dict[int, TagSighting]:
        """Every upright tagged block seen on the table (not in a bin), by id
        (``TagView.survey``)."""
        s = self.settings
        seen = self.view.survey(s.survey_bearings_deg, s.survey_radius_mm,
                                self.table_z_mm + PROBE_MM, s.survey_mm)
        out = {tag: t for tag, t in seen.items() if not self._in_a_bin(t)}
        self.on_survey(dict(out))
        return out

    def _in_a_bin(self, t: TagSighting) -> bool:
        return any(math.hypot(t.x_mm - x, t.y_mm - y) < IN_BIN_MM for x, y in self.bins.values())

    # ------------------------------------------------------------------ the run

    def _sort(self, report: RunReport) -> None:
        """Survey, then each block to its place, nearest first; those not seen again are
        looked for once more."""
        records: dict[int, BlockOutcome] = {}
        looked_again = False
        while True:
            seen = self.survey()
            waiting = {tag: t for tag, t in seen.items()
                       if tag not in records or records[tag].outcome == "pending"}
            for tag, t in waiting.items():
                if tag not in records:
                    records[tag] = self._record(report, t)
            todo = [t for t in waiting.values() if self._why_not(records[t.tag_id], t) == ""]
            if not todo:
                missing = [o for o in records.values() if o.outcome == "pending"]
                if not missing or looked_again:
                    for o in missing:
                        o.outcome, o.reason = "failed", "not seen again"
                    return
                looked_again = True
                continue
            target = min(todo, key=lambda t: math.hypot(t.x_mm, t.y_mm))
            self._one(records[target.tag_id], target, seen)

    def _record(self, report: RunReport, t: TagSighting) -> BlockOutcome:
        outcome = BlockOutcome(f"tag {t.tag_id}", (t.x_mm, t.y_mm))
        outcome.place = self.rule.place_for("", t.size_mm, t.tag_id, list(self.bins)) or ""
        report.blocks.append(outcome)
        return outcome

    def _why_not(self, outcome: BlockOutcome, t: TagSighting) -> str:
        """Why the block is not to be taken ("" if it is); said once, as skipped."""
        why = ""
        if outcome.place not in self.bins:
            why = f"no place for tag {t.tag_id}"
        elif self.places.is_full(outcome.place, t.size_mm):
            why = (f"bin full: the {outcome.place} bin holds "
                   f"{self.places.count(outcome.place)} blocks")
        elif outcome.attempts >= self.settings.max_grasps:
            why = outcome.reason or "not taken"
            outcome.outcome = "failed"
        if why and outcome.outcome == "pending":
            outcome.outcome, outcome.reason = "skipped", why
            self.progress(f"skip tag {t.tag_id} at {place_text((t.x_mm, t.y_mm))}: {why}")
        return why

    def _one(self, outcome: BlockOutcome, target: TagSighting,
             seen: Mapping[int, TagSighting]) -> None:
        """Look closer at ``target``, take it and put it in its bin; the record says how."""
        t0, tag = self.clock.now(), target.tag_id
        s = self.settings
        closer = self.view.find(tag, target.x_mm, target.y_mm,
                                self.table_z_mm + target.size_mm, s.look_mm)
        if closer is None or not closer.upright:
            outcome.attempts += 1
            outcome.reason = "not seen upright when looked at closer"
            self.progress(f"tag {tag}: {outcome.reason}")
            return
        outcome.found_mm = (closer.x_mm, closer.y_mm)
        others = [Footprint.square(o.x_mm, o.y_mm, o.size_mm, o.yaw_deg)
                  for o in seen.values() if o.tag_id != tag]
        planner = replace(self.planner, block_mm=closer.size_mm)
        try:
            plan = planner.plan(closer.x_mm, closer.y_mm, closer.yaw_deg, others,
                                s.pick.gaps_mm(closer.size_mm))
        except (NoClearGrasp, UnreachableError) as exc:
            outcome.outcome, outcome.reason = "skipped", str(exc)
            self.progress(f"skip tag {tag} at {place_text(outcome.found_mm)}: {exc}")
            return
        outcome.attempts += 1
        outcome.grasp_pitch_deg = plan.pitch_deg
        missed = self._take(plan)
        if not missed:
            placed = self._put(plan, outcome.place, closer.size_mm)
            missed = "" if placed is not None else "it slipped out on the way"
            if placed is not None:
                outcome.outcome, outcome.placed_mm = "sorted", placed
        outcome.seconds += self.clock.now() - t0
        if missed:
            outcome.reason = missed
            self.progress(f"tag {tag} at {place_text(outcome.found_mm)}: {missed}")
        else:
            self.progress(f"tag {tag} from {place_text(outcome.found_mm)} into the "
                          f"{outcome.place} bin ({outcome.seconds:.1f} s)")

    def _take(self, plan: GraspPlan) -> str:
        """To above the block, down, close: "" if it holds it, else why not."""
        pick = self.settings.pick
        self.arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
        try:
            self.arm.move_to(*plan.above, plan.pitch_deg, plan.roll_deg,
                             speed_deg_s=pick.joint_speed_deg_s)
        except MotionTimeoutError as exc:  # it met something on the way: back off
            self.arm.move_joints(self.arm.config.pose("look"),
                                 speed_deg_s=pick.joint_speed_deg_s)
            return f"blocked on the way to it ({exc})"
        self.arm.open_gripper(gap_mm=plan.gap_mm)
        return descend_and_grip(self.arm, plan, pick.line_speed_mm_s)

    def _put(self, plan: GraspPlan, place: str, size_mm: float) -> tuple[float, float] | None:
        """Carry the block held at ``plan``'s lift to its bin's next place and let it go
        (a second layer: set down just above the first); where, or None if it slipped."""
        pick, z0, gap = self.settings.pick, self.table_z_mm, plan.gap_mm
        carry, release = self.places.heights_mm(place, size_mm, pick.carry_mm,
                                                pick.release_mm)
        carry_z, release_z = z0 + carry, z0 + release
        bx, by, _, roll = self.places.next_spot(place, (), gap, release_z, size_mm)
        release_z = z0 + self.places.release_mm(place, release, roll, gap)
        self.arm.move_line(*plan.lift, plan.pitch_deg, plan.roll_deg,
                           speed_mm_s=pick.line_speed_mm_s)
        self.arm.move_to(bx, by, carry_z, -90.0, roll, speed_deg_s=pick.joint_speed_deg_s)
        if not still_holding(self.arm):
            self.arm.open_gripper(wait=False, gap_mm=gap)
            self.places.take_back(place)
            return None
        lower_and_release(self.arm, (bx, by, release_z), -90.0, roll, gap,
                          pick.line_speed_mm_s)
        self.arm.move_line(bx, by, carry_z, -90.0, roll, speed_mm_s=pick.line_speed_mm_s)
        return bx, by
