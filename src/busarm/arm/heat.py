"""How hot a servo gets holding a load, and when to rest it: a first-order thermal model
(the one the twin's servos obey, busarm.sim.servo_params; docs/twin.md says what of it
is assumed) and a watch over the temperatures read during a long hold.

The manual gives the protection, not the heating: at ``SERVO_TEMP_MAX_LIMIT`` (85 C by
default) a servo unloads its motor until it cools, so a gripper that reaches it lets the
block go. A servo whose effort (torque as a fraction of stall) is ``e`` heads for
``ambient + e * rise`` with the time constant ``tau``:
``T(t) = T_goal + (T0 - T_goal) * exp(-t / tau)``. Readings are whole degrees.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Literal

from busarm.errors import ConfigError
from busarm.sim.servo_params import PARAMS_20KG, PARAMS_35KG, ServoParams
from busarm.units import check_range

__all__ = [
    "GRIPPER_HEAT",
    "HOLD_EFFORT",
    "IDLE_EFFORT",
    "JOINT_HEAT",
    "HeatAction",
    "HeatModel",
    "HeatWatch",
]


@dataclass(frozen=True)
class HeatModel:
    """A servo's first-order heating: ``tau`` (s), the rise at full effort (C), ambient."""

    time_constant_s: float
    full_effort_rise_c: float
    ambient_c: float = 25.0

    def __post_init__(self) -> None:
        check_range("time_constant_s", self.time_constant_s, 1.0, 3600.0, "s")
        check_range("full_effort_rise_c", self.full_effort_rise_c, 1.0, 500.0, "C")
        check_range("ambient_c", self.ambient_c, -40.0, 80.0, "C")

    @classmethod
    def of(cls, params: ServoParams) -> HeatModel:
        """The model a servo's simulation parameters describe."""
        return cls(params.thermal_time_constant_s, params.full_effort_rise_c, params.ambient_c)

    def steady_c(self, effort: float) -> float:
        """Where a servo at ``effort`` (0..1) heads."""
        return self.ambient_c + _effort(effort) * self.full_effort_rise_c

    def temp_after_c(self, temp_c: float, effort: float, duration_s: float) -> float:
        """The temperature ``duration_s`` from now at ``effort``, from ``temp_c``."""
        goal = self.steady_c(effort)
        return goal + (temp_c - goal) * math.exp(-max(0.0, duration_s) / self.time_constant_s)

    def time_to_c(self, temp_c: float, effort: float, limit_c: float) -> float:
        """Seconds until ``limit_c`` at ``effort`` from ``temp_c``: 0 if there already,
        inf if never (the servo heads for the limit or somewhere short of it)."""
        goal = self.steady_c(effort)
        if temp_c >= limit_c:
            return 0.0
        if goal <= limit_c:
            return math.inf
        return self.time_constant_s * math.log((goal - temp_c) / (goal - limit_c))

    def steady_from_c(self, first_c: float, last_c: float, dt_s: float) -> float:
        """Where a servo heads whose temperature went ``first_c`` -> ``last_c`` in
        ``dt_s`` at a constant, unknown effort (the model solved for its goal)."""
        if not dt_s > 0:
            raise ConfigError(f"dt_s = {dt_s!r} must be > 0")
        decay = math.exp(-dt_s / self.time_constant_s)
        return (last_c - first_c * decay) / (1.0 - decay)

    def rest_before_s(self, temp_c: float, limit_c: float, hold_s: float,
                      effort: float = 0.0, rest_effort: float = 0.0) -> float:
        """How long to rest (at ``rest_effort``) first so that a hold of ``hold_s`` at
        ``effort`` ends below ``limit_c``: 0 if it may start now, inf if no rest is
        enough (the hold's own heating alone passes the limit in that time)."""
        check_range("hold_s", hold_s, 0.0, 86400.0, "s")
        goal = self.steady_c(effort)
        # The hottest start from which the hold still ends at the limit.
        grow = math.exp(min(hold_s / self.time_constant_s, 700.0))  # (no overflow)
        start_max = goal + (limit_c - goal) * grow
        if temp_c <= start_max:
            return 0.0
        rest_goal = self.steady_c(rest_effort)
        if start_max <= rest_goal:
            return math.inf
        return self.time_constant_s * math.log((temp_c - rest_goal) / (start_max - rest_goal))


def _effort(effort: float) -> float:
    if not (math.isfinite(effort) and 0.0 <= effort <= 1.0):
        raise ConfigError(f"effort = {effort!r} is out of range 0..1")
    return effort


GRIPPER_HEAT = HeatModel.of(PARAMS_20KG)
"""The 20 kg gripper servo (tau 30 s, +100 C at full effort: assumed, docs/twin.md)."""
JOINT_HEAT = HeatModel.of(PARAMS_35KG)
"""The 35 kg joint servos (tau 40 s)."""
IDLE_EFFORT = PARAMS_20KG.effort_holding
"""A servo holding still with no load (the gripper open)."""
HOLD_EFFORT = 0.5
"""The effort assumed of a light hold (busarm.arm.gripper's squeeze) when planning a
carry before it starts: twice what the twin's hold shows, so a real gripper that
presses harder is still covered; its goal (77 C from 25 C) is under the 85 C limit."""


HeatAction = Literal["ok", "ease", "rest"]
_ADVICE: tuple[HeatAction, ...] = ("ok", "ease", "rest")


class HeatWatch:
    """A servo's temperature read now and then during a hold: its peak, where it heads
    (from the readings of the last ``window_s``), and what to do (``update``).

    "ease" when it reads within ``ease_margin_c`` of its limit or would reach the limit
    within ``ease_horizon_s``; "rest" (stop and let it cool) within ``rest_margin_c`` or
    ``rest_horizon_s``; else "ok". The advice never falls back until ``forget_trend``
    (called once it has been acted on): readings in whole degrees make the trend flicker.
    """

    def __init__(self, model: HeatModel, limit_c: float, *, ease_margin_c: float = 12.0,
                 rest_margin_c: float = 6.0, ease_horizon_s: float = 60.0,
                 rest_horizon_s: float = 20.0, window_s: float = 20.0) -> None:
        check_range("limit_c", limit_c, 30.0, 120.0, "C")
        check_range("rest_margin_c", rest_margin_c, 0.0, 40.0, "C")
        check_range("ease_margin_c", ease_margin_c, rest_margin_c, 60.0, "C")
        check_range("rest_horizon_s", rest_horizon_s, 0.0, 3600.0, "s")
        check_range("ease_horizon_s", ease_horizon_s, rest_horizon_s, 3600.0, "s")
        check_range("window_s", window_s, 1.0, 600.0, "s")
        self.model, self.limit_c = model, float(limit_c)
        self.ease_margin_c, self.rest_margin_c = ease_margin_c, rest_margin_c
        self.ease_horizon_s, self.rest_horizon_s = ease_horizon_s, rest_horizon_s
        self.window_s = window_s
        self.peak_c: float | None = None
        self._readings: deque[tuple[float, float]] = deque()
        self._advice = 0

    @property
    def margin_c(self) -> float | None:
        """The limit less the peak read (None before any reading)."""
        return None if self.peak_c is None else self.limit_c - self.peak_c

    def forget_trend(self) -> None:
        """Drop the readings and the advice (acted on: the effort changed)."""
        self._readings.clear()
        self._advice = 0

    def heading_c(self) -> float | None:
        """Where the readings head (None until they span half the window)."""
        if len(self._readings) < 2:
            return None
        (t0, first), (t1, last) = self._readings[0], self._readings[-1]
        if t1 - t0 < self.window_s / 2:
            return None
        # A reading is a whole degree: the estimate's error shrinks with the span.
        return self.model.steady_from_c(first, last, t1 - t0)

    def time_to_limit_s(self) -> float:
        """Seconds until the limit at the present trend (inf if not heading there)."""
        goal = self.heading_c()
        if goal is None or not self._readings:
            return math.inf
        last = self._readings[-1][1]
        if goal <= last:
            return math.inf
        effort = min(1.0, max(0.0, (goal - self.model.ambient_c) / self.model.full_effort_rise_c))
        return self.model.time_to_c(last, effort, self.limit_c)

    def update(self, t_s: float, temp_c: float) -> HeatAction:
        """Take the reading ``temp_c`` made at ``t_s``; what to do now."""
        if not (math.isfinite(t_s) and math.isfinite(temp_c)):
            raise ConfigError(f"reading ({t_s!r} s, {temp_c!r} C) must be finite")
        if self._readings and t_s < self._readings[-1][0]:
            raise ConfigError(f"reading at {t_s:g} s is before the last one")
        self.peak_c = temp_c if self.peak_c is None else max(self.peak_c, temp_c)
        self._readings.append((t_s, temp_c))
        while self._readings and self._readings[0][0] < t_s - self.window_s:
            self._readings.popleft()
        eta = self.time_to_limit_s()
        if temp_c >= self.limit_c - self.rest_margin_c or eta < self.rest_horizon_s:
            self._advice = 2
        elif temp_c >= self.limit_c - self.ease_margin_c or eta < self.ease_horizon_s:
            self._advice = max(self._advice, 1)
        return _ADVICE[self._advice]
