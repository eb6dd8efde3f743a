"""Sampling the twin's arm at a fixed rate of its clock while a program drives it.

A ``ServoTap`` rides on the twin's physics (``Twin.physics_hooks``): every ``1/fps`` of
simulated time it takes each servo's position as the bus would read it (the state) and
its firmware's setpoint (where its move profile has the horn then). A frame's action is
the next frame's setpoint: where the servos are to be one frame later, which a policy's
action asks for and a move of one frame reaches (the last frame's, its own). Units are
the flat form's (rad, the gripper's gap in mm). The program it watches (the expert's
pick, a scripted move) runs unchanged, and no bus read is added to its own.
"""

from __future__ import annotations

import math
from types import TracebackType

import numpy as np
import numpy.typing as npt

from busarm.arm.arm import Arm
from busarm.errors import ConfigError
from busarm.twin.twin import Twin

__all__ = ["ServoTap"]


class ServoTap:
    """``with ServoTap(twin, arm, fps) as tap: ...``; then ``tap.states``, ``tap.actions``
    (frames x motors, float32) and ``tap.times_s`` (the twin's clock)."""

    def __init__(self, twin: Twin, arm: Arm, fps: int) -> None:
        if not 1 <= fps <= 200:
            raise ConfigError(f"fps = {fps!r} is out of range 1..200")
        self.twin, self.arm, self.period_s = twin, arm, 1.0 / fps
        self._next_s = math.inf
        self._t0 = 0.0
        self.times_s: list[float] = []
        self._states: list[list[float]] = []
        self._actions: list[list[float]] = []

    def __repr__(self) -> str:
        return f"ServoTap({len(self.times_s)} frames at {1 / self.period_s:g} fps)"

    def __enter__(self) -> ServoTap:
        self._t0 = self.twin.clock.now() - float(self.twin.data.time)
        self._next_s = self.twin.clock.now()
        self.twin.physics_hooks.append(self._hook)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._hook in self.twin.physics_hooks:
            self.twin.physics_hooks.remove(self._hook)

    def _motors(self, pulses: list[float]) -> list[float]:
        joints = self.arm.config.joints
        angles = self.arm.joints_from_pulses(
            {j.servo_id: p for j, p in zip(joints, pulses, strict=False)})
        gap = self.arm.config.gripper.gap_mm_at(pulses[-1])
        return [math.radians(a) for a in angles] + [
            min(max(gap, 0.0), self.arm.config.gripper.widest_gap_mm)]

    def _hook(self, physics_s: float, step_s: float) -> None:
        now = self._t0 + physics_s
        if now + 1e-9 < self._next_s:
            return
        read, setpoint = self.twin.servo_pulses_in_step()
        self.times_s.append(now)
        self._states.append(self._motors([float(p) for p in read]))
        self._actions.append(self._motors(setpoint))
        while self._next_s <= now + 1e-9:
            self._next_s += self.period_s

    @property
    def states(self) -> npt.NDArray[np.float32]:
        return np.asarray(self._states, np.float32).reshape(len(self._states), self._width)

    @property
    def actions(self) -> npt.NDArray[np.float32]:
        """Each frame's action: the next frame's setpoints (the last frame: its own)."""
        ahead = self._actions[1:] + self._actions[-1:]
        return np.asarray(ahead, np.float32).reshape(len(ahead), self._width)

    @property
    def _width(self) -> int:
        return len(self.arm.config.joints) + 1
