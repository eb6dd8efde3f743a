"""Jogging: a joint or the tool moving at a steady speed while a person holds a key.

Pure planning, no I/O: ``JogPlan.step`` turns where the jog's target is now into the
next target one control period on, in joint degrees, or says why it cannot go on (a
joint limit, the edge of the reach). The target runs ahead of the measured joints by at
most ``MAX_LEAD_S`` of motion, so an arm that is held back (a stall, a slow bus) is not
wound up; the servo is sent each target to reach in one period, so when the targets stop
coming it stops within a period, and a stop (MOVE_STOP) halts it at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from busarm.arm.config import ArmConfig
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import KinematicsError

__all__ = [
    "EDGE_DEG",
    "JOINT_JOG_DEG_S",
    "MAX_LEAD_S",
    "PITCH_JOG_DEG_S",
    "TOOL_JOG_MM_S",
    "JogPlan",
    "JogStep",
]


JOINT_JOG_DEG_S = 30.0
"""A joint jog's speed at full speed (1.0), capped by the joint's own limit."""
TOOL_JOG_MM_S = 40.0
"""The tool's speed along x, y or z at full speed."""
PITCH_JOG_DEG_S = 30.0
"""The tool's pitch rate at full speed."""
MAX_LEAD_S = 0.3
"""How far ahead of the measured joints (in seconds of jog motion) a target may run."""
EDGE_DEG = 0.05
"""A joint this close to its limit counts as at it (a jog toward it does not move)."""


@dataclass(frozen=True)
class JogStep:
    """The next joint targets, or why the jog stops (``blocked``)."""

    joints_deg: tuple[float, ...] | None
    blocked: str | None = None


class JogPlan:
    """A jog of ``joint`` (a name) or ``axis`` (x, y, z, pitch) in ``direction`` (+1/-1)
    at ``speed`` (0..1 of the full jog speed)."""

    def __init__(self, config: ArmConfig, kin: ArmKinematics, *, joint: str | None,
                 axis: str | None, direction: int, speed: float) -> None:
        self.config, self.kin = config, kin
        self.joint = joint
        self.axis = axis
        self.direction = direction
        self.speed = speed
        self.index = [j.name for j in config.joints].index(joint) if joint else None

    def same_as(self, joint: str | None, axis: str | None, direction: int) -> bool:
        return (joint, axis, direction) == (self.joint, self.axis, self.direction)

    def rate(self) -> float:
        """deg/s of the joint, mm/s of the tool, or deg/s of its pitch."""
        if self.index is not None:
            return self.speed * min(JOINT_JOG_DEG_S, self.config.joints[self.index].max_speed_deg_s)
        return self.speed * (PITCH_JOG_DEG_S if self.axis == "pitch" else TOOL_JOG_MM_S)

    def step(self, target_deg: Sequence[float], measured_deg: Sequence[float],
             period_s: float) -> JogStep:
        """The targets ``period_s`` on from ``target_deg`` (the last ones sent)."""
        if self.index is not None:
            return self._joint_step(target_deg, measured_deg, period_s)
        return self._tool_step(target_deg, measured_deg, period_s)

    def _joint_step(self, target: Sequence[float], measured: Sequence[float],
                    period_s: float) -> JogStep:
        assert self.index is not None
        j = self.config.joints[self.index]
        rate = self.rate()
        lead = abs(target[self.index] - measured[self.index])
        step = 0.0 if lead > rate * MAX_LEAD_S else rate * period_s
        angle = target[self.index] + self.direction * step
        angle = min(max(angle, j.min_deg), j.max_deg)
        if abs(angle - target[self.index]) < 1e-9 and step > 0:
            edge = j.max_deg if self.direction > 0 else j.min_deg
            return JogStep(None, f"{j.name} is at its limit ({edge:g} deg)")
        out = list(target)
        out[self.index] = angle
        return JogStep(tuple(out))

    def _tool_step(self, target: Sequence[float], measured: Sequence[float],
                   period_s: float) -> JogStep:
        pose = self.kin.fk(target)
        now = self.kin.fk(measured)
        rate = self.rate()
        values = {"x": pose.x_mm, "y": pose.y_mm, "z": pose.z_mm, "pitch": pose.pitch_deg}
        at = {"x": now.x_mm, "y": now.y_mm, "z": now.z_mm, "pitch": now.pitch_deg}
        assert self.axis is not None
        lead = abs(values[self.axis] - at[self.axis])
        if lead > rate * MAX_LEAD_S:
            return JogStep(tuple(target))  # the arm catches up first
        values[self.axis] += self.direction * rate * period_s
        try:
            joints = self.kin.ik_best(values["x"], values["y"], values["z"], values["pitch"],
                                      current_deg=target)
        except KinematicsError as exc:
            sign = "+" if self.direction > 0 else "-"
            return JogStep(None, f"the tool cannot go further in {sign}{self.axis}: {exc}")
        # A jog near a singularity asks a joint for a leap: refuse it rather than fling
        # the arm (the joint's own speed limit over this period).
        for j, a, b in zip(self.config.joints, target, joints, strict=True):
            if abs(b - a) > j.max_speed_deg_s * period_s * 1.5 + 1e-6:
                return JogStep(None, f"the tool cannot go on in that direction here: "
                                     f"{j.name} would turn faster than "
                                     f"{j.max_speed_deg_s:g} deg/s")
        return JogStep(tuple(joints))

