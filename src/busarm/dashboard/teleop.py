"""Driving the mobile base from the page: a twist held while a key or button is held.

The page sends ``base_drive`` (a twist within the base's limits) when a key or button is
pressed and again every 100 ms while it is held, and ``base_stop`` when it is let go.
``BaseTeleop`` checks the twist against the base's limits, its wheels' included (a
refusal names the value and the range; nothing is sent), and the dashboard's deadman
thread calls ``tick`` every few milliseconds: it repeats the twist to the base
(``Base.drive``, which ramps within the acceleration limits and has its own watchdog)
every ``DRIVE_PERIOD_S``, and stops the wheels at once when no ``base_drive`` has come for
``BASE_HOLD_S``: the page's heartbeats do not keep the base going, only the held twist
asked again does (a key-up lost, a page whose script failed: the wheels stop).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

from busarm.base.base import Base
from busarm.base.kinematics import Twist
from busarm.dashboard.protocol import BaseDrive, RequestError
from busarm.errors import BusArmError, ConfigError

__all__ = [
    "BASE_HOLD_S",
    "DRIVE_PERIOD_S",
    "BaseTeleop",
    "base_limits",
]


BASE_HOLD_S = 0.25
"""The wheels stop when no ``base_drive`` has come for this long (the page asks again every
100 ms while a key is held): stopped within 300 ms of its last one."""
DRIVE_PERIOD_S = 0.05
"""The held twist is sent to the base this often (its watchdog stops the wheels after
``command_timeout_s``, 0.5 s on the JetAuto)."""


def base_limits(base: Base) -> dict[str, Any]:
    """What the page shows and keeps to: the base's speed limits."""
    cfg = base.config
    return {"name": cfg.name, "max_speed_m_s": cfg.max_speed_m_s,
            "max_yaw_rate_rad_s": cfg.max_yaw_rate_rad_s,
            "max_yaw_rate_deg_s": math.degrees(cfg.max_yaw_rate_rad_s),
            "hold_ms": round(BASE_HOLD_S * 1000)}


class BaseTeleop:
    """The base's held twist (``start``, ``stop``), driven by ``tick``; ``say`` logs;
    ``now``: the wall clock's seconds (monotonic), which the page's messages keep."""

    def __init__(self, base: Base, say: Callable[[str, str], None],
                 now: Callable[[], float] = time.monotonic) -> None:
        self.base = base
        self.say = say
        self.now = now
        self._lock = threading.Lock()
        self._twist: Twist | None = None
        self._sent_at = -math.inf
        self._asked_at = -math.inf  # when the held twist was last asked for (monotonic)

    @property
    def twist(self) -> Twist | None:
        """The twist held now (None: not driving)."""
        return self._twist

    def check(self, request: BaseDrive) -> Twist:
        """The request's twist, if within the base's limits and its wheels'; else
        RequestError naming the value and the range (nothing is scaled in silence)."""
        twist = Twist(request.vx_m_s, request.vy_m_s, request.wz_rad_s)
        try:
            self.base.kinematics.check_limits(twist)
        except ConfigError as exc:
            raise RequestError(f"base_drive: {exc}") from None
        return twist

    def start(self, twist: Twist) -> None:
        """Drive at ``twist`` from now on (sent at once)."""
        with self._lock:
            started = self._twist is None
            self._asked_at = self.now()
            try:
                self._send(twist)
            except BusArmError:
                self._twist = None
                raise
            self._twist = twist
        if started:
            self.say(f"base: driving at {_twist_text(twist)}", "info")

    def stop(self, why: str) -> None:
        """Stop the wheels at once (sent even when not driving: a stop is never wrong)."""
        failed = None
        with self._lock:  # nothing said under it: saying takes the dashboard's lock
            was, self._twist = self._twist, None
            try:
                self.base.stop()
            except BusArmError as exc:
                failed = str(exc)
        if failed is not None:
            self.say(f"base: the stop could not be sent: {failed}", "error")
        elif was is not None:
            self.say(f"base stopped ({why})", "info")

    def tick(self) -> None:
        """Repeat the twist (due every DRIVE_PERIOD_S), or stop the wheels when it has not
        been asked for again for BASE_HOLD_S."""
        twist = self._twist
        if twist is None:
            return
        if self.now() - self._asked_at > BASE_HOLD_S:
            self.stop(f"no drive from the driver for {BASE_HOLD_S * 1000:.0f} ms")
            return
        if self.now() - self._sent_at < DRIVE_PERIOD_S:
            return
        with self._lock:
            if self._twist is not twist:
                return  # stopped (or changed) meanwhile
            try:
                self._send(twist)
                return
            except BusArmError as exc:
                failed = str(exc)
        self.stop(f"the base refused: {failed}")

    def state(self) -> dict[str, Any]:
        """The base for the page: the odometry's pose and velocity, the twist held."""
        try:
            odom = self.base.odometry()
        except BusArmError as exc:
            return {"error": f"the base did not answer: {exc}"}
        p, v, held = odom.pose, odom.twist, self._twist
        return {"x_m": p.x_m, "y_m": p.y_m, "yaw_deg": p.yaw_deg, "vx_m_s": v.vx_m_s,
                "vy_m_s": v.vy_m_s, "wz_deg_s": math.degrees(v.wz_rad_s),
                "source": odom.source, "driving": None if held is None else {
                    "vx_m_s": held.vx_m_s, "vy_m_s": held.vy_m_s, "wz_rad_s": held.wz_rad_s}}

    def _send(self, twist: Twist) -> None:
        self.base.drive(twist.vx_m_s, twist.vy_m_s, twist.wz_rad_s)
        self._sent_at = self.now()


def _twist_text(twist: Twist) -> str:
    return (f"{twist.vx_m_s:+.2f} m/s forward, {twist.vy_m_s:+.2f} m/s left, "
            f"{math.degrees(twist.wz_rad_s):+.0f} deg/s")
