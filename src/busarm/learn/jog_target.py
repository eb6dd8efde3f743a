"""The target a person jogs (the keyboard's, a gamepad's): the motors in the state's form,
kept within the joints' limits and the gripper's travel, starting where it is told
(``begin_at``: where the arm is) or at the arm's ``look`` pose, gripper open."""

from __future__ import annotations

import math

from busarm.arm.config import ArmConfig
from busarm.learn.features import motor_names

__all__ = ["JogTarget"]


class JogTarget:
    """``nudge`` a motor (by index, in rad or mm), ``home`` to the start; ``values``."""

    def __init__(self, config: ArmConfig) -> None:
        self.motors = tuple(motor_names(config))
        self.low = [math.radians(j.min_deg) for j in config.joints] + [0.0]
        self.high = [math.radians(j.max_deg) for j in config.joints] + [
            config.gripper.widest_gap_mm]
        self.start = [math.radians(a) for a in config.pose("look")] + [
            config.gripper.widest_gap_mm]
        self.target = list(self.start)

    def __repr__(self) -> str:
        return f"JogTarget({len(self.motors)} motors)"

    def begin_at(self, motors: dict[str, float]) -> None:
        """Start (and ``home`` come back) where the arm is: ``motors`` in the state's form."""
        self.start = [min(max(float(motors[m]), lo), hi)
                      for m, lo, hi in zip(self.motors, self.low, self.high, strict=True)]
        self.target = list(self.start)

    def nudge(self, k: int, delta: float) -> None:
        self.target[k] = min(max(self.target[k] + delta, self.low[k]), self.high[k])

    def home(self) -> None:
        self.target = list(self.start)

    def values(self) -> dict[str, float]:
        return dict(zip(self.motors, self.target, strict=True))
