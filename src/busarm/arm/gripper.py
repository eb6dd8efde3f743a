"""The gripper's state as a person means it: open, closed, or holding something.

One rule for every interface (``busarm arm pose``, ``arm gripper``, the dashboard): the
servo's ``MOVE_TIME_READ`` returns the position it was last told, so a gripper told to a
position narrower than where it stands (by ``HOLD_MIN_PULSES`` or more, twice the
vendor's 0.2 deg accuracy) while its fingers stand apart (short of closed by more than
the config's ``holding_margin_pulses``) is pressing on something between its fingers:
it holds it. A grip closes until the fingers stop on the block, then eases to a hold
``HOLD_SQUEEZE_PULSES`` inside where they stopped (``Arm.grip``): the servo's torque rises
with its position error, so the hold presses lightly and does not cook the servo on a
long carry, and the rule still reads it as holding.
Pure: the readings come in, nothing is read here (``Arm.read_gripper_state`` reads them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from busarm.arm.config import GripperConfig

HOLD_SQUEEZE_PULSES = 3
"""A hold is told this far inside where the fingers stopped on the block (closing at
full torque): a squeeze of about a quarter of stall torque on the twin's servo, whose
friction keeps a 20 g block through the base's starts and turns."""
HOLD_MIN_PULSES = 2
"""Told at least this far inside where it stands (and the fingers apart): pressing on
something. Twice the vendor's servo accuracy (0.2 deg, about 1 pulse)."""

GripperStateName = Literal["open", "closed", "holding"]


@dataclass(frozen=True)
class GripperState:
    """The gripper now: ``state``, the fingers' gap in mm and the readings it came from."""

    state: GripperStateName
    gap_mm: float
    """Between the fingers, 0 (closed) .. the config's widest (open)."""
    position_pulses: int
    target_pulses: int | None
    """The position it was last told (``MOVE_TIME_READ``); None if not read."""
    torque_on: bool | None = None
    """None if not read."""

    @property
    def is_holding(self) -> bool:
        return self.state == "holding"

    @property
    def short_of_target_pulses(self) -> int:
        """How far it stopped from where it was told (0 if not known)."""
        return 0 if self.target_pulses is None else abs(self.target_pulses - self.position_pulses)


def gripper_state(
    gripper: GripperConfig, position_pulses: int, target_pulses: int | None,
    torque_on: bool | None = None,
) -> GripperState:
    """The gripper's state from its position, the position it was last told and its torque.

    Holding: told to close at least ``HOLD_MIN_PULSES`` further than it stands while it
    stands short of closed by more than ``holding_margin_pulses`` (pressing on
    something), torque not off (a limp gripper holds nothing). Else closed within the
    margin of ``closed_pulses``, else open.
    """
    closing = 1 if gripper.closed_pulses >= gripper.open_pulses else -1
    gap = min(gripper.gap_mm_at(position_pulses), gripper.widest_gap_mm)
    apart = closing * (gripper.closed_pulses - position_pulses) > gripper.holding_margin_pulses
    state: GripperStateName
    if (target_pulses is not None and torque_on is not False and apart
            and closing * (target_pulses - position_pulses) >= HOLD_MIN_PULSES):
        state = "holding"
    elif not apart:
        state = "closed"
    else:
        state = "open"
    return GripperState(state, gap, position_pulses, target_pulses, torque_on)


__all__ = ["HOLD_MIN_PULSES", "HOLD_SQUEEZE_PULSES", "GripperState", "GripperStateName",
           "gripper_state"]
