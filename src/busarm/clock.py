"""Clocks: the one source of time for everything that waits on the robot.

Hardware runs on the wall clock (``WALL_CLOCK``). A simulation in this process runs on a
``SimClock``: simulated seconds that pass only when someone waits on them, and each wait
first runs whatever is attached to the clock (the twin's physics, later the base and the
Lidar) up to the new time. A program that waits for a servo to arrive therefore waits as
long as the CPU needs to simulate the move, not as long as the move takes, and every time
it reports is in simulated seconds. ``SimClock(pace=1.0)`` keeps it no faster than the
wall clock, for a person watching.

The bus driver, the arm, the apps and the twin take their clock from the transport
(``transport.clock``), so one decision, made where the transport is opened, holds for
the whole job.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Protocol, runtime_checkable

from busarm.units import check_range

__all__ = [
    "MAX_SLEEP_S",
    "WALL_CLOCK",
    "Clock",
    "SimClock",
    "WallClock",
]


MAX_SLEEP_S = 3600.0
"""The longest single wait a clock accepts (a wait this long is a bug, not a plan)."""


@runtime_checkable
class Clock(Protocol):
    """Seconds that only go forward, and a way to wait for them to pass."""

    @property
    def is_simulated(self) -> bool:
        """True when time passes only as fast as a simulation computes it."""
        ...

    def now(self) -> float:
        """Seconds since an arbitrary start (monotonic)."""
        ...

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` of this clock's time (0 or more)."""
        ...

    def wait(self, event: threading.Event, seconds: float) -> bool:
        """Wait up to ``seconds`` of this clock's time for ``event``; whether it is set."""
        ...


def _check_sleep(seconds: float) -> float:
    # A negative wait (a deadline already passed) is no wait; a huge one is a bug.
    return max(check_range("sleep seconds", seconds, -math.inf, MAX_SLEEP_S, "s"), 0.0)


class WallClock:
    """The machine's monotonic clock: hardware, and a twin other processes talk to."""

    is_simulated = False
    now = staticmethod(time.monotonic)  # no Python frame on the bus's hot path

    def sleep(self, seconds: float) -> None:
        time.sleep(_check_sleep(seconds))

    def wait(self, event: threading.Event, seconds: float) -> bool:
        return event.wait(_check_sleep(seconds))

    def __repr__(self) -> str:
        return "WallClock()"


WALL_CLOCK = WallClock()
"""The one wall clock; hardware transports hand it out."""


class SimClock:
    """Simulated time, moved forward by ``sleep`` in steps of at most ``step_s``.

    After each step every attached callback runs (``attach``): the twin steps its physics
    to the new time there. ``pace`` = None runs as fast as the CPU allows; ``pace`` = 1.0
    never lets simulated time get ahead of the wall clock (2.0: twice as fast). Thread
    safe: waits from several threads take turns, each moving time forward.
    """

    is_simulated = True

    def __init__(self, start_s: float = 0.0, *, step_s: float = 0.004,
                 pace: float | None = None) -> None:
        self.step_s = check_range("step_s", step_s, 1e-5, 1.0, "s")
        if pace is not None:
            check_range("pace", pace, 0.01, 1000.0)
        self.pace = pace
        self._now = float(start_s)
        self._lock = threading.RLock()
        self._callbacks: list[Callable[[], None]] = []
        self._wall_start = time.monotonic()
        self._sim_start = self._now

    def now(self) -> float:
        return self._now

    def attach(self, callback: Callable[[], None]) -> None:
        """Run ``callback()`` after every step of simulated time."""
        with self._lock:
            self._callbacks.append(callback)

    def detach(self, callback: Callable[[], None]) -> None:
        """Stop running ``callback`` (no error if it was not attached)."""
        with self._lock:
            if callback in self._callbacks:
                self._callbacks.remove(callback)

    def sleep(self, seconds: float) -> None:
        seconds = _check_sleep(seconds)
        with self._lock:
            end = self._now + seconds
            while self._now < end - 1e-12:
                self._now = min(end, self._now + self.step_s)
                for callback in list(self._callbacks):
                    callback()
            # A wait within the rounding tolerance still ends at its end: a caller
            # waiting for a deadline (now >= deadline) would otherwise spin forever.
            self._now = max(self._now, end)
            if self.pace is not None:
                ahead = (self._now - self._sim_start) / self.pace - (
                    time.monotonic() - self._wall_start)
                if ahead > 0:
                    time.sleep(ahead)

    def wait(self, event: threading.Event, seconds: float) -> bool:
        # Another thread sets the event in wall time: look at it every step.
        end = self._now + _check_sleep(seconds)
        while not event.is_set() and self._now < end - 1e-12:
            self.sleep(min(self.step_s, end - self._now))
        return event.is_set()

    def __repr__(self) -> str:
        return f"SimClock(now={self._now:.3f} s, pace={self.pace})"
