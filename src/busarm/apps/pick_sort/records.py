"""Which record of a pick-and-sort run a block seen is: blocks move between surveys (looked
at closer, pushed out of a group, missed and knocked aside), and each keeps its record.
What is kept between cycles besides the records themselves lives here."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from busarm.apps.pick_sort.outcomes import BlockOutcome, RunReport
from busarm.apps.pick_sort.table_view import SAME_BLOCK_MM, off_mm, same_block
from busarm.perception.locate import Sighting
from busarm.perception.shape import nearest_other_mm

__all__ = [
    "BlockRecords",
    "Place",
]


Place = tuple[float, float]


class BlockRecords:
    """What a run knows of its records between cycles, by record: where the survey saw a
    block found elsewhere when looked at closer, where a pushed block was pushed, which
    were seen boxed in when looked at closer (and how), how often each was pushed."""

    def __init__(self) -> None:
        self.boxed: dict[int, Sighting] = {}
        """Records seen boxed in when looked at closer, and how (until the table changes)."""
        self._nudges: dict[int, int] = {}  # pushes per record
        # Records of blocks pushed out of a group: (record, from, towards), until seen.
        self._pushed: dict[int, tuple[BlockOutcome, Place, Place]] = {}
        # Where the survey saw a block that was found elsewhere when looked at closer.
        self._aliases: dict[int, list[Place]] = {}

    def record_for(self, sighting: Sighting, report: RunReport) -> BlockOutcome:
        """The record of this block: one already made where it was seen, or a new one."""
        # Of the records made about here, one still waiting first (a block set down
        # where one was picked before is that one), then the nearest.
        near = sorted((outcome for outcome in report.blocks
                       if same_block(outcome.color, *outcome.found_mm, sighting)),
                      key=lambda o: (o.outcome != "pending", off_mm(sighting, *o.found_mm)))
        if near:
            outcome = near[0]
            if outcome.outcome == "sorted":
                # Sorted, yet seen where it was: it did not go (a slip). Try again.
                outcome.outcome, outcome.placed_mm = "pending", None
            self._pushed.pop(id(outcome), None)
            return outcome
        for outcome in report.blocks:  # seen where the survey saw it, not as seen closer
            if outcome.outcome == "pending" and any(
                    same_block(outcome.color, x, y, sighting)
                    for x, y in self._aliases.get(id(outcome), ())):
                return outcome
        pushed = self._pushed_here(sighting)
        if pushed is not None:
            return pushed
        outcome = BlockOutcome(sighting.color, (sighting.location.x_mm, sighting.location.y_mm))
        report.blocks.append(outcome)
        return outcome

    def _pushed_here(self, sighting: Sighting) -> BlockOutcome | None:
        """The record of a block pushed to about where ``sighting`` is, moved there."""
        here = np.array([sighting.location.x_mm, sighting.location.y_mm])
        for key, (outcome, start, end) in list(self._pushed.items()):
            # A pushed block ends somewhere along its push: the record goes there too.
            a, b = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
            ab, ah = b - a, here - a
            t = float(np.clip(float(np.dot(ah, ab)) / max(float(np.dot(ab, ab)), 1e-9), 0, 1))
            if outcome.color == sighting.color and float(
                    np.linalg.norm(here - (a + t * (b - a)))) < 2 * SAME_BLOCK_MM:
                del self._pushed[key]
                outcome.found_mm = (float(here[0]), float(here[1]))
                return outcome
        return None

    def seen_closer(self, outcome: BlockOutcome, here: Place) -> None:
        """The block is ``here``, as seen closer: it is looked for there from now on (and
        where the survey saw it, while it waits)."""
        if math.dist(here, outcome.found_mm) > SAME_BLOCK_MM:
            self._aliases.setdefault(id(outcome), []).append(outcome.found_mm)
        outcome.found_mm = here

    def taken(self, outcome: BlockOutcome, size_mm: float, report: RunReport) -> None:
        """``outcome``'s block, ``size_mm`` wide, was taken to its bin: a record still
        waiting, never tried, of its colour and nearer it than another block can stand
        was this block seen in part (a large block's picture split in two): it goes."""
        report.blocks[:] = [
            o for o in report.blocks
            if o is outcome or o.outcome not in ("pending", "skipped") or o.attempts
            or o.color != outcome.color
            or math.dist(o.found_mm, outcome.found_mm) >= nearest_other_mm(size_mm)]

    def may_push(self, outcome: BlockOutcome, most: int) -> bool:
        """Whether the block may be pushed once more (``most`` pushes a record); counted."""
        if self._nudges.get(id(outcome), 0) >= most:
            return False
        self._nudges[id(outcome)] = self._nudges.get(id(outcome), 0) + 1
        return True

    def pushed(self, outcome: BlockOutcome, end: Place) -> None:
        """The block was pushed towards ``end``: its record follows it (``record_for``)."""
        self._pushed[id(outcome)] = (outcome, outcome.found_mm, end)
        self.boxed.pop(id(outcome), None)

    def mark_moved(self, report: RunReport, seen: Sequence[Sighting]) -> None:
        """Records of blocks missed and no longer where they were: someone moved them.
        Such a block is looked for afresh (a new record if it is seen elsewhere). A block
        pushed since is not: its record follows it (a missed grasp, then a push, had
        lost a block the run then never took)."""
        for outcome in report.blocks:
            if outcome.outcome == "pending" and outcome.attempts and id(
                    outcome) not in self._pushed and not any(
                    same_block(outcome.color, *outcome.found_mm, s) for s in seen):
                outcome.outcome = "moved"
                outcome.reason = "not where it was after a missed grasp: it was moved"
