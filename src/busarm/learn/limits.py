"""A policy's actions made safe to send: each value within its joint's or the gripper's
limits, and each joint's step within what its servo turns in one frame.

A learned policy may ask for anything. Every action it gives is clipped here before
``Robot.send_action`` checks it again (which refuses, never clips): within the arm
config's joint limits and the gripper's travel, and no joint more than
``SPEED_MARGIN`` of its ``max_speed_deg_s`` times the frame's time away from where it
was read, so the move of one frame never needs more than the servo has.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.arm.config import ArmConfig
from busarm.learn.features import motor_names
from busarm.robot.observation import MIN_DURATION_KEY
from busarm.units import check_range

__all__ = [
    "SPEED_MARGIN",
    "ActionLimits",
]

SPEED_MARGIN = 1.0
"""Of a joint's top speed, what one frame's step may use. The move is sent with the
frame's time as its shortest (``min_duration_s``): where the joint has moved on since it
was read, the arm takes that little longer rather than exceed the speed."""

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ActionLimits:
    """The limits of one frame's action for an arm (``ActionLimits.of(config, fps)``)."""

    names: tuple[str, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    max_step: tuple[float, ...]
    frame_s: float

    @classmethod
    def of(cls, config: ArmConfig, fps: float) -> ActionLimits:
        check_range("fps", fps, 1.0, 200.0, "frames/s")
        frame_s = 1.0 / fps
        joints = config.joints
        low = [math.radians(j.min_deg) for j in joints] + [0.0]
        high = [math.radians(j.max_deg) for j in joints] + [config.gripper.widest_gap_mm]
        steps = [SPEED_MARGIN * math.radians(j.max_speed_deg_s) * frame_s for j in joints]
        return cls(tuple(motor_names(config)), tuple(low), tuple(high),
                   (*steps, math.inf), frame_s)

    def clip(self, action: npt.ArrayLike, measured: npt.ArrayLike) -> tuple[FloatArray, int]:
        """``action`` (state order: joints in rad, the gap in mm) within the limits, from
        ``measured`` (where the arm was read); and how many values were changed. A value
        that is not a number becomes the measured one."""
        a = np.asarray(action, np.float64).reshape(-1)
        m = np.asarray(measured, np.float64).reshape(-1)
        if a.shape != (len(self.names),) or m.shape != a.shape:
            raise ValueError(f"an action has {len(self.names)} values ({', '.join(self.names)}); "
                             f"got {a.shape[0]} (measured {m.shape[0]})")
        finite = np.isfinite(a)
        asked = np.where(finite, a, m)
        step = np.asarray(self.max_step)
        out = np.clip(asked, m - step, m + step)
        out = np.clip(out, np.asarray(self.low), np.asarray(self.high))
        changed = int(np.sum(~finite | (np.abs(out - asked) > 1e-9)))
        return out, changed

    def flat(self, values: FloatArray) -> dict[str, float]:
        """The flat form ``Robot.send_action`` takes: every value, moved in one frame (or
        a little longer where the arm has moved on since it was read)."""
        out = {name: float(v) for name, v in zip(self.names, values, strict=True)}
        out[MIN_DURATION_KEY] = self.frame_s
        return out
