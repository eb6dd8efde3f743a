"""Recording an action group from the page: start, a frame at each pose, save or cancel.

``GroupRecorder`` keeps the frames (each the arm's present joints, reached in the
frame's ``duration_ms``) and writes them as a ``.d6a`` in the robot's ``actions/``
folder (busarm.arm.actions), where the page's Play finds them.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from busarm.arm.actions import ActionFrame, ActionGroup, write_d6a
from busarm.arm.arm import Arm
from busarm.dashboard.protocol import Record, RequestError

__all__ = [
    "GroupRecorder",
]


class GroupRecorder:
    """The page's recording of ``arm`` into ``folder``/actions; ``log`` says each step."""

    def __init__(self, arm: Arm, folder: Path, log: Callable[[str], None]) -> None:
        self.arm, self.folder, self.log = arm, folder, log
        self.frames: list[ActionFrame] | None = None
        """The frames so far (None: not recording)."""

    def handle(self, request: Record) -> bool:
        """Carry out ``request``; whether a group was saved (the page's list changes)."""
        if request.action == "start":
            self.frames = []
            self.log("recording an action group: jog to each pose and add it as a frame")
            return False
        if self.frames is None:
            raise RequestError(f"record: {request.action} needs a recording: start one first")
        if request.action == "cancel":
            self.frames = None
            self.log("recording cancelled")
        elif request.action == "frame":
            self.frames.append(self.arm.record_frame(request.duration_ms))
            self.log(f"frame {len(self.frames)} recorded ({request.duration_ms} ms)")
        else:
            if not self.frames:
                raise RequestError("record: no frame recorded yet: add one first")
            assert request.name is not None
            path = self.folder / "actions" / f"{request.name}.d6a"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_d6a(path, ActionGroup(tuple(self.frames)))
            self.log(f"saved action group {request.name!r} ({len(self.frames)} frames) "
                     f"in {path}")
            self.frames = None
            return True
        return False
