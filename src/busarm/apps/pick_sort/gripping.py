"""The gripper's part of taking a block and setting it down, shared by the jobs that do
(pick-and-sort on the table, the mobile robot's picks): the straight descent watched for
contact, the squeeze and the reading that says whether it holds, the release."""

from __future__ import annotations

from collections.abc import Callable

from busarm.apps.pick_sort.grasp import GraspPlan
from busarm.arm import Arm
from busarm.errors import BusArmError, ContactError, MotionTimeoutError
from busarm.units import place_text

__all__ = [
    "RELEASE_POLL_S",
    "RELEASE_SETTLE_S",
    "descend_and_grip",
    "lower_and_release",
    "still_holding",
    "stop_and_read_gripper",
]


RELEASE_SETTLE_S = 0.3
"""Before letting go, the arm stands still for this long at most ..."""
RELEASE_POLL_S = 0.02
"""... its joints read this often until two readings agree."""


def still_holding(arm: Arm) -> bool:
    """Whether the gripper still holds its block (``Arm.check_hold``: a dropped block
    lets the fingers reach the hold they were told)."""
    return arm.check_hold()


def descend_and_grip(arm: Arm, plan: GraspPlan, speed_mm_s: float, *,
                     profile: str = "min_jerk",
                     on_squeeze: Callable[[], None] = lambda: None,
                     on_step: Callable[[str], None] = lambda _: None) -> str:
    """From ``plan.above`` with the fingers ``plan.gap_mm`` apart: straight down to the
    grasp, watched for contact, and close (``on_squeeze()`` just before, ``on_step("grip")``
    once closed). "" when the gripper holds something; else why not, the fingers opened
    again (and, closed on nothing, the tool back at ``plan.above``); ``profile``: the
    descent's (``busarm.arm.motion``), at peak ``speed_mm_s``. ContactError if a
    contact left the arm stopped where it touched (it could not back off)."""
    pitch, roll = plan.pitch_deg, plan.roll_deg
    try:  # watched: fingers landing on something stop, back off, and try again later
        arm.move_line_guarded(*plan.grasp, pitch, roll, speed_mm_s=speed_mm_s,
                              profile=profile)
    except ContactError as exc:
        if not exc.backed_off:
            raise  # stopped and holding where it touched: not for a retry
        arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
        return (f"blocked on the way down at {place_text(exc.tool_mm)} "
                f"({exc.joint} stopped short): backed off")
    on_squeeze()
    grip = arm.grip()
    on_step("grip")
    if not grip.is_holding:
        arm.open_gripper(wait=False, gap_mm=plan.gap_mm)
        arm.move_line(*plan.above, pitch, roll, speed_mm_s=speed_mm_s)
        return f"the gripper closed on nothing ({grip.position_pulses} pulses)"
    return ""


def lower_and_release(arm: Arm, point_mm: tuple[float, float, float], pitch_deg: float,
                      roll_deg: float, gap_mm: float, speed_mm_s: float, *,
                      profile: str = "min_jerk", free_mm: float | None = None) -> None:
    """Straight down to ``point_mm`` (stopping where the block rests on something on the
    way), then open the fingers ``gap_mm`` apart (``free_mm``: waited for only until
    they are that far apart, the block free)."""
    try:
        arm.move_line(*point_mm, pitch_deg, roll_deg, speed_mm_s=speed_mm_s, profile=profile)
    except MotionTimeoutError:  # it rests on something: let go there
        arm.stop()
    # Let go from rest: a block let go while the arm still closes its last degree is
    # thrown a few mm (in the twin, out to a tray's corner).
    arm.settled_joints_deg(timeout_s=RELEASE_SETTLE_S, poll_s=RELEASE_POLL_S)
    arm.open_gripper(gap_mm=gap_mm, until_gap_mm=free_mm)


def stop_and_read_gripper(arm: Arm, holding: str | None, open_beyond_mm: float) -> str:
    """Stop ``arm`` (a Ctrl+C between moves has stopped nothing yet); what the gripper
    holds, judged from its position read back and the block it last took (``holding``:
    its colour); fingers further apart than ``open_beyond_mm`` are open."""
    g = arm.config.gripper
    try:
        arm.stop()
        pulses = arm.read_gripper_pulses()
    except (BusArmError, OSError) as exc:  # the port itself may be what failed
        return f"unknown: the bus did not answer ({exc})"
    gap_mm = g.gap_mm_at(pulses)
    said = f"{gap_mm:.0f} mm apart, {pulses} pulses"
    if abs(pulses - g.closed_pulses) <= g.holding_margin_pulses:
        lost = f", the {holding} block lost" if holding else ""
        return f"closed on nothing{lost} ({said})"
    if gap_mm > open_beyond_mm:
        return f"open ({said})"
    # Fingers a block's width apart: the block it took (kept until the gripper has opened
    # past it), or none it knows of.
    if holding:
        return f"holding a {holding} block ({said})"
    return f"nearly closed, on no block it took ({said})"
