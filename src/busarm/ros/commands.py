"""What the bridge takes from ROS 2 and how it reaches the robot: checked whole first.

- ``/joint_trajectory``: every point is checked against the arm (joint limits, and each
  joint's speed from where the arm stands, point to point) before the first is sent;
  then the points are streamed on schedule (each a timed move to arrive on time). A new
  trajectory replaces the one running. The trajectory stops, and the arm holds where it
  is (MOVE_STOP), on an e-stop, when the bridge closes, and when its sender leaves:
  its publisher's liveliness token goes (the link dropped, the process died). Which
  token is the sender's is known when the message's GID is its token's hash (rmw_zenoh's
  rule); when it is not (another Zenoh SDK's GIDs), every /joint_trajectory publisher
  there when it came is a possible sender, and the first of them to leave ends it: a
  stop too many holds the arm, a stop too few leaves it moving for nobody.
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
from busarm.errors import BusArmError, ConfigError, LimitError, ProtocolError
from busarm.protocol.rmw_zenoh import gid_of, parse_token
from busarm.ros.messages import Trajectory

__all__ = [
    "CLOSED_GAP_M",
    "CMD_VEL_TIMEOUT_S",
    "CmdVel",
    "Plan",
    "Publishers",
    "TrajectoryRunner",
    "plan_trajectory",
]


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
    """The GID of the publisher that sent it (its attachment's)."""
    tokens: frozenset[str] = frozenset()
    """The liveliness tokens whose going ends it (Publishers.of)."""


def plan_trajectory(arm: Arm, trajectory: Trajectory, current_deg: Sequence[float],
                    sender: bytes, tokens: frozenset[str] = frozenset()) -> Plan:
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
    return Plan(trajectory.times_s, tuple(rows), sender, tokens)


class Publishers:
    """The publishers of ``topic`` alive now, by liveliness token (fed every token of the
    domain, as they come and go)."""

    def __init__(self, topic: str) -> None:
        self.topic = topic
        self._lock = threading.Lock()
        self._tokens: set[str] = set()

    def update(self, key: str, alive: bool) -> None:
        try:
            entity = parse_token(key)
        except ProtocolError:
            return  # not an rmw_zenoh entity: nothing to track
        if entity.kind != "MP" or entity.topic != self.topic:
            return
        with self._lock:
            if alive:
                self._tokens.add(key)
            else:
                self._tokens.discard(key)

    def of(self, gid: bytes) -> frozenset[str]:
        """The tokens whose going ends what ``gid`` sent: its own, when ``gid`` is a
        token's hash; else all there now (one of them sent it; which, no one can tell).
        Empty when there is none: no departure can be seen."""
        with self._lock:
            mine = frozenset(t for t in self._tokens if gid_of(t) == gid)
            return mine or frozenset(self._tokens)

    def present(self, tokens: frozenset[str]) -> bool:
        """Whether every one of ``tokens`` is still there."""
        with self._lock:
            return tokens <= self._tokens


class TrajectoryRunner:
    """Streams one plan at a time to the arm, from a worker thread of its own: a new plan
    replaces the one running (or waiting) at once, however many come (a flood costs no
    thread each); a cancel is final for the plan it stops: no point of it is sent after
    the stop (a lock spans each check and send)."""

    def __init__(self, arm: Arm) -> None:
        self.arm = arm
        self._cond = threading.Condition()
        self._send = threading.Lock()
        self._pending: Plan | None = None
        self._generation = 0
        self._closed = False
        self.running: Plan | None = None
        self.last_outcome = ""
        self._thread = threading.Thread(target=self._work, name="ros-trajectory",
                                        daemon=True)
        self._thread.start()

    def start(self, plan: Plan) -> None:
        """Run ``plan`` next, replacing the one running (it is not stopped first: the new
        one was planned from where the arm is, and goes on from there)."""
        with self._cond:
            self._pending = plan
            self._generation += 1
            self._cond.notify_all()

    def cancel(self, why: str, *, hold: bool = True) -> bool:
        """Stop the running plan (the arm holds where it is: MOVE_STOP); False if none
        was running or waiting."""
        with self._send, self._cond:
            was = self.running is not None or self._pending is not None
            self._pending = None
            self._generation += 1
            self._cond.notify_all()
            if was:
                self.last_outcome = f"stopped: {why}"
                log.warning("trajectory stopped: %s", why)
                if hold:
                    self.arm.stop()
        return was

    def sender_left(self, token: str, why: str) -> bool:
        """Stop the running (or waiting) plan if the publisher of liveliness token
        ``token`` may have sent it (Plan.tokens), or its GID is the token's hash."""
        plan = self._pending or self.running
        return plan is not None and (token in plan.tokens or plan.sender == gid_of(token)) \
            and self.cancel(why)

    def close(self) -> None:
        """Stop the running plan (holding) and the worker."""
        self.cancel("the bridge closed")
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self._thread.join(timeout=2.0)

    def _work(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    return
                plan, self._pending = self._pending, None
                generation, self.running = self._generation, plan
            assert plan is not None
            try:
                self._run(plan, generation)
            except BusArmError as exc:
                self.last_outcome = f"failed: {exc}"
                log.error("trajectory failed: %s", exc)
                self.arm.stop()
            finally:
                with self._cond:
                    if self.running is plan:
                        self.running = None

    def _superseded(self, generation: int, until: float) -> bool:
        """Wait until ``until`` (monotonic s); True at once if the plan was replaced or
        cancelled meanwhile."""
        with self._cond:
            return self._cond.wait_for(lambda: self._generation != generation,
                                       timeout=max(0.0, until - time.monotonic()))

    def _run(self, plan: Plan, generation: int) -> None:
        t0, before = time.monotonic(), 0.0
        for t, row in zip(plan.times_s, plan.joints_deg, strict=True):
            if self._superseded(generation, t0 + before):
                return
            with self._send:
                if self._generation != generation:
                    return
                self.arm.command_joints(row, t - before)
            before = t
        if not self._superseded(generation, t0 + plan.times_s[-1]):
            self.last_outcome = f"done: {len(plan.times_s)} points in {before:.2f} s"


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
