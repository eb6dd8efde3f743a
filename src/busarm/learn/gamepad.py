"""A gamepad as a teleoperator, through Linux's joystick device (``/dev/input/js0``: any
pad the kernel knows, over USB or Bluetooth; no window system or SDL needed).

The device gives 8-byte events (time ms, value -32767..32767, type: button 1, axis 2, with
0x80 on the state it reports when opened; number). A stick held moves its joint at up to
``speed_deg_s`` (in proportion, past a dead zone); let go, the joint stops where it is:

==================  ===============  ==================  ================
left stick  x       base_yaw         right stick  x      wrist_roll
left stick  y       shoulder_pitch   right stick  y      elbow_pitch
d-pad  y            wrist_pitch      A / B (0 / 1)       close / open
Start (7)           back to the start pose
==================  ===============  ==================  ================

``read()`` returns the target in the state's form, moved on by the time since the last
read (``clock``: the wall clock, a person's). It starts as the keyboard's does
(busarm.learn.jog_target).
"""

from __future__ import annotations

import math
import os
import select
import struct
import time
from collections.abc import Callable
from types import TracebackType

from busarm.arm.config import ArmConfig
from busarm.errors import ConfigError
from busarm.learn.jog_target import JogTarget
from busarm.units import check_range

__all__ = [
    "AXES",
    "BUTTONS",
    "DEFAULT_DEVICE",
    "GamepadJog",
]

DEFAULT_DEVICE = "/dev/input/js0"
AXES = {0: (0, 1), 1: (1, -1), 4: (2, -1), 7: (3, -1), 3: (4, 1)}
"""Axis number -> (motor index in the state's order, direction): a stick pushed up is -."""
BUTTONS = {0: -1, 1: 1}
"""Button -> the gripper's direction (A closes, B opens)."""
HOME_BUTTON = 7
_EVENT = struct.Struct("<IhBB")
_BUTTON, _AXIS, _INIT = 0x01, 0x02, 0x80
_FULL = 32767.0
MAX_STEP_S = 0.2
"""A read this long after the last moves the target as if this long had passed (a loop
that stalled does not fling the arm)."""


class GamepadJog:
    """Events from ``device`` (or an open ``fd``) jog a target pose at held rates."""

    def __init__(self, config: ArmConfig, *, device: str = DEFAULT_DEVICE,
                 fd: int | None = None, speed_deg_s: float = 45.0,
                 gripper_mm_s: float = 40.0, dead_zone: float = 0.1,
                 clock: Callable[[], float] = time.monotonic) -> None:
        check_range("speed_deg_s", speed_deg_s, 1.0, 180.0, "deg/s")
        check_range("gripper_mm_s", gripper_mm_s, 1.0, 200.0, "mm/s")
        check_range("dead_zone", dead_zone, 0.0, 0.9, "")
        self.device, self.fd, self._own_fd = device, fd, fd is None
        self.jog = JogTarget(config)
        self.rates = [math.radians(speed_deg_s)] * len(config.joints) + [gripper_mm_s]
        self.dead_zone, self.clock = dead_zone, clock
        self.held = [0.0] * len(self.rates)
        """Each motor's held rate, -1..1 of its top."""
        self._last: float | None = None

    def __repr__(self) -> str:
        return f"GamepadJog({self.device if self._own_fd else f'fd {self.fd}'})"

    def open(self) -> GamepadJog:
        if self.fd is None:
            try:
                self.fd = os.open(self.device, os.O_RDONLY | os.O_NONBLOCK)
            except OSError as exc:
                raise ConfigError(f"gamepad {self.device}: {exc.strerror} (a pad the kernel "
                                  "knows appears as /dev/input/jsN)") from None
        return self

    def begin_at(self, motors: dict[str, float]) -> None:
        """Start (and Start come back) where the arm is: ``motors`` in the state's form."""
        self.jog.begin_at(motors)

    def read(self) -> dict[str, float]:
        """Every event since the last read applied; the target moved on by the rates held
        since then; the target now."""
        if self.fd is None:
            raise ConfigError("the gamepad is not open: open() it first")
        now = self.clock()
        dt = 0.0 if self._last is None else min(max(now - self._last, 0.0), MAX_STEP_S)
        self._last = now
        for k, rate in enumerate(self.held):  # the rates held until now
            if rate:
                self.jog.nudge(k, rate * self.rates[k] * dt)
        while select.select([self.fd], [], [], 0)[0]:
            data = os.read(self.fd, _EVENT.size * 32)
            if not data:
                break
            for offset in range(0, len(data) - _EVENT.size + 1, _EVENT.size):
                self._event(*_EVENT.unpack_from(data, offset))
        return self.jog.values()

    def _event(self, _ms: int, value: int, kind: int, number: int) -> None:
        kind &= ~_INIT
        if kind == _AXIS and number in AXES:
            k, sign = AXES[number]
            x = value / _FULL
            self.held[k] = 0.0 if abs(x) < self.dead_zone else sign * x
        elif kind == _BUTTON and number in BUTTONS:
            self.held[-1] = float(BUTTONS[number]) if value else 0.0
        elif kind == _BUTTON and number == HOME_BUTTON and value:
            self.jog.home()

    def close(self) -> None:
        if self.fd is not None and self._own_fd:
            os.close(self.fd)
        self.fd = None if self._own_fd else self.fd

    def __enter__(self) -> GamepadJog:
        return self.open()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
