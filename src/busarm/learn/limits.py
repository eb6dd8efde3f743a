"""A policy's actions made safe to send: each value within its joint's or the gripper's
limits, and each joint's step within what its servo turns in one frame.

A learned policy may ask for anything. Every action it gives is clipped here before
``Robot.send_action`` checks it again (which refuses, never clips): within the arm
config's joint limits and the gripper's travel; each joint within one frame's turn at its
``max_speed_deg_s`` of where it was last told to go (``heading``: where its firmware's
setpoint is when a frame's move has ended), so that a move of one frame never asks more
of a servo than its speed; and within ``LEAD_FRAMES`` frames' turn of where it was read,
so that the setpoint never runs away from a joint held back (a stall, a collision).
Without a heading (the first action), within one frame's turn of where it was read.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.arm.config import ArmConfig
from busarm.errors import ConfigError
from busarm.learn.features import motor_names
from busarm.robot.observation import MIN_DURATION_KEY
from busarm.units import check_range

__all__ = [
    "LEAD_FRAMES",
    "SPEED_MARGIN",
    "ActionLimits",
]

SPEED_MARGIN = 1.0
"""Of a joint's top speed, what one frame's step may use."""
LEAD_FRAMES = 3.0
"""How many frames' turn a target may lead where the joint was read (the servos follow
their setpoint within about one)."""

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
        """The limits of ``config``'s arm at ``fps`` frames a second."""
        check_range("fps", fps, 1.0, 200.0, "frames/s")
        frame_s = 1.0 / fps
        joints = config.joints
        low = [math.radians(j.min_deg) for j in joints] + [0.0]
        high = [math.radians(j.max_deg) for j in joints] + [config.gripper.widest_gap_mm]
        steps = [SPEED_MARGIN * math.radians(j.max_speed_deg_s) * frame_s for j in joints]
        return cls(tuple(motor_names(config)), tuple(low), tuple(high),
                   (*steps, math.inf), frame_s)

    def clip(self, action: npt.ArrayLike, measured: npt.ArrayLike,
             heading: npt.ArrayLike | None = None, *, since_s: float | None = None
             ) -> tuple[FloatArray, int]:
        """``action`` (state order: joints in rad, the gap in mm) within the limits, from
        ``measured`` (where the arm was read) and ``heading`` (where it was last told to
        go, ``since_s`` ago; None: nowhere yet); and how many values were changed. A
        value that is not a number becomes the heading's (else the measured one). Told
        less than a frame ago, the last move is still under way: the step allowed is that
        much shorter, so that the two together stay within the speed."""
        a = np.asarray(action, np.float64).reshape(-1)
        m = np.asarray(measured, np.float64).reshape(-1)
        h = m if heading is None else np.asarray(heading, np.float64).reshape(-1)
        n = len(self.names)
        if a.shape != (n,) or m.shape != (n,) or h.shape != (n,):
            raise ConfigError(f"an action has {n} values ({', '.join(self.names)}); got "
                              f"{a.shape[0]} (measured {m.shape[0]}, heading {h.shape[0]})")
        finite = np.isfinite(a)
        asked = np.where(finite, a, h)
        step = np.asarray(self.max_step)
        share = 1.0 if heading is None or since_s is None else min(
            1.0, max(0.0, since_s) / self.frame_s)
        reach = np.where(np.isinf(step), np.inf, share * step)  # the gripper: any step
        out = np.clip(asked, h - reach, h + reach)
        out = np.clip(out, m - LEAD_FRAMES * step, m + LEAD_FRAMES * step)
        out = np.clip(out, np.asarray(self.low), np.asarray(self.high))
        changed = int(np.sum(~finite | (np.abs(out - asked) > 1e-9)))
        return out, changed

    def flat(self, values: FloatArray) -> dict[str, float]:
        """The flat form ``Robot.send_action`` takes: every value, moved in one frame
        (longer only where a joint's speed needs it: ``min_duration_s``)."""
        out = {name: float(v) for name, v in zip(self.names, values, strict=True)}
        out[MIN_DURATION_KEY] = self.frame_s
        return out
