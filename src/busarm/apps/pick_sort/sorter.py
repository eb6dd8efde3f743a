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

Any exception or Ctrl+C stops the arm where it is (MOVE_STOP); ``PickSorter.report`` keeps
what was done, why it stopped and what the gripper holds, as read back.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.bin_check import check_bins
from busarm.apps.pick_sort.bins import (
    BIN_PLACES,
    BIN_RADIUS_MM,
    BIN_SLOTS_MM,
    IN_BIN_MM,
    BinPlaces,
)
from busarm.apps.pick_sort.carrying import Carrier
from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner, NoClearGrasp
from busarm.apps.pick_sort.gripping import (
    descend_and_grip,
    stop_and_read_gripper,
)
from busarm.apps.pick_sort.outcomes import BlockOutcome, RunReport
from busarm.apps.pick_sort.push import Push, PushPlanner
from busarm.apps.pick_sort.records import BlockRecords
from busarm.apps.pick_sort.restage import Restaged, staging_spot
from busarm.apps.pick_sort.rules import SortRule
from busarm.apps.pick_sort.servo_care import rest_while_hot
from busarm.apps.pick_sort.settings import ORDERS, PickSortSettings
from busarm.apps.pick_sort.table_view import (
    OVER_THINGS_MM,
    TableView,
    off_mm,
    same_block,
    too_near_for_two,
)
from busarm.arm.motion import TIME_OPTIMAL
from busarm.errors import (
    ConfigError,
    HaltedError,
    MotionTimeoutError,
    UnreachableError,
)
from busarm.perception.locate import Sighting
from busarm.robot import Robot
from busarm.units import place_text

MAX_CYCLES = 150
"""Surveys a run makes at most (a cycle picks a block, or pushes one, or looks closer)."""
HOLD_SLACK_MM = 4.0
"""A gripper this little wider than a block, squeezing one, holds it (pads give a little)."""

TILTED_SET_DOWN_MM = 32.0
"""A block larger than this, taken tilted, is set down to be taken again straight down
before it goes to a bin: held tilted it would land leaning on the tray's wall (in the
twin a 40 mm block leaned 24 deg, and the one set on it threw it out)."""
LARGER_FIRST_MM = 5.0
"""Blocks are taken larger first, by sizes this far apart (a bin packs best so)."""
_Candidate = tuple[tuple[bool, int, int, float], Sighting, BlockOutcome]
"""A block that may be picked: its rank (colour order, distance), as seen, its record."""


class PickSorter:
    """Sorts the blocks of ``colors`` the robot's wrist camera sees into their bins (the
    robot's, or ``bins``: name -> (x, y) mm) by ``rule`` (by colour unless given: each
    bin named as a colour); a block with no bin is left alone.

    Hooks: ``on_step`` hears each step of a cycle by name, ``on_pick`` each block about to
    be picked, ``on_survey`` what each ``survey()`` saw (a run makes one a cycle and a
    last one; closer looks and the bins' check are no surveys)."""

    def __init__(self, robot: Robot, *, colors: Sequence[str] | None = None,
                 bins: dict[str, tuple[float, float]] | None = None,
                 survey_poses: Sequence[Sequence[float]] | None = None,
                 settings: PickSortSettings | None = None,
                 rule: SortRule | None = None,
                 progress: Callable[[str], None] | None = None,
                 on_step: Callable[[str], None] | None = None,
                 on_pick: Callable[[Sighting], None] | None = None,
                 on_survey: Callable[[Sequence[Sighting]], None] | None = None) -> None:
        arm = self.arm = robot.arm
        self.camera = robot.camera
        locator = self.locator = robot.locator(colors)
        self.rule = rule or SortRule()
        if self.rule.reads_tags:
            raise ConfigError("PickSorter sorts by colour or size; by tag, TagSortJob does "
                              "(blocks found by their tags)")
        self.bins = self.rule.places(robot.bins if bins is None else bins,
                                     locator.detector.colors)
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
        # Called with what each survey saw (a copy: a bench scores the first).
        self.on_survey = on_survey or (lambda _: None)
        # Every wait and cycle time is on the arm's clock (a twin's simulated seconds).
        self.clock = arm.clock
        self.planner = GraspPlanner(arm.kin, locator.table_z_mm, locator.block_size_mm,
                                    self.settings.approach_mm, self.settings.carry_mm,
                                    pad_mm=arm.config.gripper.pad_mm)
        self._bin_squares = [Footprint.square(x, y, 2 * BIN_RADIUS_MM, 0.0)
                             for x, y in self.bins.values()]
        self._planners: dict[float, GraspPlanner] = {}
        self.places = BinPlaces(self.bins, self.planner)
        self.view = TableView(arm, self.camera, locator, self.bins, self.survey_poses,
                              self.settings, lambda step: self._stepped(step),
                              lambda line: self.progress(line))
        # The block whose cycle runs, and when it began: its steps are timed.
        self._timing: tuple[BlockOutcome, float] | None = None
        self.records = BlockRecords()
        # The colour of the block in the fingers, from a good grip to its release.
        self._holding: str | None = None
        self.carrier = Carrier(arm, self.settings, self.view, self.places, self.planner,
                               locator.table_z_mm, self._stepped, self._released)
        self.report = RunReport()
        """The run's report as it goes (what was done so far, if it stops early)."""

    # ------------------------------------------------------------------ seeing

    @property
    def last_survey(self) -> list[tuple[npt.NDArray[np.uint8], list[Sighting]]]:
        """The last survey's (or closer look's) pictures and what was found in each."""
        return self.view.last_survey

    def survey(self, facing: Sequence[tuple[float, float]] = ()) -> list[Sighting]:
        """Every block seen (``TableView.survey``; looking ``facing`` these points too);
        ``on_survey`` is told."""
        seen = self.view.survey(facing)
        self.on_survey(tuple(seen))
        return seen

    def look_closer(self, target: Sighting, *, always: bool = False) -> Sighting | None:
        """``target`` seen facing it (``TableView.look_closer``)."""
        return self.view.look_closer(target, always=always)

    # ------------------------------------------------------------------ moving

    def _stepped(self, step: str, *, tell: bool = True) -> None:
        """A step of a cycle ended: timed for its block's record, then told (``tell``)."""
        if self._timing is not None:
            outcome, t0 = self._timing
            outcome.steps_s.append((step, self.clock.now() - t0))
        if tell:
            self.on_step(step)

    def _released(self) -> None:
        """The fingers have let the block go."""
        self._holding = None

    def check_servos(self) -> None:
        """Pause while a servo is too hot (arm at home, gripper open); a supply too low for
        the servos stops the run with ServoFaultError (``rest_while_hot``)."""
        rest_while_hot(self.arm, self.settings, self.progress)

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
        up = self.locator.table_z_mm + s.carry_mm + self.view.tallest_mm
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
        pusher = PushPlanner(self._planner_for(loc.size_mm), self._bin_squares)
        push = pusher.plan(loc.x_mm, loc.y_mm, loc.yaw_deg, self._neighbours(target),
                           self._gaps(loc.size_mm), self.view.obstacles)
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
        self._stepped("nudge")
        return push

    def pick_and_place(self, target: Sighting, place: str | None = None
                       ) -> tuple[bool, str, tuple[float, float] | None, GraspPlan]:
        """One grasp-carry-release cycle into the bin ``place`` (by default the rule's for
        ``target``); (holding was seen, why not, where it was put, the grasp plan)."""
        arm, s = self.arm, self.settings
        place = place or self.place_of(target)
        if place not in self.bins:
            what = self.rule.what(target.color, target.location.size_mm, None)
            raise ConfigError(f"no bin for {what} (bins: {', '.join(self.bins)})")
        plan = self._plan(target)
        pitch, roll = plan.pitch_deg, plan.roll_deg
        blocked = self._go_above(plan)
        if blocked:
            return False, blocked, None, plan

        def squeezing() -> None:  # from the squeeze on: the reading says if it holds
            self._holding = target.color

        missed = descend_and_grip(arm, plan, s.line_speed_mm_s, profile=TIME_OPTIMAL,
                                  on_squeeze=squeezing,
                                  on_step=self._stepped)
        if missed:
            self._holding = None
            return False, missed, None, plan
        # Not waited for: the carry's first move takes over from the line's last waypoint
        # (the block is at the lift's height, within the last waypoint's few mm).
        arm.move_line(*plan.lift, pitch, roll, speed_mm_s=s.carry_speed_mm_s,
                      profile=TIME_OPTIMAL, wait=False)
        self._stepped("lift")
        size = target.location.size_mm
        tilted = pitch != -90.0
        large_tilted = tilted and size > TILTED_SET_DOWN_MM
        if large_tilted or (tilted and self.places.next_layer(place, size) == 1):
            # Taken tilted, it turns with the tool and lands on an edge when set down
            # straight: a small one falls flat in a tray, a large one leans on the wall
            # (and one on it then throws it out), and a second layer does not forgive
            # it at all. Put down to be taken again straight down.
            stage = self._staging_spot(target)
            if stage is not None:
                self.carrier.set_down(plan, stage, plan.gap_mm)
                raise Restaged(stage)
        placed = self.carrier.to_bin(place, plan, size)
        if placed is None:
            return False, "the block slipped out during the carry", None, plan
        if large_tilted:  # no room to set it down first
            self.places.may_lean(place)
        return True, "", placed, plan

    def _go_above(self, plan: GraspPlan) -> str:
        """To ``plan.above`` (over a thing that is not a block on the way), the fingers
        opened as wide as the plan allows; "" when there, else why not (backed off)."""
        arm, s = self.arm, self.settings
        pitch, roll = plan.pitch_deg, plan.roll_deg
        # Open no wider than the neighbours allow (the plan chose it).
        arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
        tool = arm.read_pose() if self.view.obstacles else None
        if tool is not None and self.view.thing_on_the_way((tool.x_mm, tool.y_mm),
                                                           plan.above[:2]):
            # Over the thing that is not a block first, then down to the approach.
            over = (*plan.above[:2],
                    self.locator.table_z_mm + OVER_THINGS_MM + self.view.tallest_mm)
            with contextlib.suppress(UnreachableError):
                arm.move_to(*over, pitch, roll, speed_deg_s=s.joint_speed_deg_s)
        try:
            arm.move_to(*plan.above, pitch, roll, speed_deg_s=s.joint_speed_deg_s)
        except MotionTimeoutError as exc:  # the arm met something on its way: an event
            self._retreat()
            return f"blocked on the way to it ({exc}): backed off"
        arm.open_gripper(gap_mm=plan.gap_mm)
        self._stepped("above")
        return ""

    def _staging_spot(self, held: Sighting) -> tuple[float, float] | None:
        """Where to set ``held`` down to take it again straight down (``staging_spot``)."""
        loc = held.location
        size = loc.size_mm
        others = [Footprint.square(v.location.x_mm, v.location.y_mm, v.location.size_mm,
                                   v.location.yaw_deg) for v in self.view.seen
                  if off_mm(v, loc.x_mm, loc.y_mm) > size / 2]
        bins = [Footprint.square(x, y, 2 * BIN_RADIUS_MM, 0.0) for x, y in self.bins.values()]
        room = size + 2 * (self.planner.pad_mm[0] + self.settings.finger_clearance_mm)
        # Things found no block anywhere so far, not only those the last picture showed:
        # set down by one of its colour, a block makes one blob with it.
        keep_off = [*self.view.obstacles, *self.view.not_block_footprints(), *bins]
        return staging_spot(self._planner_for(size), others, keep_off, self.view.things,
                            self._gaps(size), room)

    def verify_bins(self, report: RunReport) -> None:
        """Look into each bin a block was put in: a block reported sorted but not found
        there (it bounced out, say) is reported failed instead (``check_bins``)."""
        check_bins(report, self.view, self.places, any_color=self.rule.by != "color",
                   progress=self.progress)

    # ------------------------------------------------------------------ the job

    def run(self, *, max_cycles: int = MAX_CYCLES) -> RunReport:
        """Sort until the table shows no block that can be sorted (or ``max_cycles``
        surveys have been made); the whole report.

        On an error or Ctrl+C the arm is stopped where it is, ``self.report`` says why
        and what the gripper holds, and the exception goes on up.
        """
        start = self.clock.now()
        self.report = report = RunReport()
        self._holding = None
        try:
            why = f"not done when the run's {max_cycles} cycles were up"
            looking_for: list[tuple[float, float]] = []
            for _ in range(max_cycles):
                if self._cycle(report, looking_for):
                    looking_for = []
                    continue
                # Blocks seen before and not now (a cluster the survey's far picture does
                # not make out, say): looked for once more, facing where they were.
                missing = [o.found_mm for o in report.blocks if o.outcome == "pending"]
                if looking_for or not missing:
                    why = "not seen again"
                    break
                looking_for = missing
            # A record made before its thing was found to be no block is no block's.
            report.blocks[:] = [o for o in report.blocks if o.outcome == "sorted"
                                or not self.view.is_not_block_at(o.color, o.found_mm)]
            for outcome in report.blocks:
                if outcome.outcome == "pending":
                    outcome.outcome, outcome.reason = "failed", why
            self.verify_bins(report)
        except BaseException as exc:
            # A person's stop (Ctrl+C, a signal, a halt or a page's Stop) in its words.
            report.stopped = ((str(exc) or "interrupted (Ctrl+C)")
                              if isinstance(exc, KeyboardInterrupt | HaltedError)
                              else f"{type(exc).__name__}: {exc}")
            report.gripper = "not read back (interrupted again)"  # if a Ctrl+C cuts it short
            report.gripper = self._stop_and_read_gripper()
            raise
        finally:
            report.seconds = self.clock.now() - start
        return report

    def _cycle(self, report: RunReport, facing: Sequence[tuple[float, float]] = ()) -> bool:
        """Survey (facing these points too), then pick and place the next block; False if
        there is none to pick."""
        seen = self.survey(facing)
        self.records.mark_moved(report, seen)
        candidates, boxed_in = self._choices(report, seen)
        if not candidates:
            return self._free_one(boxed_in)
        _, target, outcome = min(candidates, key=lambda c: c[0])
        self.check_servos()
        t0 = self.clock.now()
        outcome.steps_s = []
        self._timing = (outcome, t0)
        try:
            return self._pick_one(report, target, outcome, t0)
        finally:
            self._timing = None

    def _pick_one(self, report: RunReport, target: Sighting, outcome: BlockOutcome,
                  t0: float) -> bool:
        """``_cycle`` from the closer look on, for the block ``target`` (begun at ``t0``)."""
        # The fingers open while the camera looks (as wide as its grasp may want).
        self.arm.open_gripper(wait=False, gap_mm=max(self._gaps(target.location.size_mm)))
        closer = self.look_closer(target)
        if closer is not None:
            confirmed = self.view.confirm(closer)
            if confirmed is None:  # not a block after all: no record, never touched
                report.blocks.remove(outcome)
                return True
            closer = confirmed
        loc = target.location  # seen in part, even facing it: it may be farther out
        reason = self._why_not(closer) if closer is not None else self.planner.out_of_reach(
            loc.x_mm, loc.y_mm, loc.yaw_deg, loc.size_mm / 2)
        if reason:  # seen better, it is out of reach after all
            outcome.outcome, outcome.reason = "skipped", reason
            self.progress(f"skip {target.color} at {_mm(outcome.found_mm)}: {reason}")
            return True
        outcome.attempts += 1
        self._stepped("confirmed", tell=False)
        held, why, placed, restaged = self._attempt(outcome, closer)
        outcome.seconds += self.clock.now() - t0
        self._stepped("done", tell=False)
        self._tell(target.color, outcome, held, why, placed, restaged)
        if outcome.outcome == "sorted" and closer is not None:
            self.records.taken(outcome, closer.location.size_mm, report)
        return True

    def _choices(self, report: RunReport, seen: Sequence[Sighting]
                 ) -> tuple[list[_Candidate], list[tuple[BlockOutcome, str, Sighting]]]:
        """The blocks that may be picked (ranked), and those boxed in by their neighbours
        (why, and as seen); blocks not to be picked are skipped, with the reason."""
        candidates: list[_Candidate] = []
        boxed_in: list[tuple[BlockOutcome, str, Sighting]] = []
        # A blob split into touching blocks is in a bin if any of them is (blocks side by
        # side in a bin can look like one blob).
        binned = {id(v.detection) for v in seen
                  if v.detection is not None and self.view.in_a_bin(v)}
        coming: dict[str, list[float]] = {}  # where what waits goes: room kept for it
        for v in seen:
            if not self.view.in_a_bin(v) and id(v.detection) not in binned:
                coming.setdefault(self.place_of(v), []).append(v.location.size_mm)
        for place in self.bins:
            self.places.expect(place, coming.get(place, []))
        for sighting in seen:
            if self.view.in_a_bin(sighting) or id(sighting.detection) in binned:
                continue  # sorted already
            outcome = self.records.record_for(sighting, report)
            if outcome.outcome != "pending":
                continue
            reason = self._why_not(sighting)
            if reason:
                outcome.outcome, outcome.reason = "skipped", reason
                self.progress(f"skip {sighting.color} at {_mm(outcome.found_mm)}: {reason}")
                continue
            if id(outcome) in self.records.boxed:  # seen closer since, and boxed in there
                boxed_in.append((outcome, "no grasp clears its neighbours, seen closer",
                                 self.records.boxed[id(outcome)]))
                continue
            if sighting.whole:
                try:
                    self._plan(sighting)
                except NoClearGrasp as exc:  # perhaps once a neighbour has gone
                    boxed_in.append((outcome, str(exc), sighting))
                    continue
            distance = math.hypot(sighting.location.x_mm, sighting.location.y_mm)
            place = self.place_of(sighting)
            rank = (list(self.bins).index(place) if place in self.bins else len(self.bins)) \
                if self.settings.order == "colors" else 0
            # A thing whose shape waits for its neighbours to go: after them. Larger blocks
            # first (by 5 mm): a bin packs best that way, the large at the bottom.
            larger = -round(sighting.location.size_mm / LARGER_FIRST_MM)
            candidates.append(((self.view.is_waiting(sighting), rank, larger, distance),
                               sighting, outcome))
        return candidates, boxed_in

    def _free_one(self, boxed_in: list[tuple[BlockOutcome, str, Sighting]]) -> bool:
        """Every block left is boxed in by its neighbours: push one out of the group (True:
        look again); one pushed too often is skipped. False when none could be pushed."""
        for outcome, _, sighting in boxed_in:
            if self.records.may_push(outcome, self.settings.max_nudges):
                # Its neighbours as seen facing it (the survey may see a group as one).
                fresh = self.look_closer(sighting, always=True)
                push = self.nudge(fresh) if fresh is not None else None
                if push is not None:  # the record follows it (BlockRecords.record_for)
                    self.records.pushed(outcome, push.end)
                    return True
        for outcome, why, _ in boxed_in:
            outcome.outcome, outcome.reason = "skipped", why
            self.progress(f"skip {outcome.color} at {_mm(outcome.found_mm)}: {why}")
        return False

    def _attempt(self, outcome: BlockOutcome, closer: Sighting | None
                 ) -> tuple[bool, str, tuple[float, float] | None, tuple[float, float] | None]:
        """Pick the block seen ``closer`` and put it in its bin: (holding was seen, why
        not, where it was put, where it was set down to be taken again). A grasp that was
        not tried (set down, boxed in) does not count as an attempt."""
        if closer is None:
            return False, "not seen whole when looked at closer", None, None
        self.records.seen_closer(outcome, (closer.location.x_mm, closer.location.y_mm))
        self.on_pick(closer)
        place = outcome.place = self.place_of(closer) or ""
        try:
            held, why, placed, plan = self.pick_and_place(closer, place)
            outcome.grasp_pitch_deg = plan.pitch_deg
        except Restaged as exc:  # set down to be taken straight down: no attempt
            outcome.attempts -= 1
            return False, str(exc), None, exc.spot_mm
        except NoClearGrasp as exc:  # seen closer, the neighbours are in the way:
            outcome.attempts -= 1  # no attempt; boxed in
            self.records.boxed[id(outcome)] = closer
            return False, str(exc), None, None
        except MotionTimeoutError as exc:  # a move met something: back off, go on
            self._retreat()
            if self._holding is not None:  # let it go: it is looked for afresh
                self.arm.open_gripper()
                self._holding = None
            return False, f"a move met something ({exc}): backed off", None, None
        return held, why, placed, None

    def _tell(self, color: str, outcome: BlockOutcome, held: bool, why: str,
              placed: tuple[float, float] | None,
              restaged: tuple[float, float] | None) -> None:
        """Record and say how an attempt at ``outcome``'s block went."""
        if restaged is not None:  # its record goes with it (after saying where from)
            self.progress(f"{color} from {_mm(outcome.found_mm)}: {why}")
            outcome.found_mm = restaged
            self.records.boxed.clear()  # where it was is free now
        elif held:
            self.records.boxed.clear()  # a neighbour gone may have freed them
            outcome.outcome, outcome.placed_mm = "sorted", placed
            into = "its bin" if self.rule.by == "color" else f"the {outcome.place} bin"
            self.progress(f"{color} from {_mm(outcome.found_mm)} into {into} "
                          f"({outcome.seconds:.1f} s)")
        elif outcome.attempts >= self.settings.max_attempts:
            outcome.outcome, outcome.reason = "failed", why
            self.progress(f"{color} at {_mm(outcome.found_mm)}: gave up: {why}")
        else:
            self.progress(f"{color} at {_mm(outcome.found_mm)}: {why}; looking again")

    def _stop_and_read_gripper(self) -> str:
        """Stop the arm (a Ctrl+C between moves has stopped nothing yet); what the gripper
        holds (``stop_and_read_gripper``)."""
        return stop_and_read_gripper(self.arm, self._holding,
                                     self.view.tallest_mm + HOLD_SLACK_MM)

    def place_of(self, sighting: Sighting) -> str:
        """The bin ``sighting`` goes to by the rule (its colour's, or its size class's)."""
        return self.rule.place_for(sighting.color, sighting.location.size_mm, None,
                                   list(self.bins)) or ""

    def _why_not(self, sighting: Sighting) -> str:
        """Why this block is not to be picked ("" if it is)."""
        size = sighting.location.size_mm
        place = self.place_of(sighting)
        if place not in self.bins:
            return f"no bin for {self.rule.what(sighting.color, size, None)}"
        if self.places.is_full(place, size):
            return f"bin full: the {place} bin holds {self.places.count(place)} blocks"
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
        return self._planner_for(loc.size_mm).plan(
            loc.x_mm, loc.y_mm, loc.yaw_deg, self._neighbours(target),
            self._gaps(loc.size_mm), self.view.things)

    def _planner_for(self, size_mm: float) -> GraspPlanner:
        """Grasps of a block ``size_mm`` wide (the run's planner if it is that size)."""
        size = round(size_mm, 1)
        if abs(size - self.planner.block_mm) < 0.05:
            return self.planner
        if size not in self._planners:
            self._planners[size] = replace(self.planner, block_mm=size)
        return self._planners[size]

    def _neighbours(self, target: Sighting) -> list[Footprint]:
        """The footprints of every other block the last survey saw (not those standing
        where a block measured whole stands: that block seen in part)."""
        loc, size = target.location, target.location.size_mm
        whole = target.shape is not None and target.shape.verdict == "cube"
        return [Footprint.square(v.location.x_mm, v.location.y_mm, v.location.size_mm,
                                 v.location.yaw_deg)
                for v in self.view.seen
                if not same_block(target.color, loc.x_mm, loc.y_mm, v)
                and off_mm(v, loc.x_mm, loc.y_mm) > size / 2
                and not (whole and too_near_for_two(size, loc.x_mm, loc.y_mm, v))]

    def _gaps(self, size_mm: float) -> list[float]:
        """How far apart the fingers may open for a grasp of a block ``size_mm`` wide,
        widest first."""
        return self.settings.gaps_mm(size_mm)


def _mm(xy: tuple[float, float]) -> str:
    """A place on the table as the progress lines say it: ``(208, -124) mm``."""
    return place_text(xy)


__all__ = ["BIN_PLACES", "BIN_SLOTS_MM", "IN_BIN_MM", "ORDERS", "TILTED_SET_DOWN_MM",
           "BlockOutcome", "PickSortSettings", "PickSorter", "RunReport"]
