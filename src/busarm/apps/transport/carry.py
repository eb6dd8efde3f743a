"""Keeping a carried block: the gripper's temperature and hold watched while the base
drives, so that a long carry neither cooks the gripper nor loses the block.

A gripper holds a block with a light squeeze (``Arm.grip``), which on the twin heads for
about 50 C; a servo still reaching its limit (85 C by default: it then unloads and lets
go) is a hot room, a hard block or a gripper already hot from work. So:

- ``before_carry(carry_s)``: a carry is never started with a gripper too hot to finish
  it: the thermal model (busarm.arm.heat, an assumed hold's effort of ``HOLD_EFFORT``)
  says how long to rest first, the fingers open;
- ``check()`` (every ``PERIOD_S`` of the trip, from the navigator's scan hook): reads the
  gripper's temperature and position and the joints' temperatures; a block no longer
  held stops the trip (``BlockLost``); a gripper heading for its limit is eased to the
  lightest hold, then, still heading there, the trip is stopped (``CarryTooHot``) and
  ``rest()`` waits with the base stopped until it has cooled.
"""

from __future__ import annotations

import math
from typing import Any

from busarm.apps.pick_sort.gripping import still_holding
from busarm.arm.heat import (
    GRIPPER_HEAT,
    HOLD_EFFORT,
    IDLE_EFFORT,
    JOINT_HEAT,
    HeatAction,
    HeatWatch,
)
from busarm.errors import NavigationError
from busarm.progress import Progress, quiet
from busarm.robot import Robot

__all__ = [
    "PERIOD_S",
    "REST_LIMIT_S",
    "START_MARGIN_C",
    "BlockLost",
    "CarryGuard",
    "CarryTooHot",
]


PERIOD_S = 1.0
"""The gripper is read this often while carrying."""
START_MARGIN_C = 6.0
"""A carry starts only if the model says it ends this far below the limit."""
REST_LIMIT_S = 180.0
"""A rest that has not cooled the gripper in this time ends the job."""


class CarryTooHot(NavigationError):
    """The gripper heads for its limit: the trip stops for it to cool."""


class BlockLost(NavigationError):
    """The gripper closed: the block is no longer between its fingers."""


class CarryGuard:
    """The watch over one carry on ``robot`` (see the module docstring)."""

    def __init__(self, robot: Robot, progress: Progress = quiet) -> None:
        self.robot, self.arm, self.progress = robot, robot.arm, progress
        self.gripper_id = self.arm.config.gripper.servo_id
        self.limit_c: float | None = None
        self.watch: HeatWatch | None = None
        self.joint_watch: HeatWatch | None = None
        self.joint_peak_c: float | None = None
        self._hottest = ""
        self._joint_action: HeatAction = "ok"
        self._hottest_c = math.nan
        self.rested_s = 0.0
        self.eased = False
        self.carrying = False
        self._last_s = -math.inf

    @property
    def gripper_peak_c(self) -> float | None:
        return None if self.watch is None else self.watch.peak_c

    def _read(self) -> float:
        """The gripper's temperature now (its limit read once), and the hottest joint's
        (``joint_watch``: its limit the lowest of theirs)."""
        bus, joints = self.arm.bus, self.arm.config.joints
        if self.limit_c is None:
            self.limit_c = float(bus.read_temp_limit_c(self.gripper_id))
            self.watch = HeatWatch(GRIPPER_HEAT, self.limit_c)
            self.joint_watch = HeatWatch(JOINT_HEAT, min(
                float(bus.read_temp_limit_c(j.servo_id)) for j in joints))
        temps = {j.name: float(bus.read_temp_c(j.servo_id)) for j in joints}
        self._hottest = max(temps, key=lambda name: temps[name])
        hottest = self._hottest_c = temps[self._hottest]
        self.joint_peak_c = hottest if self.joint_peak_c is None else max(self.joint_peak_c,
                                                                          hottest)
        assert self.joint_watch is not None
        self._joint_action = self.joint_watch.update(self.robot.clock.now(), hottest)
        return float(bus.read_temp_c(self.gripper_id))

    def before_carry(self, carry_s: float) -> float:
        """Rest first (fingers open, as they are before a pick) if the gripper is too hot
        to hold a block for ``carry_s``; returns the seconds rested."""
        temp = self._read()
        assert self.watch is not None and self.limit_c is not None
        end_c = self.limit_c - START_MARGIN_C
        # Cool enough that the whole carry ends below end_c, and that it starts below
        # where the watch would ease the hold (the squeeze itself heats it too).
        rest = max(GRIPPER_HEAT.rest_before_s(temp, end_c, carry_s, HOLD_EFFORT, IDLE_EFFORT),
                   GRIPPER_HEAT.rest_before_s(temp, self.limit_c - self.watch.ease_margin_c,
                                              0.0, IDLE_EFFORT, IDLE_EFFORT))
        if rest > 0:
            rest = min(rest, REST_LIMIT_S)
            self.progress(f"gripper at {temp:.0f} C: resting {rest:.0f} s so that a "
                          f"{carry_s:.0f} s carry starts cool and ends below {end_c:.0f} C")
            self.robot.clock.sleep(rest)
            self.rested_s += rest
            temp = self._read()
        self.watch.update(self.robot.clock.now(), temp)
        return rest

    def on_scan(self, _nav: Any, _sensed: Any) -> None:
        """The navigator's scan hook: ``check()`` every ``PERIOD_S`` while carrying."""
        if self.carrying and self.robot.clock.now() - self._last_s >= PERIOD_S:
            self.check()

    def check(self, *, arrived: bool = False) -> None:
        """Read the gripper; ease it, or stop the trip (CarryTooHot, BlockLost).
        ``arrived``: the carry is over (the block is put down next): the readings are
        kept, a lost block still raises, the heat is not acted on."""
        now = self._last_s = self.robot.clock.now()
        temp = self._read()
        assert self.watch is not None
        if not still_holding(self.arm):
            raise BlockLost(f"the gripper closed during the carry ({temp:.0f} C): "
                            "the block is no longer held")
        action = self.watch.update(now, temp)
        if arrived:
            self.carrying = False
            return
        if self._joint_action == "rest":  # (a joint holding a pose has no lighter hold)
            assert self.joint_watch is not None
            raise CarryTooHot(f"the {self._hottest} servo is at {self._hottest_c:.0f} C, near "
                              f"its {self.joint_watch.limit_c:.0f} C limit: stopping to let it "
                              "cool")
        if action == "ok" or (action == "ease" and self.eased):
            return
        if not self.eased:
            self.eased = True
            self.arm.hold_lighter()
            self.watch.forget_trend()
            self.progress(f"gripper at {temp:.0f} C: holding the block more lightly")
            return
        raise CarryTooHot(f"the gripper is at {temp:.0f} C, near its {self.limit_c:.0f} C "
                          "limit: stopping to let it cool")

    def rest(self) -> None:
        """The base stopped, the block held lightly: wait until the gripper reads below
        its ease threshold; NavigationError if it does not within ``REST_LIMIT_S``."""
        watch, clock = self.watch, self.robot.clock
        assert watch is not None and self.limit_c is not None
        base = self.robot.base
        if base is not None:
            base.stop()
        self.arm.hold_lighter()
        cool_c = self.limit_c - watch.ease_margin_c
        began = clock.now()
        temp = self._read()
        while temp >= cool_c or self._joint_action != "ok":
            if clock.now() - began > REST_LIMIT_S:
                what = (f"the gripper stayed at {temp:.0f} C" if temp >= cool_c else
                        f"the {self._hottest} servo did not cool")
                raise NavigationError(f"{what} holding the block for {REST_LIMIT_S:g} s of "
                                      f"rest (limit {self.limit_c:.0f} C)")
            clock.sleep(2.0)
            if self.joint_watch is not None:
                self.joint_watch.forget_trend()  # (cooling: the last readings tell)
            temp = self._read()
            watch.update(clock.now(), temp)
        self.rested_s += clock.now() - began
        watch.forget_trend()
        self.progress(f"gripper cooled to {temp:.0f} C: going on")
