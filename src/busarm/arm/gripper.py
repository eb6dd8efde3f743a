"""The gripper's state as a person means it: open, closed, or holding something.

One rule for every interface (``busarm arm pose``, ``arm gripper``, the dashboard): the
servo's ``MOVE_TIME_READ`` returns the position it was last told, so a gripper told to a
position narrower than where it stands, by more than the config's
``holding_margin_pulses``, has stalled on something between its fingers: it holds it.
Pure: the readings come in, nothing is read here (``Arm.read_gripper_state`` reads them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from busarm.arm.config import GripperConfig

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

    Holding: told to close further than it stands by more than ``holding_margin_pulses``
    (stalled on something), torque not off (a limp gripper holds nothing). Else closed
    within the margin of ``closed_pulses``, else open.
    """
    closing = 1 if gripper.closed_pulses >= gripper.open_pulses else -1
    gap = min(gripper.gap_mm_at(position_pulses), gripper.widest_gap_mm)
    state: GripperStateName
    if (target_pulses is not None and torque_on is not False
            and closing * (target_pulses - position_pulses) > gripper.holding_margin_pulses):
        state = "holding"
    elif closing * (gripper.closed_pulses - position_pulses) <= gripper.holding_margin_pulses:
        state = "closed"
    else:
        state = "open"
    return GripperState(state, gap, position_pulses, target_pulses, torque_on)


__all__ = ["GripperState", "GripperStateName", "gripper_state"]
