"""What the bridge takes from ROS 2 and how it reaches the robot: checked whole first.

- ``/joint_trajectory``: every point is checked against the arm (joint limits, and each
  joint's speed from where the arm stands, point to point) before the first is sent;
  then the points are streamed on schedule (each a timed move to arrive on time). A new
  trajectory replaces the one running. The trajectory stops, and the arm holds where it
  is (MOVE_STOP), on an e-stop, when the bridge closes, and when its sender leaves:
  its publisher's liveliness token goes (the link dropped, the process died).
- ``/cmd_vel``: the base goes at the latest twist, scaled to its limits, until no twist
  has come for ``CMD_VEL_TIMEOUT_S``; then the wheels stop.
- ``/gripper/command``: the gripper's gap in m (0: close and grip).
- ``/estop``, ``/rearm``: latch an emergency stop (arm held, wheels stopped, every
  write refused) until an explicit re-arm.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass

from busarm.arm.arm import Arm
from busarm.base.base import Base
from busarm.errors import BusArmError, ConfigError, LimitError
from busarm.ros.messages import Trajectory

log = logging.getLogger(__name__)

CMD_VEL_TIMEOUT_S = 0.5
"""No /cmd_vel for this long and the wheels stop (teleop nodes send at 10 Hz or more)."""
CLOSED_GAP_M = 0.0005
"""A gripper command at most this wide closes the gripper to grip."""


@dataclass(frozen=True)
class Plan:
    """A trajectory made ready for the arm: every joint at every point (deg), times (s)."""

    times_s: tuple[float, ...]
    joints_deg: tuple[tuple[float, ...], ...]
    sender: bytes
    """The GID of the publisher that sent it."""


def plan_trajectory(arm: Arm, trajectory: Trajectory, current_deg: Sequence[float],
                    sender: bytes) -> Plan:
    """Every joint at every point (a joint not named stays where it is), checked against
    the arm's limits and speeds from ``current_deg``; LimitError or ConfigError naming
    the first bad point, nothing sent."""
    names = [j.name for j in arm.config.joints]
    index = {n: names.index(n) for n in trajectory.joint_names}
    rows: list[tuple[float, ...]] = []
    previous, t_before = tuple(float(v) for v in current_deg), 0.0
    for k, (t, values) in enumerate(zip(trajectory.times_s, trajectory.positions_deg,
                                        strict=True)):
        row = list(previous)
        for name, value in zip(trajectory.joint_names, values, strict=True):
            row[index[name]] = value
        try:
            arm.config.check_joints(row)
        except ConfigError as exc:
            raise LimitError(f"trajectory point {k}: {exc}") from exc
        step = t - t_before
        for j, a, b in zip(arm.config.joints, previous, row, strict=True):
            if abs(b - a) / step > j.max_speed_deg_s * (1 + 1e-9):
                raise LimitError(
                    f"trajectory point {k}: {j.name} would turn {abs(b - a):.1f} deg in "
                    f"{step:.3f} s ({abs(b - a) / step:.0f} deg/s); allowed: at most "
                    f"{j.max_speed_deg_s:g} deg/s (from where the arm is, point to point)")
        rows.append(tuple(row))
        previous, t_before = tuple(row), t
    return Plan(trajectory.times_s, tuple(rows), sender)


class TrajectoryRunner:
    """Streams one plan at a time to the arm, in a thread of its own."""

    def __init__(self, arm: Arm) -> None:
        self.arm = arm
        self._lock = threading.Lock()
        self._cancel = threading.Event()
        self._thread: threading.Thread | None = None
        self.running: Plan | None = None
        self.last_outcome = ""

    def start(self, plan: Plan) -> None:
        """Run ``plan``, replacing (and stopping) the one running."""
        with self._lock:
            self._stop_running(hold=False)
            self._cancel = threading.Event()
            self.running = plan
            self._thread = threading.Thread(target=self._run, args=(plan, self._cancel),
                                            name="ros-trajectory", daemon=True)
            self._thread.start()

    def cancel(self, why: str, *, hold: bool = True) -> bool:
        """Stop the running plan (the arm holds where it is); False if none was running."""
        with self._lock:
            was = self.running is not None
            if was:
                self.last_outcome = f"stopped: {why}"
                log.warning("trajectory stopped: %s", why)
            self._stop_running(hold=hold and was)
            return was

    def cancel_from(self, sender: bytes, why: str) -> bool:
        """Stop the running plan if ``sender`` sent it."""
        plan = self.running
        return plan is not None and plan.sender == sender and self.cancel(why)

    def _stop_running(self, *, hold: bool) -> None:
        self._cancel.set()
        if hold:
            self.arm.stop()  # MOVE_STOP first: the arm holds now, whatever the thread does
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=1.0)
        self._thread, self.running = None, None

    def _run(self, plan: Plan, cancel: threading.Event) -> None:
        t0 = time.monotonic()
        before = 0.0
        try:
            for t, row in zip(plan.times_s, plan.joints_deg, strict=True):
                send_at = t0 + before
                if cancel.wait(max(0.0, send_at - time.monotonic())):
                    return
                self.arm.command_joints(row, t - before)
                before = t
            cancel.wait(max(0.0, t0 + plan.times_s[-1] - time.monotonic()))
            if not cancel.is_set():
                self.last_outcome = f"done: {len(plan.times_s)} points in {before:.2f} s"
        except BusArmError as exc:
            self.last_outcome = f"failed: {exc}"
            log.error("trajectory failed: %s", exc)
            self.arm.stop()
        finally:
            if self.running is plan:  # (not under the lock: cancel() holds it, joining us)
                self.running = None


class CmdVel:
    """The latest /cmd_vel and when it came: ``tick()`` each period drives or stops."""

    def __init__(self, base: Base, timeout_s: float = CMD_VEL_TIMEOUT_S) -> None:
        self.base = base
        self.timeout_s = timeout_s
        self._lock = threading.Lock()
        self._twist: tuple[float, float, float] | None = None
        self._at = -math.inf

    def take(self, twist: tuple[float, float, float]) -> None:
        with self._lock:
            self._twist, self._at = twist, time.monotonic()
        self.tick()

    def tick(self) -> None:
        with self._lock:
            twist, fresh = self._twist, time.monotonic() - self._at <= self.timeout_s
            if twist is not None and not fresh:
                self._twist = None  # timed out: stop once, then wait for the next twist
        if twist is None:
            return
        if fresh:
            self.base.drive(*twist)
        else:
            log.warning("no /cmd_vel for %.1f s: the wheels stop", self.timeout_s)
            self.base.stop()

    def stop(self) -> None:
        with self._lock:
            self._twist = None
        self.base.stop()
