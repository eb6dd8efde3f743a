"""How pick-and-sort works: heights, speeds, and how hard it tries (checked on
construction)."""

from __future__ import annotations

from dataclasses import dataclass

from busarm.errors import ConfigError
from busarm.units import check_int_range, check_range

__all__ = [
    "ORDERS",
    "PickSortSettings",
]


ORDERS = ("nearest", "colors")


@dataclass(frozen=True)
class PickSortSettings:
    """Heights in mm above the table, speeds, and how hard to try."""

    approach_mm: float = 60.0
    carry_mm: float = 75.0
    release_mm: float = 45.0
    """The fingertips let a block go this high over the table; in a tray lower where it
    would land with little room, higher where a pad stands over a taller block
    (``busarm.apps.pick_sort.bins.BinPlaces.release_mm``)."""
    finger_clearance_mm: float = 10.0
    """Opening beyond the block on each side when grasping (its yaw is known to a few deg)."""
    min_finger_clearance_mm: float = 3.0
    """Between close neighbours the fingers open down to this beyond the block a side."""
    max_nudges: int = 2
    """Pushes a boxed-in block gets before it is skipped."""
    line_speed_mm_s: float = 200.0
    """The guarded descent's peak speed (its contact watch is tuned to it), the lowering
    into a bin's and, from it, the pushes'."""
    carry_speed_mm_s: float = 300.0
    """The lift and the rise from a bin cruise at most this fast, time-optimal within the
    tool's acceleration (``busarm.arm.motion.LINE_ACCEL_MM_S2``) and the joints' speeds
    (the lowering into a bin goes no faster than the descent: ``line_speed_mm_s``)."""
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
    """Before a picture the arm stands still for, this long at most; and a push's waits."""
    pause_above_c: float = 70.0
    """A servo this hot pauses the run (arm at home, gripper open) ..."""
    resume_below_c: float = 60.0
    """... until every servo is this cool again (LX servos cut out at 85 C by default)."""
    min_supply_v: float = 6.8
    """A supply this low stops the run cleanly (LX servos go silent near 6 V)."""
    max_pause_s: float = 600.0

    def gaps_mm(self, block_mm: float) -> list[float]:
        """How far apart the fingers may open for a grasp of a block ``block_mm`` wide,
        widest first (down to the least clearance, between close neighbours)."""
        c, least = self.finger_clearance_mm, self.min_finger_clearance_mm
        return [block_mm + 2 * k for k in (c, (c + least) / 2, least)]

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
                             ("carry_speed_mm_s", 10.0, 400.0),
                             ("look_closer_beyond_deg", 0.0, 180.0),
                             ("joint_speed_deg_s", 10.0, 180.0), ("settle_s", 0.0, 5.0)):
            check_range(name, getattr(self, name), lo, hi)
        for name, ilo, ihi in (("max_attempts", 1, 10), ("survey_frames", 1, 20),
                               ("max_nudges", 0, 10)):
            check_int_range(name, getattr(self, name), ilo, ihi)
