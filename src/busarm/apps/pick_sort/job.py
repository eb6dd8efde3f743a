"""A whole pick-and-sort run as every interface starts it: the sorter, the pictures its
report shows, the table before and after, the arm home at the end, the report folder.

The command line and the dashboard both run ``PickJob``; what they add is how they show
progress and the outcome.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.report import write_report
from busarm.apps.pick_sort.rules import SortRule
from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.apps.pick_sort.sorter import PickSorter, RunReport
from busarm.apps.pick_sort.tag_sort import TagSortJob
from busarm.apps.stack.settings import StackSettings
from busarm.errors import BusArmError
from busarm.perception.locate import Sighting
from busarm.progress import quiet
from busarm.robot import Robot
from busarm.units import place_text
from busarm.vision.camera import CameraSource

__all__ = [
    "Image",
    "PickJob",
]


Image = npt.NDArray[np.uint8]


@dataclass
class _Pictures:
    """What the report shows: the camera after each step, and the annotated picture each
    pick started from."""

    camera: CameraSource
    sorter: PickSorter | None = None
    frames: list[Image] = field(default_factory=list)
    picks: list[tuple[str, Image]] = field(default_factory=list)

    def on_step(self, step: str) -> None:
        self.frames.append(self.camera.read().image)

    def on_pick(self, target: Sighting) -> None:
        from busarm.vision.annotate import annotate

        assert self.sorter is not None
        image, found = self.sorter.last_survey[0]
        self.picks.append((target.color, annotate(
            image, [s.detection for s in found if s.detection is not None],
            text_lines=[f"next: {target.color} at "
                        f"{place_text((target.location.x_mm, target.location.y_mm))}"])))


class PickJob:
    """Pick-and-sort on ``robot`` with its report in ``report_dir``.

    ``run()`` returns the report and the path of report.json. If the run stops early
    (the sorter has stopped the arm), the report so far is written and ``notes`` says what
    the gripper holds and where the report is, for the message about the stop.
    """

    def __init__(self, robot: Robot, report_dir: Path, *, colors: Sequence[str],
                 survey_poses: Sequence[Sequence[float]] | None = None,
                 settings: PickSortSettings | None = None,
                 rule: SortRule | None = None,
                 progress: Callable[[str], None] | None = None,
                 on_pick: Callable[[Sighting], None] | None = None) -> None:
        self.robot, self.report_dir = robot, report_dir
        self.pictures = _Pictures(robot.camera)
        chained = on_pick or (lambda _: None)

        def pick(target: Sighting) -> None:
            self.pictures.on_pick(target)
            chained(target)

        self.sorter: PickSorter | TagSortJob
        if rule is not None and rule.reads_tags:  # blocks found by their tags
            self.sorter = TagSortJob(robot, rule=rule, settings=StackSettings(
                pick=settings or PickSortSettings()), progress=progress or quiet)
        else:
            self.sorter = self.pictures.sorter = PickSorter(
                robot, colors=colors, survey_poses=survey_poses, settings=settings,
                rule=rule, progress=progress, on_step=self.pictures.on_step, on_pick=pick)
        self.about: dict[str, Any] = {
            "port": robot.port, "clock": "simulated" if robot.clock.is_simulated else "wall",
            "camera_calibration": robot.require_camera_calibration().source}
        self.notes: list[str] = []

    def run(self) -> tuple[RunReport, Path]:
        """Sort, go home, write the report folder."""
        wall_start = time.monotonic()
        overview = self.robot.cameras.get("overview")
        before = overview.read().image if overview is not None else None
        report = self._sort()
        self.robot.arm.move_joints(self.robot.config.pose("home"))
        last = self.sorter.last_survey
        after = overview.read().image if overview is not None else (
            last[0][0] if last else None)
        path = write_report(self.report_dir, report, before=before, after=after,
                            picks=self.pictures.picks, camera_frames=self.pictures.frames,
                            extra={**self.about, "wall_seconds":
                                   round(time.monotonic() - wall_start, 1)})
        return report, path

    def _sort(self) -> RunReport:
        try:
            return self.sorter.run()
        except BaseException:
            stopped = self.sorter.report
            if stopped.gripper:  # empty if it stopped before the run began
                self.notes.append(f"the gripper: {stopped.gripper}")
            try:
                path = write_report(self.report_dir, stopped, picks=self.pictures.picks,
                                    camera_frames=self.pictures.frames, extra=self.about)
                self.notes.append(f"the report so far: {path}")
            except (BusArmError, OSError) as write_error:  # the stop's own error is the one
                self.notes.append(f"the report could not be written: {write_error}")
            raise
