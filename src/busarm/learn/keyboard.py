"""The keyboard as a teleoperator: a pair of keys per joint and for the gripper, read from
a terminal without waiting (no window system needed, as on a robot's own computer).

======  ======================  ======  ======================
``q a`` base_yaw + / -          ``t g`` wrist_roll + / -
``w s`` shoulder_pitch + / -    ``o c`` gripper open / close
``e d`` elbow_pitch + / -       ``h``   back to the start pose
``r f`` wrist_pitch + / -
======  ======================  ======  ======================

Each press moves the target by ``step_deg`` (the gripper by ``gripper_step_mm``), kept
within the joints' limits; ``read()`` returns the target in the state's form. The target
starts where the arm is when it is given (``begin_at``, as ``busarm record --teleop
keyboard`` does), else at the arm's ``look`` pose, gripper open (the first action then
takes the arm there, at its servos' speed).
"""

from __future__ import annotations

import math
import os
import select
import sys
import termios
import tty
from types import TracebackType
from typing import Any

from busarm.arm.config import ArmConfig
from busarm.learn.jog_target import JogTarget
from busarm.units import check_range

__all__ = [
    "KEYS",
    "KeyboardJog",
]

KEYS = {"q": (0, 1), "a": (0, -1), "w": (1, 1), "s": (1, -1), "e": (2, 1), "d": (2, -1),
        "r": (3, 1), "f": (3, -1), "t": (4, 1), "g": (4, -1), "o": (5, 1), "c": (5, -1)}
"""Key -> (motor index in the state's order, direction)."""
HOME_KEY = "h"


class KeyboardJog:
    """Keys read from ``fd`` (default the terminal's stdin) jog a target pose."""

    def __init__(self, config: ArmConfig, *, fd: int | None = None, step_deg: float = 2.0,
                 gripper_step_mm: float = 3.0) -> None:
        check_range("step_deg", step_deg, 0.1, 30.0, "deg")
        check_range("gripper_step_mm", gripper_step_mm, 0.1, 30.0, "mm")
        self.config = config
        self.fd = sys.stdin.fileno() if fd is None else fd
        self.jog = JogTarget(config)
        self.steps = [math.radians(step_deg)] * len(config.joints) + [gripper_step_mm]
        self.presses = 0
        self._saved: list[Any] | None = None

    def __repr__(self) -> str:
        return f"KeyboardJog(fd {self.fd}, {self.presses} presses)"

    def open(self) -> KeyboardJog:
        if os.isatty(self.fd) and self._saved is None:
            self._saved = termios.tcgetattr(self.fd)
            tty.setcbreak(self.fd)  # each key as it is pressed, not echoed
        return self

    def begin_at(self, motors: dict[str, float]) -> None:
        """Start (and ``h`` come back) where the arm is: ``motors`` in the state's form."""
        self.jog.begin_at(motors)

    def read(self) -> dict[str, float]:
        """Every key pressed since the last read applied; the target now."""
        while select.select([self.fd], [], [], 0)[0]:
            data = os.read(self.fd, 64)
            if not data:
                break
            for key in data.decode("ascii", "ignore").lower():
                self._press(key)
        return self.jog.values()

    def _press(self, key: str) -> None:
        if key == HOME_KEY:
            self.jog.home()
        elif key in KEYS:
            k, sign = KEYS[key]
            self.jog.nudge(k, sign * self.steps[k])
        else:
            return
        self.presses += 1

    def close(self) -> None:
        if self._saved is not None:
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
            self._saved = None

    def __enter__(self) -> KeyboardJog:
        return self.open()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
