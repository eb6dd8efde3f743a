"""How the tag-stacking game works: heights, tolerances and tries (checked on
construction); how a block is taken and carried is pick-and-sort's (``pick``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.units import check_int_range, check_range

__all__ = [
    "StackSettings",
]


@dataclass(frozen=True)
class StackSettings:
    """Heights in mm, tolerances and tries; ``pick``: the grasp's approach, lift, finger
    clearances, speeds and settling (pick-and-sort's settings)."""

    pick: PickSortSettings = field(default_factory=PickSortSettings)
    carry_clear_mm: float = 30.0
    """A carried block's bottom passes this high over the tower's top."""
    release_drop_mm: float = 2.0
    """A block is let go this far above the top it is set on (the descent stops sooner
    where it rests on it)."""
    survey_mm: float = 250.0
    """The survey's camera height over the blocks' tops (a tag cell is 4-5 px there)."""
    look_mm: float = 170.0
    """A closer look's camera height over the top looked at (a cell is 6-8 px)."""
    survey_radius_mm: float = 195.0
    survey_bearings_deg: tuple[float, ...] = (-40.0, 0.0, 40.0)
    """The survey looks at points this far out on these bearings."""
    max_offset_mm: float = 4.0
    """A block seen set down further than this from the tower's axis is placed again."""
    max_tries: int = 3
    """Placements a block gets (the first and re-placements) before the run fails."""
    max_grasps: int = 3
    """Grasps a block gets (closing on nothing counts) before the run fails."""
    max_height_mm: float | None = None
    """The tallest tower built (mm over the table); None: as tall as the arm reaches over."""

    def __post_init__(self) -> None:
        for name, lo, hi in (("carry_clear_mm", 10.0, 150.0), ("release_drop_mm", 0.0, 10.0),
                             ("survey_mm", 100.0, 500.0), ("look_mm", 80.0, 400.0),
                             ("survey_radius_mm", 80.0, 400.0), ("max_offset_mm", 0.5, 20.0)):
            check_range(name, getattr(self, name), lo, hi, "mm")
        if self.max_height_mm is not None:
            check_range("max_height_mm", self.max_height_mm, 10.0, 1000.0, "mm")
        for bearing in self.survey_bearings_deg:
            check_range("survey_bearings_deg", bearing, -120.0, 120.0, "deg")
        check_int_range("max_tries", self.max_tries, 1, 10)
        check_int_range("max_grasps", self.max_grasps, 1, 10)
