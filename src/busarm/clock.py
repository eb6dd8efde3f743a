"""Clocks: the one source of time for everything that waits on the robot.

Hardware runs on the wall clock (``WALL_CLOCK``). A simulation in this process runs on a
``SimClock``: simulated seconds that pass only when someone waits on them, and each wait
first runs whatever is attached to the clock (the twin's physics, later the base and the
Lidar) up to the new time. A program that waits for a servo to arrive therefore waits as
long as the CPU needs to simulate the move, not as long as the move takes, and every time
it reports is in simulated seconds. ``SimClock(pace=1.0)`` keeps it no faster than the
wall clock, for a person watching.

Such a clock stands still while a program waits any other way: ``time.sleep(1.0)`` on a
twin in this process leaves its physics, odometry and camera stamps where they were. A
clock that ``warn_when_frozen`` was asked of (the twin asks it of its own) says so once, a
``FrozenClockWarning``, when it is read after the wall clock ran ``FROZEN_AFTER_S`` ahead
while it stood still and the program waited (blocked, not computing).

The bus driver, the arm, the apps and the twin take their clock from the transport
(``transport.clock``), so one decision, made where the transport is opened, holds for
the whole job.
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
import warnings
from collections.abc import Callable
from typing import Protocol, runtime_checkable

from busarm.units import check_range

__all__ = [
    "FROZEN_AFTER_S",
    "IDLE_SHARE",
    "MAX_SLEEP_S",
    "SAMPLE_S",
    "WALL_CLOCK",
    "Clock",
    "FrozenClockWarning",
    "SimClock",
    "WallClock",
]


MAX_SLEEP_S = 3600.0
"""The longest single wait a clock accepts (a wait this long is a bug, not a plan)."""
FROZEN_AFTER_S = 0.5
"""Wall seconds a watched simulated clock may stand still while the program waits before
a read of it warns (``SimClock.warn_when_frozen``)."""
IDLE_SHARE = 0.1
"""Waiting, not computing: the reading thread was blocked (``time.sleep``, a lock) for all
but this share of the time the clock stood still. Where the scheduler's statistics are not
to be had (not Linux): the process used less than this share of it on the CPU. A program
that computes (a plan, a render) leaves the clock standing too, but busy; one starved of
the CPU on a loaded machine waits for a CPU, which is not blocking."""
SAMPLE_S = 0.1
"""A watched clock samples its thread's scheduler times at most this often (wall s)."""
_SCHEDSTAT = "/proc/thread-self/schedstat"


class FrozenClockWarning(UserWarning):
    """A simulated clock stood still while the wall clock ran: the program waited with
    ``time.sleep`` (or on something else) instead of the robot's clock, so the simulation
    it reads did not move. Wait with ``robot.clock.sleep(seconds)``."""


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
        self._watch: _Watch | None = None
        """The frozen-clock watch; None: not watched (or warned once)."""

    def now(self) -> float:
        # The frozen-clock watch costs one wall-clock read per call while it is on: the
        # reads that matter (odometry, a frame, a scan) all ask the time first.
        watch = self._watch
        if watch is not None and time.monotonic() - watch.moved_wall_s >= FROZEN_AFTER_S:
            self._check_frozen(watch)
        return self._now

    def warn_when_frozen(self, owner: str) -> None:
        """Warn once (``FrozenClockWarning``) when this clock is read after it stood still
        for ``FROZEN_AFTER_S`` of wall time while the program waited (``IDLE_SHARE``): a
        program in ``time.sleep``, which moves no simulated time. ``owner`` names what
        keeps this time in the message (``the twin``)."""
        self._watch = _Watch(owner)

    def _check_frozen(self, watch: _Watch) -> None:
        if not self._lock.acquire(blocking=False):
            watch.moved()  # another thread is waiting on this clock: it moves
            return
        self._lock.release()
        stood_s = watch.stood_idle_s()
        if stood_s is None or self._watch is not watch:
            return
        self._watch = None  # once: a program that means it need not hear it again
        warnings.warn(FrozenClockWarning(
            f"{watch.owner} keeps simulated time, and it stood still for {stood_s:.1f} s "
            f"of wall time before this read ({self._now:.3f} s on its clock): time.sleep "
            "does not move it. Wait with robot.clock.sleep(seconds), not time.sleep"),
            stacklevel=_caller_outside_busarm())

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
            if self._watch is not None:
                self._watch.moved()

    def wait(self, event: threading.Event, seconds: float) -> bool:
        # Another thread sets the event in wall time: look at it every step.
        end = self._now + _check_sleep(seconds)
        while not event.is_set() and self._now < end - 1e-12:
            self.sleep(min(self.step_s, end - self._now))
        return event.is_set()

    def __repr__(self) -> str:
        return f"SimClock(now={self._now:.3f} s, pace={self.pace})"


def _thread_times() -> tuple[float, float] | None:
    """This thread's time on a CPU and waiting for one (s, since it started), from Linux's
    scheduler statistics; None where there are none."""
    try:
        with open(_SCHEDSTAT, "rb") as stats:
            on_cpu_ns, waiting_ns = stats.read().split()[:2]
        return int(on_cpu_ns) / 1e9, int(waiting_ns) / 1e9
    except (OSError, ValueError):
        return None


class _Watch:
    """A watched clock's memory: when it last moved (wall time), and a sample of the
    scheduler's times of the thread that moved it, to tell waiting from computing."""

    def __init__(self, owner: str) -> None:
        self.owner = owner
        self.moved_wall_s = self._sample_wall_s = -math.inf
        self._thread = 0
        self._sample_cpu_s = 0.0
        self._sample_times: tuple[float, float] | None = None
        self.moved()

    def moved(self) -> None:
        """The clock moved (or the program was found busy): watch from now."""
        wall = time.monotonic()
        self.moved_wall_s = wall
        # A sample costs a file read: taken now and then, not at every step.
        if wall - self._sample_wall_s >= SAMPLE_S or threading.get_ident() != self._thread:
            self._thread = threading.get_ident()
            self._sample_wall_s, self._sample_cpu_s = wall, time.process_time()
            self._sample_times = _thread_times()

    def stood_idle_s(self) -> float | None:
        """How long the clock has stood still if the program spent it waiting; None if it
        was busy (then the watch starts again from now)."""
        wall = time.monotonic()
        stood_s, since_sample_s = wall - self.moved_wall_s, wall - self._sample_wall_s
        times = _thread_times() if threading.get_ident() == self._thread else None
        if times is not None and self._sample_times is not None:
            # Blocked: neither on a CPU nor waiting for one (a loaded machine's wait).
            blocked_s = since_sample_s - sum(times) + sum(self._sample_times)
            idle = blocked_s >= (1.0 - IDLE_SHARE) * stood_s
        else:
            idle = time.process_time() - self._sample_cpu_s < IDLE_SHARE * since_sample_s
        if idle:
            return stood_s
        self._sample_wall_s = -math.inf
        self.moved()
        return None


_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep


def _caller_outside_busarm() -> int:
    """The ``stacklevel`` of ``warnings.warn`` (called two frames below here) that names
    the first line outside busarm: the program's read, not the clock's inside."""
    frame = sys._getframe(2)  # the clock's own caller's frame is stacklevel 2
    level = 2
    while frame.f_back is not None and frame.f_code.co_filename.startswith(_PACKAGE_DIR):
        frame = frame.f_back
        level += 1
    return level
