"""What the wrist camera has seen of the table: the blocks (merged over several
pictures, looked at again where a picture cut them) and the things that are not blocks.

``TableView.survey`` looks from the survey poses, and again facing whatever a picture's
edge cut; ``look_closer`` turns the camera to face one block before it is taken.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.bins import BIN_RADIUS_MM, BIN_SEEN_MM
from busarm.apps.pick_sort.footprint import Footprint
from busarm.apps.pick_sort.look_poses import look_pose
from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.arm import Arm
from busarm.errors import ConfigError, UnreachableError
from busarm.perception.locate import BlockLocator, NotBlock, Sighting
from busarm.perception.obstacles import Obstacle, refine
from busarm.perception.shape import (
    CUBE_SIDES_MM,
    HEIGHT_TOLERANCE,
    Shape,
    judge,
    nearest_other_mm,
)
from busarm.units import place_text
from busarm.vision.camera import CameraSource

__all__ = [
    "CARRY_CLEARANCE_MM",
    "CROWDED_LOOKS",
    "MAX_EXTRA_LOOKS",
    "OBLIQUE_CAMERA_MM",
    "OBLIQUE_TILT_DEG",
    "OVER_CAMERA_MM",
    "OVER_THINGS_MM",
    "OVER_TILT_DEG",
    "SAME_BLOCK_MM",
    "SECOND_VIEW_DEG",
    "STILL_POLL_S",
    "TableView",
    "off_mm",
    "same_block",
    "thing_footprint",
    "too_near_for_two",
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
OBLIQUE_TILT_DEG = 35.0
"""A thing whose shape one picture leaves unsure is seen again from the side first, the
camera this far from looking straight down (from above, a box's sides hide its height)."""
OBLIQUE_CAMERA_MM = 230.0
"""... from about this high over the thing."""
OVER_CAMERA_MM, OVER_TILT_DEG = 260.0, 15.0
"""Then from over it, the camera this high and about this tilted: it in the middle of the
picture, its size measured best."""
STILL_POLL_S = 0.02
"""Before a picture, the joints are read this often until two readings agree."""
CROWDED_LOOKS = 1
"""A thing hidden among others, seen so again from this many other poses in a row (the
first: from the side, near it), is not looked at from more. (On 8 of the clutter
family's tables, of 24 things the side view left hidden, the view from over them and
the two from the survey's height made out none: 2 at best as unsure.)"""
SECOND_VIEW_DEG = 15.0
"""A thing whose shape one picture leaves unsure is seen again with the base turned this
far from facing it (well in the picture, its sides seen anew)."""


class TableView:
    """Looks at the table with ``arm``'s wrist ``camera`` (see the module docstring)."""

    def __init__(self, arm: Arm, camera: CameraSource, locator: BlockLocator,
                 bins: Mapping[str, tuple[float, float]], survey_poses: Sequence[Sequence[float]],
                 settings: PickSortSettings, on_step: Callable[[str], None],
                 on_note: Callable[[str], None] = lambda _: None) -> None:
        self.arm, self.camera, self.locator = arm, camera, locator
        self.bins = dict(bins)
        self.survey_poses = list(survey_poses)
        self.settings = settings
        self.on_step = on_step
        self.on_note = on_note  # a line for the person watching
        self.clock = arm.clock
        # The last survey's pictures and what was found in each (for reports).
        self.last_survey: list[tuple[npt.NDArray[np.uint8], list[Sighting]]] = []
        # Every block the last survey saw: the neighbours a grasp must keep clear of.
        self.seen: list[Sighting] = []
        self.last_found: list[Sighting] = []  # the blocks the last look saw
        # Every block measured whole by a look since the last survey began: what a later
        # judgement of one of them may use before it looks again.
        self.measured_since_survey: list[Sighting] = []
        # Things seen since the last survey began that are not blocks (cast on the table).
        self.obstacles: list[Footprint] = []
        self.things: list[Obstacle] = []  # the same, as seen (refined by each look)
        # Things in a block's colour found not to be blocks (by their shape), kept for good.
        self.not_blocks: list[NotBlock] = []
        # Things no picture made out (colour, where): not touched, not reported.
        self.unknown: list[tuple[str, tuple[float, float]]] = []
        # Things among others whose shape no picture was sure of (colour, where): judged
        # again once the blocks around them have gone.
        self.waiting: list[tuple[str, tuple[float, float]]] = []

    def survey(self, facing: Sequence[tuple[float, float]] = ()) -> list[Sighting]:
        """Every block seen from the survey poses, merged (averaged per pose), then from
        poses turned to face what was cut by a picture's edge (the table may reach beyond
        the survey's pictures) and the points ``facing`` (x, y mm: where blocks were
        that the survey may not make out, a cluster of several seen from afar). A block
        seen from several poses keeps its best sighting: whole rather than cut, measured
        rather than not, then the one nearest the middle of its picture (in bearing)."""
        seen: list[tuple[tuple[bool, bool, float], Sighting]] = []
        self.last_survey = []
        self.measured_since_survey = []
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

    def _merge(self, seen: list[tuple[tuple[bool, bool, float], Sighting]],
               pose: Sequence[float], *, fresh: bool = False) -> None:
        """Look from ``pose`` and merge what is found into ``seen`` (see ``survey``)."""
        image, found = self.look(pose, fresh=fresh)
        self.last_survey.append((image, found))
        for new in found:
            # Whole before cut, measured (its size known) before not, then nearest the
            # picture's middle.
            rank = (not new.whole, not _judged(new), abs(_bearing_deg(new) - pose[0]))
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

    @property
    def tallest_mm(self) -> float:
        """The largest block seen (or the locator's size): what is carried is no taller."""
        return max([self.locator.block_size_mm, *(v.location.size_mm for v in self.seen)])

    def thing_on_the_way(self, start: Sequence[float], end: Sequence[float]) -> bool:
        """Whether a thing that is not a block lies near the way from ``start`` to ``end``
        (x, y mm), taken as the base turns: bearing and radius changing evenly."""
        if not self.obstacles:
            return False
        (r0, a0), (r1, a1) = ((math.hypot(x, y), math.atan2(y, x)) for x, y in (start, end))
        turn = (a1 - a0 + math.pi) % (2 * math.pi) - math.pi
        size = self.tallest_mm
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
        over = self.locator.table_z_mm + OVER_THINGS_MM + self.tallest_mm
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
        # The pictures once the arm stands still (``settle_s`` at most; the camera keeps
        # no older frame than the one it is taking: busarm.vision.camera).
        arm.settled_joints_deg(timeout_s=s.settle_s, poll_s=STILL_POLL_S)
        pictures = [(self.camera.read().image, arm.read_joints_deg())
                    for _ in range(s.survey_frames)]
        # Things that are not blocks, for the fingers and pushes to keep off.
        found = self.locator.find(pictures, trays=[(x, y, BIN_RADIUS_MM)
                                                   for x, y in self.bins.values()])
        for thing in found.not_blocks:
            self.not_block(thing)
        self.things = refine([] if fresh else self.things, self.locator.obstacles(
            *pictures[-1], [(x, y, 2 * BIN_RADIUS_MM) for x, y in self.bins.values()],
            found.blocks, found.not_blocks))
        self.obstacles = [Footprint(o.corners) for o in self.things]
        blocks = self.last_found = [v for v in found.blocks if not self.is_not_block(v)]
        self.measured_since_survey += [v for v in blocks if _judged(v)]
        return pictures[-1][0], blocks

    def not_block(self, thing: NotBlock) -> None:
        """Remember ``thing`` as no block (said once)."""
        if not any(old.color == thing.color and math.dist(old.xy_mm, thing.xy_mm)
                   < SAME_BLOCK_MM for old in self.not_blocks):
            self.not_blocks.append(thing)
            row = (" (if it is blocks in a row seen as one, each is taken where it shows "
                   "alone)") if _blocks_in_a_row(thing.shape) else ""
            self.on_note(f"the {thing.color} thing at {place_text(thing.xy_mm)} is not a "
                         f"block ({thing.shape.why}): left alone{row}")

    def not_block_footprints(self) -> list[Footprint]:
        """Where each thing found not to be a block stands, as it was measured (its
        disc's square, its box's rectangle), though the last picture may not show it."""
        return [thing_footprint(thing.shape) for thing in self.not_blocks]

    def is_not_block(self, seen: Sighting, *, rows: bool = True) -> bool:
        """Whether ``seen`` is where a thing found not to be a block was. A thing that may
        be blocks in a row seen as one (``_blocks_in_a_row``) rules out no block measured
        whole and alone there (another pose saw the blocks apart), nor any, if not
        ``rows``."""
        return self.is_not_block_at(seen.color, (seen.location.x_mm, seen.location.y_mm),
                                    rows=rows and not _judged(seen))

    def is_not_block_at(self, color: str, xy_mm: tuple[float, float], *,
                        rows: bool = True) -> bool:
        """Whether a thing of ``color`` found not to be a block is at ``xy_mm`` (one
        that may be blocks in a row only if ``rows``)."""
        return any(n.color == color and _on_thing(n.shape, xy_mm) and (
            rows or not _blocks_in_a_row(n.shape)) for n in self.not_blocks
        ) or any(c == color and math.dist(xy, xy_mm) < SAME_BLOCK_MM for c, xy in self.unknown)

    def confirm(self, target: Sighting) -> Sighting | None:
        """``target`` if its outline showed a cube; else seen again from other poses
        (``_other_looks``: its sides seen anew) and judged from every picture that
        measured it, until they say: the block (measured from all), or None if it is no
        block (or its shape stays unsure). A thing hidden by its neighbours in every
        picture is taken as located (a block of the usual size in a crowd of blocks)."""
        if target.shape is not None and target.shape.verdict == "cube":
            return target
        seen = [target] if _judged(target) else []
        answered = self._answered_already(target) if seen else None
        if answered is not None:
            return answered
        last: Sighting | None = None
        verdict = target.shape if seen else None
        # Pictures in a row that found it among others and left it undecided: seen so
        # from the side as well, the looks from over it and from the survey's height will
        # not see more. (Every picture that measured it is judged first.)
        crowded = 1 if self._in_a_crowd(target) else 0
        row: Shape | None = None
        for again in self._other_looks(target):
            if self.is_not_block(target, rows=False):
                return None
            if again is None:
                continue
            last = again
            if _judged(again):
                seen.append(again)
                assert again.shape is not None
                verdict = again.shape if len(seen) == 1 else self._judged_all(seen)
                if verdict.verdict == "cube":
                    return again if len(seen) == 1 else self.locator.measured(again, verdict)
                if verdict.verdict == "not a block" and _blocks_in_a_row(verdict):
                    # Blocks in a row a little apart, seen from the side as one: the
                    # next pose may see them apart (these pictures show no one block).
                    row, seen = verdict, []
                elif verdict.verdict == "not a block":
                    self.not_block(NotBlock(target.color, verdict))
                    return None
            crowded = crowded + 1 if crowded and self._in_a_crowd(again) else 0
            if crowded > CROWDED_LOOKS:
                break
        if row is not None and not seen:  # a row from every pose: no block
            self.not_block(NotBlock(target.color, row))
            return None
        return self._undecided(target, seen, last, verdict)

    def _answered_already(self, target: Sighting) -> Sighting | None:
        """``target`` measured as a cube from its outline and those other pictures since
        the survey began took of it (the survey's, seen from the side, and the closer
        look's, facing it), if together they say it is one; else None (looked at again)."""
        loc = target.location
        earlier = [v for v in self.measured_since_survey if v is not target
                   and same_block(target.color, loc.x_mm, loc.y_mm, v)]
        if not earlier:
            return None
        verdict = self._judged_all([*earlier, target])
        return self.locator.measured(target, verdict) if verdict.verdict == "cube" else None

    def _undecided(self, target: Sighting, seen: Sequence[Sighting], last: Sighting | None,
                   verdict: Shape | None) -> Sighting | None:
        """``confirm``'s answer when no picture decided: among others (its outline partly
        hidden by them), judged again once they have gone, and then taken as a block if
        its height is still a block's as far as they show; else left alone."""
        crowded = any(self._in_a_crowd(v) for v in (target, last) if v is not None)
        where = place_text(target.location.xy_mm)
        if verdict is not None and crowded and not self.is_waiting(target):
            # Among others its sides hardly show: once they have gone, they will.
            self.waiting.append((target.color, target.location.xy_mm))
            self.on_note(f"the {target.color} thing at {where} stands among others and its "
                         f"shape is not sure yet: looked at again once they have gone")
            return None
        if verdict is not None and crowded and _block_high(verdict):
            # Still among others (things that stay): as a thing hidden in every picture
            # is, a block of the size its outline shows; no picture says it is none.
            self.on_note(f"the {target.color} thing at {where} stays among others: taken "
                         f"for a block ({verdict.box.height_mm:.0f} mm high as far as its "
                         f"outline shows)")
            return seen[-1] if len(seen) == 1 else self.locator.measured(seen[-1], verdict)
        if verdict is not None:  # unsure from every picture: not touched
            self.not_block(NotBlock(target.color, replace(
                verdict, why=f"its shape is not sure from {len(seen)} picture(s) "
                             f"({verdict.why})")))
            return None
        if not crowded:
            # No picture made it out, and no neighbour hides it: it is not touched.
            self.on_note(f"the {target.color} thing at {where} could not be made out from "
                         f"any pose: left alone")
            self.unknown.append((target.color, target.location.xy_mm))
            return None
        return target if last is None else last

    def is_waiting(self, seen: Sighting) -> bool:
        """Whether ``seen`` is a thing among others to be judged once they have gone."""
        return any(c == seen.color and math.dist(xy, seen.location.xy_mm) < 2 * SAME_BLOCK_MM
                   for c, xy in self.waiting)

    def _in_a_crowd(self, seen: Sighting) -> bool:
        """Whether ``seen`` is hidden by its neighbours, or one of several touching blocks
        split from one blob: a block of the usual size among others."""
        if seen.shape is not None and seen.shape.verdict == "hidden":
            return True
        return seen.detection is not None and len(
            {id(v) for v in (*self.seen, *self.last_found) if v.detection is seen.detection}) > 1

    def _judged_all(self, seen: Sequence[Sighting]) -> Shape:
        """The verdict on one thing from every picture that measured it."""
        views = [view for v in seen if v.shape is not None for view in v.shape.views]
        loc = seen[-1].location
        return judge(views, self.locator.intrinsics, self.locator.table_z_mm,
                     (loc.x_mm, loc.y_mm, loc.yaw_deg, loc.size_mm))

    def _other_looks(self, target: Sighting) -> Iterator[Sighting | None]:
        """``target`` seen from other poses (None where not seen there): from the side,
        the camera tilted ``OBLIQUE_TILT_DEG`` (a thing's height shows in how much of
        its sides a picture holds), then with the base turned ``SECOND_VIEW_DEG`` past
        facing it."""
        loc, arm = target.location, self.arm
        bearing = math.degrees(math.atan2(loc.y_mm, loc.x_mm))
        poses: list[tuple[float, ...]] = []
        with contextlib.suppress(UnreachableError):
            oblique = look_pose(arm.kin, self.locator.cam2link,
                                self.locator.table_z_mm + loc.size_mm / 2,
                                math.hypot(loc.x_mm, loc.y_mm), OBLIQUE_CAMERA_MM,
                                OBLIQUE_TILT_DEG + 15.0, tilt_deg=OBLIQUE_TILT_DEG)
            poses.append((bearing, *oblique[1:]))
        with contextlib.suppress(UnreachableError):  # over it, a little from the side
            over = look_pose(arm.kin, self.locator.cam2link,
                             self.locator.table_z_mm + loc.size_mm / 2,
                             math.hypot(loc.x_mm, loc.y_mm), OVER_CAMERA_MM,
                             OBLIQUE_TILT_DEG + 15.0, tilt_deg=OVER_TILT_DEG)
            poses.append((bearing, *over[1:]))
        survey = self.survey_poses[0]
        poses += [(bearing + SECOND_VIEW_DEG, *survey[1:]),
                  (bearing - SECOND_VIEW_DEG, *survey[1:])]
        for pose in poses:
            try:
                seen_from = arm.config.check_joints(pose)
            except ConfigError:
                continue
            _, found = self.look(seen_from)
            again = [v for v in found if same_block(target.color, loc.x_mm, loc.y_mm, v,
                                                    2 * SAME_BLOCK_MM)]
            yield min(again, key=lambda v: off_mm(v, loc.x_mm, loc.y_mm)) if again else None

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
        """Whether ``sighting`` is a block in a bin (sorted: not to be picked)."""
        x, y = sighting.location.x_mm, sighting.location.y_mm
        return any(abs(x - bx) < BIN_SEEN_MM and abs(y - by) < BIN_SEEN_MM
                   for bx, by in self.bins.values())


def thing_footprint(shape: Shape) -> Footprint:
    """Where a thing measured as ``shape`` stands: its disc's square, or its box's
    rectangle."""
    if shape.cylinder is not None:
        return Footprint.square(*shape.xy_mm, 2 * shape.reach_mm, 0.0)
    box = shape.box
    return Footprint.rectangle(box.x_mm, box.y_mm, box.length_mm, box.width_mm, box.yaw_deg)


def _on_thing(shape: Shape, xy_mm: tuple[float, float]) -> bool:
    """Whether ``xy_mm`` lies on the thing ``shape`` measured: within its footprint (a
    disc's circle, a bar's rectangle: a block beside a bar is not on it), or as near its
    middle as two sightings of one block are."""
    if shape.cylinder is not None:
        return math.dist(shape.xy_mm, xy_mm) < max(SAME_BLOCK_MM, shape.reach_mm)
    box = shape.box
    a = math.radians(box.yaw_deg)
    dx, dy = xy_mm[0] - box.x_mm, xy_mm[1] - box.y_mm
    along, across = dx * math.cos(a) + dy * math.sin(a), -dx * math.sin(a) + dy * math.cos(a)
    return (abs(along) < max(SAME_BLOCK_MM, box.length_mm / 2)
            and abs(across) < max(SAME_BLOCK_MM, box.width_mm / 2))


def _block_high(shape: Shape) -> bool:
    """Whether the box that fits ``shape``'s outlines best is as high as a block (its
    side, within what two pictures measure)."""
    side = (shape.box.length_mm + shape.box.width_mm) / 2
    return abs(shape.box.height_mm / side - 1.0) <= HEIGHT_TOLERANCE[1]


def _blocks_in_a_row(shape: Shape) -> bool:
    """Whether a thing found no block for its footprint (a crowd's: too long) could be
    blocks standing in a row, seen as one: as wide as a block and half as long again or
    more (a bar is narrower; a tile or a tall box has a block's footprint, and the
    height one picture measures of a row is no surer than of a block)."""
    lo, hi = CUBE_SIDES_MM
    box = shape.box
    return (shape.crowd and shape.cylinder is None and lo <= box.width_mm <= hi
            and box.length_mm >= 1.5 * box.width_mm)


def _judged(seen: Sighting) -> bool:
    """Whether one picture measured ``seen`` whole (a cube, or unsure of its height)."""
    return seen.shape is not None and seen.shape.verdict in ("cube", "unsure")


def same_block(color: str, x_mm: float, y_mm: float, seen: Sighting,
                radius_mm: float = SAME_BLOCK_MM) -> bool:
    """Whether ``seen`` is the block of ``color`` seen at (x, y) before."""
    return seen.color == color and off_mm(seen, x_mm, y_mm) < radius_mm


def too_near_for_two(size_mm: float, x_mm: float, y_mm: float, seen: Sighting) -> bool:
    """Whether ``seen`` stands nearer a block ``size_mm`` wide at (x, y) than any block
    can (half its side and half the smallest block's, less 2 mm): the same block, seen
    in part (a large block's picture split in two)."""
    return off_mm(seen, x_mm, y_mm) < nearest_other_mm(size_mm)


def off_mm(seen: Sighting, x_mm: float, y_mm: float) -> float:
    return math.hypot(seen.location.x_mm - x_mm, seen.location.y_mm - y_mm)


def _bearing_deg(seen: Sighting) -> float:
    return math.degrees(math.atan2(seen.location.y_mm, seen.location.x_mm))
