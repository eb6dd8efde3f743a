"""The wrist camera with the floor tape painted out, while a block is cleared off it.

A block of the tape's own colour standing on the tape makes one blob with it in a
closer look: the pick (busarm.apps.transport.mobile_pick) would take the blob for the
block, and the block seemed to move from look to look. ``tape_hidden(robot, tape)``
puts the robot's wrist camera behind ``TapeHidingCamera`` meanwhile: each picture is
cast onto the floor from where the arm stands then (its joints read back, the floor
camera of busarm.apps.line_follow.floor_look), the tape looked for in it in its colour,
and the flat tape painted the floor's colour (busarm.vision.tape_colour.without_tape);
the block, standing up, stays. White tape too: its bright edge beside a block would be
taken for the block's side (busarm.perception.measure). Black tape needs none of it (the
outlines leave black out: the arm's own colour).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from types import TracebackType

from busarm.apps.line_follow.floor_look import floor_camera
from busarm.robot import Robot
from busarm.vision.camera import CameraFrame, CameraSource
from busarm.vision.color_thresholds import ColorRange
from busarm.vision.floor_line import each_floor_line
from busarm.vision.tape_colour import without_tape

__all__ = ["HIDDEN_MIN_M", "TapeHidingCamera", "tape_hidden"]


HIDDEN_MIN_M = 0.1
"""Pieces of tape at least this long are painted out (shorter ones are not the tape)."""


class TapeHidingCamera:
    """``inner``, its pictures without the flat tape of colour ``tape`` (see the module
    docstring)."""

    def __init__(self, robot: Robot, inner: CameraSource, tape: str | ColorRange) -> None:
        self.robot, self.inner, self.tape = robot, inner, tape

    @property
    def name(self) -> str:
        return self.inner.name

    @property
    def width_px(self) -> int:
        return self.inner.width_px

    @property
    def height_px(self) -> int:
        return self.inner.height_px

    def read(self) -> CameraFrame:
        frame = self.inner.read()
        camera = floor_camera(self.robot, joints_deg=self.robot.arm.read_joints_deg())
        image = frame.image
        for line in each_floor_line(image, camera.intrinsics, camera.cam_to_floor, self.tape,
                                    mask=camera.mask, from_middle=True):
            if line.length_m >= HIDDEN_MIN_M:
                image = without_tape(image, line, camera.intrinsics, camera.cam_to_floor,
                                     camera.mask)
        return frame if image is frame.image else replace(frame, image=image)

    def close(self) -> None:
        """Nothing: the inner camera is the robot's, closed with it."""

    def __enter__(self) -> TapeHidingCamera:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


@contextmanager
def tape_hidden(robot: Robot, tape: str | ColorRange | None) -> Iterator[None]:
    """The robot's wrist camera hides tape ``tape`` meanwhile (nothing for black or
    None)."""
    if tape is None or tape == "black":
        yield
        return
    inner = robot.camera
    robot.cameras["wrist"] = TapeHidingCamera(robot, inner, tape)
    try:
        yield
    finally:
        robot.cameras["wrist"] = inner
