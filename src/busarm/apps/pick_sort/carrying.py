"""Carrying a held block: over to its bin's next place (or to a spot on the table), high
enough to pass what stands on the way, down, and let go there."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass

from busarm.apps.pick_sort.bins import BinPlaces
from busarm.apps.pick_sort.grasp import GraspPlan, GraspPlanner
from busarm.apps.pick_sort.gripping import lower_and_release, still_holding
from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.apps.pick_sort.table_view import OVER_THINGS_MM, TableView
from busarm.arm import Arm
from busarm.arm.motion import TIME_OPTIMAL
from busarm.errors import UnreachableError

__all__ = ["Carrier"]


@dataclass
class Carrier:
    """Carries what ``arm`` holds for a pick-and-sort run: into the bins' places
    (``places``), clear of what ``view`` knows stands on the table (at ``table_z_mm``).
    ``stepped`` hears each step ended; ``released`` is called as soon as the fingers have
    let the block go (not before: stopped while opening, they still hold it)."""

    arm: Arm
    settings: PickSortSettings
    view: TableView
    places: BinPlaces
    planner: GraspPlanner
    table_z_mm: float
    stepped: Callable[[str], None]
    released: Callable[[], None]

    def to_bin(self, place: str, plan: GraspPlan, size_mm: float
               ) -> tuple[float, float] | None:
        """Carry the block held at ``plan``'s lift to the bin ``place`` and let it go
        there; where it was put, or None if it slipped out on the way (the fingers opened
        again)."""
        arm, s = self.arm, self.settings
        z0, gap = self.table_z_mm, plan.gap_mm
        carry, release = self.places.heights_mm(place, size_mm, s.carry_mm, s.release_mm)
        carry_z = z0 + carry
        bx, by, _, square = self.places.next_spot(place, self.view.obstacles, gap,
                                                  z0 + release, size_mm)
        release_z = z0 + self.places.release_mm(place, release, square, gap)
        carry_z = self._carry(plan, (bx, by), carry_z, square)
        self.stepped("carry")
        if not still_holding(arm):
            self.released()
            arm.open_gripper(wait=False, gap_mm=gap)
            self.places.take_back(place)
            return None
        # (Resting on something in the bin on the way down, it is let go there.)
        # Lowered no faster than the descent (unwatched: what it lands on stops it).
        lower_and_release(arm, (bx, by, release_z), -90.0, square, gap, s.line_speed_mm_s,
                          profile=TIME_OPTIMAL,
                          free_mm=size_mm + 2 * s.min_finger_clearance_mm)
        self.released()
        self.stepped("release")
        # Not waited for: the next move (a survey's) takes over from its last waypoint.
        arm.move_line(bx, by, carry_z, -90.0, square, speed_mm_s=s.carry_speed_mm_s,
                      profile=TIME_OPTIMAL, wait=False)
        return bx, by

    def set_down(self, plan: GraspPlan, spot: tuple[float, float], gap_mm: float) -> None:
        """Set the block held at ``plan``'s lift down at ``spot`` straight down, let go,
        and rise."""
        arm, s = self.arm, self.settings
        z0 = self.table_z_mm
        roll = self.planner.roll_squared_deg(*spot, 0.0)
        carry_z = self._carry(plan, spot, z0 + s.carry_mm, roll)
        lower_and_release(arm, (*spot, z0 + s.release_mm), -90.0, roll, gap_mm,
                          s.line_speed_mm_s)
        self.released()
        arm.move_line(*spot, carry_z, -90.0, roll, speed_mm_s=s.line_speed_mm_s)

    def _carry(self, plan: GraspPlan, end: tuple[float, float], carry_z: float,
               end_roll_deg: float) -> float:
        """Carry the block held at ``plan``'s lift to over ``end`` (x, y mm), straight
        down there at ``end_roll_deg`` (held tilted: at its own roll, turned only
        there), at ``carry_z`` or, past a thing that is not a block (of a height not
        known), over the tallest cup a desk has; the height used. Carried higher than
        its lift (over a second layer), it rises there first."""
        arm, s = self.arm, self.settings
        past_a_thing = self.view.thing_on_the_way(plan.lift[:2], end)
        if past_a_thing:
            carry_z = max(carry_z, self.table_z_mm + OVER_THINGS_MM + self.view.tallest_mm / 2)
        if past_a_thing or carry_z > plan.lift[2]:
            # (Not straight up from here: it rises on the way over.)
            with contextlib.suppress(UnreachableError):
                arm.move_line(*plan.lift[:2], carry_z, plan.pitch_deg, plan.roll_deg,
                              speed_mm_s=s.carry_speed_mm_s, profile=TIME_OPTIMAL)
        if plan.pitch_deg != -90.0:
            # Held tilted, the block is swung over at the roll it was taken at and rolled
            # square to the bin only there: rolled while swung, it twisted out of the
            # fingers (two blocks of seed 19 of the random bench; the pitch may change).
            # (Rolled on the way down instead, the cycles were slower: lines turn at
            # MAX_TURN_SPEED_DEG_S.)
            with contextlib.suppress(UnreachableError):
                arm.move_to(*end, carry_z, -90.0, plan.roll_deg,
                            speed_deg_s=s.joint_speed_deg_s)
        arm.move_to(*end, carry_z, -90.0, end_roll_deg, speed_deg_s=s.joint_speed_deg_s)
        return carry_z
