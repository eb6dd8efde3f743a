"""The robot's live values, read off the bus as it runs (the dashboard's, the ROS bridge's).

Each control period reads the fast values (every servo's position); the slow ones take
turns, one value a period: a servo's temperature, voltage or torque (six servos: each
value about every 0.7 s at 25 Hz), and every fourth period where the gripper was last
told to go (MOVE_TIME_READ: with its position, whether it holds something). Reads go
straight to the bus, never through the arm's motion lock: a job moving the arm (which
holds that lock for the whole move) is watched live.

Alarms are the servo's own limits against its readings (as ``busarm info`` shows them);
the limits are read once, when the reader starts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from busarm.arm.arm import Arm
from busarm.arm.gripper import gripper_state
from busarm.errors import BusArmError

__all__ = [
    "SLOW_VALUES",
    "TARGET_EVERY",
    "Reading",
    "ServoReadings",
    "StateReader",
]


SLOW_VALUES = ("temp", "vin", "torque")
TARGET_EVERY = 4
"""Read the gripper's last commanded position every this many periods."""


@dataclass
class ServoReadings:
    """The slow values of one servo (None until read, or when the read failed)."""

    servo_id: int
    temp_c: float | None = None
    vin_v: float | None = None
    torque_on: bool | None = None
    temp_limit_c: float | None = None
    vin_limits_v: tuple[float, float] | None = None
    error: str | None = None

    def alarms(self) -> list[str]:
        out = []
        if (self.temp_c is not None and self.temp_limit_c is not None
                and self.temp_c >= self.temp_limit_c):
            out.append(f"over temperature ({self.temp_c:.0f} C, limit "
                       f"{self.temp_limit_c:.0f} C)")
        if self.vin_v is not None and self.vin_limits_v is not None and not (
                self.vin_limits_v[0] <= self.vin_v <= self.vin_limits_v[1]):
            lo, hi = self.vin_limits_v
            out.append(f"voltage {self.vin_v:.2f} V outside {lo:.1f}..{hi:.1f} V")
        if self.error:
            out.append(self.error)
        return out

    def as_dict(self) -> dict[str, Any]:
        return {"id": self.servo_id, "temp_c": self.temp_c, "vin_v": self.vin_v,
                "torque": self.torque_on, "alarms": self.alarms()}


@dataclass
class Reading:
    """One period's fast values."""

    joints_deg: tuple[float, ...]
    gripper_pulses: int
    gripper_target_pulses: int | None
    at_s: float = field(default_factory=time.monotonic)


class StateReader:
    """Reads the robot's live values; ``read()`` each period, ``as_dict`` for the page."""

    def __init__(self, arm: Arm, *, slow_every: int = 1) -> None:
        self.arm = arm
        self.servos = {sid: ServoReadings(sid) for sid in arm.config.servo_ids}
        self.slow_every = slow_every
        """Read a slow value every this many periods (a fast reader need not read them
        every time: they change over seconds)."""
        self._period = 0
        self._turn = 0
        self.last: Reading | None = None
        self._last_gap: float | None = None
        for s in self.servos.values():
            self._read_limits(s)

    def _read_limits(self, s: ServoReadings) -> None:
        bus = self.arm.bus
        try:
            s.temp_limit_c = float(bus.read_temp_limit_c(s.servo_id))
            s.vin_limits_v = bus.read_vin_limits_v(s.servo_id)
        except BusArmError as exc:
            s.error = f"limits not read: {exc}"

    def read(self) -> Reading:
        """The fast values now, and every ``slow_every``-th time one slow value
        (BusArmError if a read fails)."""
        arm, bus = self.arm, self.arm.bus
        pulses = {j.servo_id: bus.read_position_pulses(j.servo_id) for j in arm.config.joints}
        gid = arm.config.gripper.servo_id
        grip = bus.read_position_pulses(gid)
        target = self.last.gripper_target_pulses if self.last is not None else None
        if target is None or self._period % TARGET_EVERY == 0:
            target = bus.last_target_pulses(gid)  # the last one it was told
        self.last = Reading(arm.joints_from_pulses(pulses), grip, target)
        self._period += 1
        if self._period % self.slow_every == 0:
            self._read_slow()
        return self.last

    def _read_slow(self) -> None:
        ids = list(self.servos)
        k, self._turn = self._turn, self._turn + 1
        s = self.servos[ids[k % len(ids)]]
        value = SLOW_VALUES[(k // len(ids)) % len(SLOW_VALUES)]
        bus = self.arm.bus
        try:
            if value == "temp":
                s.temp_c = float(bus.read_temp_c(s.servo_id))
            elif value == "vin":
                s.vin_v = bus.read_vin_v(s.servo_id)
            else:
                s.torque_on = bus.read_torque(s.servo_id)
            s.error = None if s.temp_limit_c is not None else s.error
        except BusArmError as exc:
            s.error = f"not answering: {exc}"

    def gripper(self, reading: Reading) -> dict[str, Any]:
        """The gripper's gap (mm) and state: open, closed or holding
        (busarm.arm.gripper's rule), or moving while its gap changes."""
        g = self.arm.config.gripper
        torque = self.servos[g.servo_id].torque_on
        state = gripper_state(g, reading.gripper_pulses, reading.gripper_target_pulses,
                              torque)
        moving = self._last_gap is not None and abs(state.gap_mm - self._last_gap) > 0.3
        self._last_gap = state.gap_mm
        return {"gap_mm": round(state.gap_mm, 1), "state": "moving" if moving else state.state}

    def as_dict(self, reading: Reading) -> dict[str, Any]:
        """The values for the page, in deg and mm."""
        kin = self.arm.kin
        joints = reading.joints_deg
        pose = kin.fk(joints)
        links = [[0.0, 0.0, 0.0]] + [[round(float(v), 1) for v in f[:3, 3]]
                                     for f in kin.frames(joints)]
        return {
            "joints_deg": [round(a, 2) for a in joints],
            "tool": {"x_mm": round(pose.x_mm, 1), "y_mm": round(pose.y_mm, 1),
                     "z_mm": round(pose.z_mm, 1), "pitch_deg": round(pose.pitch_deg, 1)},
            "links_mm": links,
            "gripper": self.gripper(reading),
            "servos": [s.as_dict() for s in self.servos.values()],
        }
