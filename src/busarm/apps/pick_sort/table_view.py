"""What the wrist camera has seen of the table: the blocks (merged over several
pictures, looked at again where a picture cut them) and the things that are not blocks.

``TableView.survey`` looks from the survey poses, and again facing whatever a picture's
edge cut; ``look_closer`` turns the camera to face one block before it is taken.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.bins import BIN_RADIUS_MM
from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.arm import Arm
from busarm.errors import ConfigError, UnreachableError
from busarm.perception.locate import BlockLocator, Sighting
from busarm.perception.obstacles import Obstacle, refine
from busarm.vision.camera import CameraSource

__all__ = [
    "CARRY_CLEARANCE_MM",
    "MAX_EXTRA_LOOKS",
    "OVER_THINGS_MM",
    "SAME_BLOCK_MM",
    "TableView",
    "off_mm",
    "same_block",
]


SAME_BLOCK_MM = 20.0
"""Two sightings this close are the same block."""
OVER_THINGS_MM = 100.0
"""A carried block's bottom passes this high over things that are not blocks (a mug is
about 95 mm tall)."""
CARRY_CLEARANCE_MM = 25.0
"""A carry passing this close to such a thing goes over it."""
MAX_EXTRA_LOOKS = 3
"""A survey looks this many more times at most, facing blocks cut by its pictures' edges."""


class TableView:
    """Looks at the table with ``arm``'s wrist ``camera`` (see the module docstring)."""

    def __init__(self, arm: Arm, camera: CameraSource, locator: BlockLocator,
                 bins: Mapping[str, tuple[float, float]], survey_poses: Sequence[Sequence[float]],
                 settings: PickSortSettings, on_step: Callable[[str], None]) -> None:
        self.arm, self.camera, self.locator = arm, camera, locator
        self.bins = dict(bins)
        self.survey_poses = list(survey_poses)
        self.settings = settings
        self.on_step = on_step
        self.clock = arm.clock
        # The last survey's pictures and what was found in each (for reports).
        self.last_survey: list[tuple[npt.NDArray[np.uint8], list[Sighting]]] = []
        # Every block the last survey saw: the neighbours a grasp must keep clear of.
        self.seen: list[Sighting] = []
        # Things seen since the last survey began that are not blocks (cast on the table).
        self.obstacles: list[Footprint] = []
        self.things: list[Obstacle] = []  # the same, as seen (refined by each look)

    def survey(self, facing: Sequence[tuple[float, float]] = ()) -> list[Sighting]:
        """Every block seen from the survey poses, merged (averaged per pose), then from
        poses turned to face what was cut by a picture's edge (the table may reach beyond
        the survey's pictures) and the points ``facing`` (x, y mm: where blocks were
        that the survey may not make out, a cluster of several seen from afar). A block
        seen from several poses keeps its best sighting: whole rather than cut, then the
        one nearest the middle of its picture (in bearing)."""
        seen: list[tuple[tuple[bool, float], Sighting]] = []
        self.last_survey = []
        looked: list[float] = []
        for k, pose in enumerate(self.survey_poses):
            # Things are seen afresh (the last ones still kept off on the way there).
            self._merge(seen, pose, fresh=k == 0)
            looked.append(pose[0])
        wanted = [math.degrees(math.atan2(y, x)) for x, y in facing]
        for _ in range(MAX_EXTRA_LOOKS):
            far = self.settings.look_closer_beyond_deg
            cut = [_bearing_deg(v) for _, v in seen if not v.whole] + wanted
            cut = [b for b in cut if all(abs(b - done) > far for done in looked)]
            if not cut:
                break
            bearing = cut[0]
            looked.append(bearing)
            try:
                pose = self.arm.config.check_joints((bearing, *self.survey_poses[0][1:]))
            except ConfigError:  # the base cannot turn that far
                continue
            self._merge(seen, pose)
        self.on_step("survey")
        self.seen = [sighting for _, sighting in seen]
        return self.seen

    def _merge(self, seen: list[tuple[tuple[bool, float], Sighting]],
               pose: Sequence[float], *, fresh: bool = False) -> None:
        """Look from ``pose`` and merge what is found into ``seen`` (see ``survey``)."""
        image, found = self.look(pose, fresh=fresh)
        self.last_survey.append((image, found))
        for new in found:
            rank = (not new.whole, abs(_bearing_deg(new) - pose[0]))
            # A cut blob's location is rough: it may lie further from the whole one.
            radius = SAME_BLOCK_MM if new.whole else 2 * SAME_BLOCK_MM
            for i, (old_rank, old) in enumerate(seen):
                if same_block(old.color, old.location.x_mm, old.location.y_mm, new,
                               radius if old.whole else 2 * SAME_BLOCK_MM):
                    if rank < old_rank:
                        seen[i] = (rank, new)
                    break
            else:
                seen.append((rank, new))

    def thing_on_the_way(self, start: Sequence[float], end: Sequence[float]) -> bool:
        """Whether a thing that is not a block lies near the way from ``start`` to ``end``
        (x, y mm), taken as the base turns: bearing and radius changing evenly."""
        if not self.obstacles:
            return False
        (r0, a0), (r1, a1) = ((math.hypot(x, y), math.atan2(y, x)) for x, y in (start, end))
        turn = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
        size = self.locator.block_size_mm
        for t in np.linspace(0.0, 1.0, 40):
            r, a = r0 + (r1 - r0) * t, a0 + turn * t
            here = Footprint.square(r * math.cos(a), r * math.sin(a), size, 0.0)
            if any(here.overlaps(o, CARRY_CLEARANCE_MM) for o in self.obstacles):
                return True
        return False

    def rise_over_things(self, end: Sequence[float]) -> None:
        """Straight up over the things that are not blocks first, if one lies on the way
        from where the tool is to ``end`` (x, y mm) and the tool is lower than that."""
        arm, s = self.arm, self.settings
        tool = arm.read_pose()
        over = self.locator.table_z_mm + OVER_THINGS_MM + self.locator.block_size_mm
        if tool.z_mm >= over or not self.thing_on_the_way((tool.x_mm, tool.y_mm), end):
            return
        try:
            arm.move_line(tool.x_mm, tool.y_mm, over, tool.pitch_deg, tool.roll_deg,
                          speed_mm_s=s.line_speed_mm_s)
        except UnreachableError:  # not straight up from here: nearly, joint by joint
            with contextlib.suppress(UnreachableError):
                arm.move_to(tool.x_mm, tool.y_mm, over, tool.pitch_deg, tool.roll_deg,
                            speed_deg_s=s.joint_speed_deg_s)

    def look(self, pose: Sequence[float], *, fresh: bool = False
             ) -> tuple[npt.NDArray[np.uint8], list[Sighting]]:
        """The blocks seen from ``pose`` (frames averaged), and the last picture; the
        things that are not blocks seen there refine those seen before (``fresh``: replace
        them)."""
        s, arm = self.settings, self.arm
        seen_from = arm.kin.fk(pose)
        self.rise_over_things((seen_from.x_mm, seen_from.y_mm))
        arm.move_joints(pose, speed_deg_s=s.joint_speed_deg_s)
        self.clock.sleep(s.settle_s)
        pictures = [(self.camera.read().image, arm.read_joints_deg())
                    for _ in range(s.survey_frames)]
        # Things that are not blocks, for the fingers and pushes to keep off.
        found = self.locator.locate_averaged(pictures)
        self.things = refine([] if fresh else self.things, self.locator.obstacles(
            *pictures[-1], [(x, y, 2 * BIN_RADIUS_MM) for x, y in self.bins.values()],
            found))
        self.obstacles = [Footprint(o.corners) for o in self.things]
        return pictures[-1][0], found

    def look_closer(self, target: Sighting, *, always: bool = False) -> Sighting | None:
        """The block as seen with the camera turned to face it, if the survey saw it more
        than ``look_closer_beyond_deg`` off to the side or cut by the picture's edge (or
        ``always``); else ``target`` itself. None if it is not seen whole there when
        looked at again."""
        s, arm = self.settings, self.arm
        x, y = target.location.x_mm, target.location.y_mm
        bearing = _bearing_deg(target)
        pose = min(self.survey_poses, key=lambda p: abs(bearing - p[0]))
        if target.whole and abs(bearing - pose[0]) <= s.look_closer_beyond_deg and not always:
            return target
        try:
            facing = arm.config.check_joints((bearing, *pose[1:]))
        except ConfigError:  # the base cannot turn that far: the survey's sighting it is
            return target if target.whole else None
        image, found = self.look(facing)
        self.last_survey = [(image, found)]
        self.on_step("closer")
        # The neighbours a grasp keeps clear of, as seen from here where seen whole.
        self.seen = [v for v in found if v.whole] + [
            old for old in self.seen if not any(
                v.whole and same_block(old.color, old.location.x_mm, old.location.y_mm, v,
                                        (1 if old.whole else 3) * SAME_BLOCK_MM)
                for v in found)]

        # Cut by the picture's edge, it was seen only in part (or a group of touching
        # blocks was): the nearest whole block of its colour about there is the one.
        radius = (2 if target.whole else 3) * SAME_BLOCK_MM
        same = sorted((v for v in found if v.whole and not self.in_a_bin(v)
                       and same_block(target.color, x, y, v, radius)),
                      key=lambda v: off_mm(v, x, y))
        return same[0] if same else None

    def in_a_bin(self, sighting: Sighting) -> bool:
        return any(math.hypot(sighting.location.x_mm - bx, sighting.location.y_mm - by)
                   < BIN_RADIUS_MM for bx, by in self.bins.values())


def same_block(color: str, x_mm: float, y_mm: float, seen: Sighting,
                radius_mm: float = SAME_BLOCK_MM) -> bool:
    """Whether ``seen`` is the block of ``color`` seen at (x, y) before."""
    return seen.color == color and off_mm(seen, x_mm, y_mm) < radius_mm


def off_mm(seen: Sighting, x_mm: float, y_mm: float) -> float:
    return math.hypot(seen.location.x_mm - x_mm, seen.location.y_mm - y_mm)


def _bearing_deg(seen: Sighting) -> float:
    return math.degrees(math.atan2(seen.location.y_mm, seen.location.x_mm))
