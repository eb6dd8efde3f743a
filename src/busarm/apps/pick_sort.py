"""Pick-and-sort: look at the table, pick each coloured block, put it in its colour's bin.

One cycle per block, the same code on the twin and on hardware:

1. survey: the camera looks from one or more survey poses; blocks are located in mm
   (``BlockLocator``, averaged over frames) and merged across poses;
2. choose: reachable blocks of a colour that has a bin, nearest to the base first;
   unknown colours and blocks out of reach are skipped with the reason;
3. grasp: above the block at ``approach_mm``, the wrist roll squared to its faces, a
   straight descent to the grasp height, close, and the gripper's position says whether
   it holds something (no holding, no carrying: the block is looked for again);
4. carry: straight up, over the bin at ``carry_mm``, down, open, up;
5. verify: the next survey must not see the block where it was picked.

Any exception or Ctrl+C leaves the arm stopped and holding (``Arm``'s guard), the
gripper's last state known from its reading.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from busarm.apps.locate import BlockLocator, Sighting
from busarm.arm.arm import Arm
from busarm.errors import ConfigError, ServoFaultError, UnreachableError
from busarm.vision.camera import CameraSource

SAME_BLOCK_MM = 20.0
"""Two sightings this close are the same block."""
BIN_RADIUS_MM = 45.0
"""A block seen this close to a bin's centre is in that bin."""
BIN_SLOTS_MM = ((-20.0, -20.0), (20.0, -20.0), (-20.0, 20.0), (20.0, 20.0))
"""Where blocks go in a bin (from its centre): 2 x 2, 10 mm apart (the camera sees them
apart when it checks the bin)."""


@dataclass(frozen=True)
class PickSortSettings:
    """Heights in mm above the table, speeds, and how hard to try."""

    approach_mm: float = 60.0
    carry_mm: float = 75.0
    release_mm: float = 45.0
    finger_clearance_mm: float = 10.0
    """Opening beyond the block on each side when grasping (its yaw is known to a few deg)."""
    line_speed_mm_s: float = 200.0
    joint_speed_deg_s: float = 180.0
    max_attempts: int = 2
    survey_frames: int = 2
    settle_s: float = 0.2
    pause_above_c: float = 70.0
    """A servo this hot pauses the run (arm at home, gripper open) ..."""
    resume_below_c: float = 60.0
    """... until every servo is this cool again (LX servos cut out at 85 C by default)."""
    min_supply_v: float = 6.8
    """A supply this low stops the run cleanly (LX servos go silent near 6 V)."""
    max_pause_s: float = 600.0

    def __post_init__(self) -> None:
        if not self.resume_below_c < self.pause_above_c:
            raise ConfigError(f"resume_below_c {self.resume_below_c:g} must be below "
                              f"pause_above_c {self.pause_above_c:g}")
        for name, lo, hi in (("approach_mm", 20.0, 200.0), ("carry_mm", 30.0, 250.0),
                             ("finger_clearance_mm", 2.0, 40.0), ("pause_above_c", 40.0, 84.0),
                             ("resume_below_c", 30.0, 83.0), ("min_supply_v", 4.5, 12.0),
                             ("max_pause_s", 0.0, 3600.0),
                             ("release_mm", 20.0, 200.0), ("line_speed_mm_s", 10.0, 400.0),
                             ("joint_speed_deg_s", 10.0, 180.0), ("settle_s", 0.0, 5.0)):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
                raise ConfigError(f"{name} = {value!r} is out of range {lo:g}..{hi:g}")
        for name, lo, hi in (("max_attempts", 1, 10), ("survey_frames", 1, 20)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
                raise ConfigError(f"{name} = {value!r} is out of range {lo}..{hi}")


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

    def to_dict(self) -> dict[str, object]:
        return {"color": self.color, "found_mm": [round(v, 1) for v in self.found_mm],
                "outcome": self.outcome, "reason": self.reason,
                "placed_mm": None if self.placed_mm is None else
                [round(v, 1) for v in self.placed_mm],
                "attempts": self.attempts, "seconds": round(self.seconds, 2)}


@dataclass
class RunReport:
    blocks: list[BlockOutcome] = field(default_factory=list)
    seconds: float = 0.0

    def totals(self) -> dict[str, object]:
        done = [b for b in self.blocks if b.outcome == "sorted"]
        cycle = float(np.median([b.seconds for b in done])) if done else math.nan
        return {"sorted": len(done),
                "failed": sum(b.outcome == "failed" for b in self.blocks),
                "skipped": sum(b.outcome == "skipped" for b in self.blocks),
                "moved": sum(b.outcome == "moved" for b in self.blocks),
                "median_cycle_s": round(cycle, 2), "seconds": round(self.seconds, 1)}


class PickSorter:
    """Sorts the blocks the camera sees into ``bins`` (colour -> (x, y) mm)."""

    def __init__(self, arm: Arm, camera: CameraSource, locator: BlockLocator,
                 bins: dict[str, tuple[float, float]], *,
                 survey_poses: Sequence[Sequence[float]] | None = None,
                 settings: PickSortSettings | None = None,
                 progress: Callable[[str], None] | None = None,
                 on_step: Callable[[str], None] | None = None,
                 on_pick: Callable[[Sighting], None] | None = None) -> None:
        self.arm = arm
        self.camera = camera
        self.locator = locator
        self.bins = dict(bins)
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
        # The last survey's pictures and what was found in each (for reports).
        self.last_survey: list[tuple[npt.NDArray[np.uint8], list[Sighting]]] = []
        self._grasp_z = locator.table_z_mm + locator.block_size_mm / 2
        self._placed: dict[str, int] = {}

    # ------------------------------------------------------------------ seeing

    def survey(self) -> list[Sighting]:
        """Every block seen from the survey poses, merged (averaged per pose)."""
        s = self.settings
        seen: list[Sighting] = []
        self.last_survey = []
        for pose in self.survey_poses:
            self.arm.move_joints(pose, speed_deg_s=s.joint_speed_deg_s)
            time.sleep(s.settle_s)
            pictures = []
            for _ in range(s.survey_frames):
                image = self.camera.read().image
                pictures.append((image, self.arm.read_joints_deg()))
            found = self.locator.locate_averaged(pictures)
            self.last_survey.append((pictures[-1][0], found))
            for new in found:
                if not any(_near(new, old) for old in seen):
                    seen.append(new)
        self.on_step("survey")
        return seen

    # ------------------------------------------------------------------ moving

    def grasp_roll_deg(self, x_mm: float, y_mm: float, yaw_deg: float) -> float:
        """The wrist roll that squares the fingers (closing along the tool's y) to a block
        at ``yaw_deg`` (modulo 90), the smallest such turn."""
        kin = self.arm.kin

        def finger_axis_deg(roll: float) -> float:
            m = kin.fk_matrix(kin.ik_best(x_mm, y_mm, self._grasp_z, -90.0, roll))
            return math.degrees(math.atan2(m[1, 1], m[0, 1]))

        a0, a1 = finger_axis_deg(0.0), finger_axis_deg(10.0)
        sign = 1.0 if (a1 - a0 + 180.0) % 360.0 - 180.0 > 0 else -1.0
        return ((yaw_deg - a0) * sign + 45.0) % 90.0 - 45.0

    def _still_holding(self) -> bool:
        """Whether the gripper still stands short of closed (a dropped block lets it close)."""
        g = self.arm.config.gripper
        return abs(self.arm.read_gripper_pulses() - g.closed_pulses) > g.holding_margin_pulses

    def check_servos(self) -> None:
        """Pause while a servo is too hot (arm at home, gripper open); a supply too low for
        the servos stops the run with ServoFaultError."""
        s, arm = self.settings, self.arm
        deadline = time.monotonic() + s.max_pause_s
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
            if time.monotonic() > deadline:
                raise ServoFaultError(f"servo {hot.servo_id} still at {hot.temp_c} C after "
                                      f"{s.max_pause_s:g} s of rest", hot.servo_id)
            time.sleep(2.0)

    def _bin_spot(self, color: str) -> tuple[float, float]:
        """Where in the bin the next block of ``color`` goes: four places side by side
        (squared to the bin, so they fit), then on top of the first ones again."""
        bx, by = self.bins[color]
        k = self._placed.get(color, 0)
        self._placed[color] = k + 1
        dx, dy = BIN_SLOTS_MM[k % len(BIN_SLOTS_MM)]
        return bx + dx, by + dy

    def pick_and_place(self, target: Sighting) -> tuple[bool, str, tuple[float, float] | None]:
        """One grasp-carry-release cycle; (holding was seen, why not, where it was put)."""
        arm, s = self.arm, self.settings
        z0 = self.locator.table_z_mm
        x, y = target.location.x_mm, target.location.y_mm
        roll = self.grasp_roll_deg(x, y, target.location.yaw_deg)
        # Open no wider than the block needs: wide-open fingers would hit a neighbour.
        gap = self.locator.block_size_mm + 2 * s.finger_clearance_mm
        arm.open_gripper(wait=False, gap_mm=gap)
        arm.move_to(x, y, z0 + s.approach_mm, -90.0, roll, speed_deg_s=s.joint_speed_deg_s)
        arm.open_gripper(gap_mm=gap)
        self.on_step("above")
        arm.move_line(x, y, self._grasp_z, -90.0, roll, speed_mm_s=s.line_speed_mm_s)
        grip = arm.grip()
        self.on_step("grip")
        if not grip.is_holding:
            arm.open_gripper(wait=False, gap_mm=gap)
            arm.move_line(x, y, z0 + s.approach_mm, -90.0, roll, speed_mm_s=s.line_speed_mm_s)
            return False, f"the gripper closed on nothing ({grip.position_pulses} pulses)", None
        arm.move_line(x, y, z0 + s.carry_mm, -90.0, roll, speed_mm_s=s.line_speed_mm_s)
        self.on_step("lift")
        bx, by = self._bin_spot(target.color)
        square = self.grasp_roll_deg(bx, by, 0.0)  # the block's faces along the bin's walls
        arm.move_to(bx, by, z0 + s.carry_mm, -90.0, square, speed_deg_s=s.joint_speed_deg_s)
        self.on_step("carry")
        if not self._still_holding():
            arm.open_gripper(wait=False, gap_mm=gap)
            self._placed[target.color] -= 1
            return False, "the block slipped out during the carry", None
        arm.move_line(bx, by, z0 + s.release_mm, -90.0, square, speed_mm_s=s.line_speed_mm_s)
        arm.open_gripper(gap_mm=gap)
        self.on_step("release")
        arm.move_line(bx, by, z0 + s.carry_mm, -90.0, square, speed_mm_s=s.line_speed_mm_s)
        return True, "", (bx, by)

    def verify_bins(self, report: RunReport) -> None:
        """Look into each bin a block was put in: a block reported sorted but not found
        there (it bounced out, say) is reported failed instead."""
        s, arm = self.settings, self.arm
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
            arm.move_joints(pose, speed_deg_s=s.joint_speed_deg_s)
            time.sleep(s.settle_s)
            pictures = [(self.camera.read().image, arm.read_joints_deg())
                        for _ in range(s.survey_frames)]
            inside = [v for v in self.locator.locate_averaged(pictures) if v.color == color
                      and math.hypot(v.location.x_mm - bx, v.location.y_mm - by) < BIN_RADIUS_MM]
            for missing in sorted_here[len(inside):]:
                missing.outcome = "failed"
                missing.reason = "not in its bin when the bins were checked (it fell out?)"
                self.progress(f"{color} block from {missing.found_mm}: not in its bin")

    # ------------------------------------------------------------------ the job

    def run(self, *, max_cycles: int = 50) -> RunReport:
        """Sort until the table shows no block that can be sorted; the whole report."""
        start = time.monotonic()
        report = RunReport()
        for _ in range(max_cycles):
            seen = self.survey()
            for outcome in report.blocks:
                # Missed, and no longer where it was: someone moved it. It is looked for
                # afresh (a new record if it is seen elsewhere).
                if outcome.outcome == "pending" and outcome.attempts and not any(
                        s.color == outcome.color and math.hypot(
                            s.location.x_mm - outcome.found_mm[0],
                            s.location.y_mm - outcome.found_mm[1]) < SAME_BLOCK_MM
                        for s in seen):
                    outcome.outcome = "moved"
                    outcome.reason = "not where it was after a missed grasp: it was moved"
            candidates: list[tuple[float, Sighting, BlockOutcome]] = []
            for sighting in seen:
                if self._in_a_bin(sighting):
                    continue  # sorted already
                outcome = self._outcome_for(sighting, report)
                if outcome.outcome != "pending":
                    continue
                reason = self._why_not(sighting)
                if reason:
                    outcome.outcome, outcome.reason = "skipped", reason
                    self.progress(f"skip {sighting.color} at {outcome.found_mm}: {reason}")
                    continue
                distance = math.hypot(sighting.location.x_mm, sighting.location.y_mm)
                candidates.append((distance, sighting, outcome))
            if not candidates:
                break
            _, target, outcome = min(candidates, key=lambda c: c[0])
            self.check_servos()
            self.on_pick(target)
            t0 = time.monotonic()
            outcome.attempts += 1
            held, why, placed = self.pick_and_place(target)
            outcome.seconds += time.monotonic() - t0
            if held:
                outcome.outcome, outcome.placed_mm = "sorted", placed
                self.progress(f"{target.color} from {outcome.found_mm} into its bin "
                              f"({outcome.seconds:.1f} s)")
            elif outcome.attempts >= self.settings.max_attempts:
                outcome.outcome, outcome.reason = "failed", why
                self.progress(f"{target.color} at {outcome.found_mm}: gave up: {why}")
            else:
                self.progress(f"{target.color} at {outcome.found_mm}: {why}; looking again")
        for outcome in report.blocks:
            if outcome.outcome == "pending":
                outcome.outcome, outcome.reason = "failed", "not seen again"
        self.verify_bins(report)
        report.seconds = time.monotonic() - start
        return report

    def _in_a_bin(self, sighting: Sighting) -> bool:
        return any(math.hypot(sighting.location.x_mm - bx, sighting.location.y_mm - by)
                   < BIN_RADIUS_MM for bx, by in self.bins.values())

    def _outcome_for(self, sighting: Sighting, report: RunReport) -> BlockOutcome:
        """The record of this block: one already made where it was seen, or a new one."""
        for outcome in report.blocks:
            if outcome.color == sighting.color and math.hypot(
                    outcome.found_mm[0] - sighting.location.x_mm,
                    outcome.found_mm[1] - sighting.location.y_mm) < SAME_BLOCK_MM:
                if outcome.outcome == "sorted":
                    # Sorted, yet seen where it was: it did not go (a slip). Try again.
                    outcome.outcome, outcome.placed_mm = "pending", None
                return outcome
        outcome = BlockOutcome(sighting.color, (sighting.location.x_mm, sighting.location.y_mm))
        report.blocks.append(outcome)
        return outcome

    def _why_not(self, sighting: Sighting) -> str:
        if sighting.color not in self.bins:
            return f"no bin for {sighting.color}"
        if not sighting.top_down:
            return sighting.reason or "out of reach of a top-down grasp"
        try:
            self.arm.kin.ik_best(sighting.location.x_mm, sighting.location.y_mm,
                                 self.locator.table_z_mm + self.settings.approach_mm, -90.0)
        except UnreachableError as exc:
            return f"cannot approach from above: {exc}"
        return ""


def _near(a: Sighting, b: Sighting) -> bool:
    return a.color == b.color and math.hypot(a.location.x_mm - b.location.x_mm,
                                             a.location.y_mm - b.location.y_mm) < SAME_BLOCK_MM
