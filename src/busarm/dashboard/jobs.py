"""The dashboard's jobs: each runs in the job thread and returns what it did, in words.

They move the arm through the same calls as the command line (limits and speeds checked
there). A stop or an e-stop halts the bus, which ends a job at its next write or wait
with HaltedError (busarm.dashboard.service says so).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

from busarm.apps.pick_sort.job import PickJob
from busarm.apps.pick_sort.rules import SortRule
from busarm.apps.pick_sort.settings import PickSortSettings
from busarm.arm.actions import ActionGroup
from busarm.arm.arm import Arm
from busarm.arm.named_poses import NamedPose
from busarm.dashboard.protocol import PickSort
from busarm.errors import BusArmError, HaltedError
from busarm.robot import Robot

__all__ = [
    "gripper",
    "move_pose",
    "pick_sort",
    "play",
    "report_folder",
]


def move_pose(arm: Arm, pose: NamedPose) -> str:
    seconds = arm.move_joints(pose.joints_deg)
    return f"at pose {pose.name} ({seconds:.1f} s)"


def gripper(arm: Arm, action: str) -> str:
    gap = arm.config.gripper.gap_mm_at
    if action == "open":
        return f"gripper open ({gap(arm.open_gripper()):.0f} mm)"
    result = arm.grip()
    if result.is_holding:
        return f"gripper holding something {gap(result.position_pulses):.0f} mm wide"
    return f"gripper closed ({gap(result.position_pulses):.0f} mm)"


def play(arm: Arm, group: ActionGroup, cancel: threading.Event,
         progress: Callable[[str], None]) -> str:
    total = len(group.frames)
    played = arm.play(group, stop_event=cancel,
                      on_frame=lambda n: progress(f"frame {n} of {total}"))
    if cancel.is_set():
        raise HaltedError(f"stopped after frame {played} of {total}")
    return f"played {played} frames"


def pick_sort(robot: Robot, request: PickSort, folder: Path,
              progress: Callable[[str], None]) -> str:
    """Pick-and-sort with its report in ``folder``; a stop says what the gripper holds
    and where the report so far is."""
    job = PickJob(robot, folder, colors=request.colors,
                  settings=PickSortSettings(order=request.order), rule=SortRule(request.by),
                  progress=progress)
    try:
        report, _ = job.run()
    except BusArmError as exc:
        exc.notes = job.notes  # type: ignore[attr-defined]  # for the message about the stop
        raise
    t = report.totals()
    return f"sorted {t['sorted']}, failed {t['failed']}, skipped {t['skipped']}"


def report_folder(reports: Path, kind: str = "pick-sort") -> Path:
    """A new folder for a run's report in ``reports`` (``KIND-`` and the time it started)."""
    stamp = time.strftime(f"{kind}-%Y%m%d-%H%M%S")
    folder, n = reports / stamp, 1
    while folder.exists():
        n += 1
        folder = reports / f"{stamp}-{n}"
    return folder
