"""Navigation transport: fetch a block from one named point and deliver it to another.

``run_transport(robot, grid, points, "shelf", "bin")``: localise on the saved map (near a
given start, or anywhere), drive to the pick point (busarm.apps.navigation.navigator), stand there
exactly (the filter's estimate refined standing still, the last centimetres closed by
``move_by``), look for the block with the wrist camera and locate it in millimetres,
line the base up and pick it with the grasp verified (busarm.apps.transport.mobile_pick, with
retries), drive to the place point, put it down and look that it is there. Every phase
is timed and kept for the report; a phase that cannot be done stops the job with the
wheels stopped and the arm holding, and the report says which and why: a block is
reported delivered only when the last look saw it where it was put.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from busarm.apps.navigation.navigator import Navigator, NavSettings, ScanHook, Trip
from busarm.apps.transport.mobile_pick import (
    BlockSeen,
    PickResult,
    PlaceResult,
    Surface,
    look_for_blocks,
    pick_block,
    place_block,
)
from busarm.base.odometry import Pose2D
from busarm.errors import BusArmError, HaltedError, NavigationError, why_stopped
from busarm.nav.grid import OccupancyGrid
from busarm.nav.mapping import compose
from busarm.nav.points import WORK_AHEAD_M, NamedPoint, NamedPoints
from busarm.progress import Progress, quiet
from busarm.robot import Robot

__all__ = [
    "APPROACH_M",
    "KEEP_OUT_M",
    "SETTLE_SCANS",
    "SETTLE_TOLERANCE_DEG",
    "SETTLE_TOLERANCE_M",
    "STOW_POSE",
    "TEACH_LIMIT_S",
    "Phase",
    "TransportJob",
    "TransportReport",
    "run_transport",
    "teach_point",
]


SETTLE_TOLERANCE_M = 0.01
SETTLE_TOLERANCE_DEG = 1.0
SETTLE_SCANS = 4
APPROACH_M = 0.25
"""A point is approached straight, from this far behind it."""
KEEP_OUT_M = 0.05
"""The base never drives over a point's work spot (blocks there are below the Lidar)."""
STOW_POSE = "home"
TEACH_LIMIT_S = 5.0
"""The arm's pose while the base drives (folded over the base)."""


@dataclass
class Phase:
    name: str
    seconds: float
    ok: bool
    detail: str = ""


@dataclass
class TransportReport:
    """One transport job: what happened in each phase, and whether the block arrived."""

    pick: str
    place: str
    delivered: bool = False
    why: str = ""
    color: str | None = None
    seconds: float = 0.0
    phases: list[Phase] = field(default_factory=list)
    pick_attempts: int = 0
    placed_at_m: tuple[float, float] | None = None
    """Where the block was put down (map frame), as the final look saw it."""
    trips: list[Trip] = field(default_factory=list)

    @property
    def driven_m(self) -> float:
        return sum(t.driven_m for t in self.trips)

    def to_dict(self) -> dict[str, Any]:
        return {
            "pick": self.pick, "place": self.place, "delivered": self.delivered,
            "why": self.why, "color": self.color, "seconds": round(self.seconds, 2),
            "driven_m": round(self.driven_m, 3), "pick_attempts": self.pick_attempts,
            "placed_at_m": None if self.placed_at_m is None else
            [round(v, 4) for v in self.placed_at_m],
            "phases": [{"name": p.name, "seconds": round(p.seconds, 2), "ok": p.ok,
                        "detail": p.detail} for p in self.phases],
            "trips": [{"goal": [round(t.goal.x_m, 3), round(t.goal.y_m, 3),
                                round(t.goal.yaw_deg, 1)], "ok": t.ok, "why": t.why,
                       "seconds": round(t.seconds, 2), "driven_m": round(t.driven_m, 3),
                       "obstacle_stops": t.obstacle_stops, "replans": len(t.plans)}
                      for t in self.trips],
        }


class TransportJob:
    """One transport on ``robot`` over ``grid`` between two of ``points``."""

    def __init__(self, robot: Robot, grid: OccupancyGrid, points: NamedPoints, pick: str,
                 place: str, *, color: str | None = None, retries: int = 2,
                 settings: NavSettings | None = None, seed: int = 0,
                 progress: Progress = quiet, on_scan: ScanHook | None = None) -> None:
        self.robot = robot
        self.pick_point: NamedPoint = points.get(pick)
        self.place_point: NamedPoint = points.get(place)
        self.color = color
        self.retries = retries
        self.progress = progress
        self.nav = Navigator(robot, grid, settings=settings, seed=seed, on_scan=on_scan)
        self.report = TransportReport(pick, place)
        self.pictures: list[tuple[str, Any]] = []
        """(name, BGR image): what the camera saw at the pick point."""

    def run(self, start: Pose2D | None = None) -> TransportReport:
        """The whole job; never raises for a job that did not work (the report says
        why), only for bad input found before anything moved, and for a person's stop
        (Ctrl+C, SIGTERM or SIGHUP, a halt: HaltedError), the wheels stopped and the
        report so far kept in ``report``."""
        clock = self.robot.clock
        began = clock.now()
        try:
            self._phase("stow the arm", self._stow)
            self._phase("localise", lambda: self._localise(start))
            self._go("drive to " + self.pick_point.name, self.pick_point)
            block = self._phase("look for the block", self._look)
            # Carried as the pick left it, lifted over the deck: folding the arm with a
            # block in the fingers knocked it out against the chassis.
            self._phase("pick", lambda: self._pick(block))
            self._go("drive to " + self.place_point.name, self.place_point)
            self._phase("place", self._place)
        except BaseException as exc:
            self.report.why = _why(exc)
            if not _failed(exc):  # a person's stop (or a bug): the wheels stop, it goes on
                with contextlib.suppress(BusArmError):
                    self._stop()
                raise
            self._stop()
        finally:
            self.report.seconds = clock.now() - began
            self.report.trips = list(self.nav.trips)
        return self.report

    # ------------------------------------------------------------------ phases
    def _phase(self, name: str, action: Callable[[], Any]) -> Any:
        clock = self.robot.clock
        began = clock.now()
        try:  # a stop that comes as the phase is said is this phase's
            self.progress(f"{name}...")
            result = action()
        except BaseException as exc:
            self.report.phases.append(Phase(name, clock.now() - began, False, _why(exc)))
            raise
        self.report.phases.append(Phase(name, clock.now() - began, True))
        return result

    def _stow(self) -> None:
        arm = self.robot.arm
        arm.move_joints(arm.config.pose(STOW_POSE))

    def _localise(self, start: Pose2D | None) -> None:
        estimate = self.nav.localize(start)
        p = estimate.pose
        self.progress(f"localised at x {p.x_m:+.2f} m, y {p.y_m:+.2f} m, "
                      f"{p.yaw_deg:+.0f} deg")

    def _go(self, name: str, point: NamedPoint) -> None:
        def go() -> None:
            spots = {p.name: (*p.work_spot_m, KEEP_OUT_M) for p in (self.pick_point,
                                                                  self.place_point)}
            others = [spot for n, spot in spots.items() if n != point.name]
            # Over the spot's keep-out to a pose behind the point, then straight in: the
            # base ends with its disc over the spot's margin (its front stops short of it).
            behind = compose(point.pose, Pose2D(-APPROACH_M, 0.0, 0.0))
            driven = 0.0
            try:
                driven += self.nav.go_to(behind, keep_out=list(spots.values())).driven_m
            except NavigationError as exc:
                self.progress(f"no way to {APPROACH_M:g} m behind {point.name} ({exc}): "
                              "going straight to it")
            trip = self.nav.go_to(point.pose, keep_out=others)
            self.nav.settle(point.pose, SETTLE_TOLERANCE_M, SETTLE_TOLERANCE_DEG, SETTLE_SCANS)
            self.progress(f"arrived at {point.name} ({driven + trip.driven_m:.2f} m)")

        self._phase(name, go)

    def _look(self) -> BlockSeen:
        surface = Surface(self.pick_point.name, self.pick_point.surface_m)
        colors = None if self.color is None else [self.color]
        seen = look_for_blocks(self.robot, surface, colors)
        if not seen:
            what = f"{self.color} block" if self.color else "block"
            raise _PhaseFailed(f"no {what} seen at {self.pick_point.name}")
        block = min(seen, key=lambda b: math.hypot(b.x_m - WORK_AHEAD_M, b.y_m))
        self.pictures.append((f"seen-{block.color}", block.image))
        return block

    def _pick(self, block: BlockSeen) -> PickResult:
        surface = Surface(self.pick_point.name, self.pick_point.surface_m)
        result = pick_block(self.robot, surface, block, retries=self.retries)
        self.report.pick_attempts = result.attempts
        if not result.ok:
            raise _PhaseFailed(f"the pick did not hold the block after {result.attempts} "
                               f"attempt(s): {result.why}")
        self.report.color = result.color
        return result

    def _place(self) -> PlaceResult:
        surface = Surface(self.place_point.name, self.place_point.surface_m)
        result = place_block(self.robot, surface, (WORK_AHEAD_M, 0.0))
        if result.where_m is not None:
            here = self.nav.pose
            spot = compose(here, Pose2D(result.where_m[0], result.where_m[1], 0.0))
            self.report.placed_at_m = (spot.x_m, spot.y_m)
        if not result.ok:
            raise _PhaseFailed(f"the block was let go at {self.place_point.name} but the look "
                               f"afterwards did not see it there: {result.why}")
        self.report.delivered = True
        self.report.why = "delivered"
        return result

    def _stop(self) -> None:
        base = self.robot.base
        if base is not None:
            base.stop()


class _PhaseFailed(NavigationError):
    """A phase of the job that could not be done (the report says which)."""


def _failed(exc: BaseException) -> bool:
    """Whether ``exc`` says the job could not be done (not a person's stop, not a bug)."""
    return isinstance(exc, BusArmError) and not isinstance(exc, HaltedError)


def _why(exc: BaseException) -> str:
    """What the report says of ``exc``: why the job could not be done, or the stop."""
    return str(exc) if _failed(exc) else why_stopped(exc)


def teach_point(robot: Robot, grid: OccupancyGrid, name: str, *, surface_m: float = 0.0,
                near: Pose2D | None = None, seed: int = 0) -> NamedPoint:
    """The named point where the base stands now (as a person teaches one: drive or carry
    the robot there, facing the blocks' spot): localised on ``grid`` (near ``near`` if
    given, else anywhere; the base does not move) and refined standing still."""
    nav = Navigator(robot, grid, seed=seed,
                    settings=NavSettings(localize_limit_s=TEACH_LIMIT_S))
    nav.localize(near, wander=False)
    for _ in range(SETTLE_SCANS):
        nav.sense()
    return NamedPoint(name, nav.pose, surface_m)


def run_transport(robot: Robot, grid: OccupancyGrid, points: NamedPoints, pick: str,
                  place: str, *, start: Pose2D | None = None, **options: Any
                  ) -> TransportReport:
    """One transport job (see ``TransportJob``)."""
    return TransportJob(robot, grid, points, pick, place, **options).run(start)
