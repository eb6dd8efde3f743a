"""Navigation transport: fetch a block from one named point and deliver it to another.

``run_transport(robot, grid, points, "shelf", "bin")``: localise on the saved map (near a
given start, or anywhere), drive to the pick point (busarm.apps.navigation.navigator), stand there
exactly (the filter's estimate refined standing still, the last centimetres closed by
``move_by``), look for the block with the wrist camera and locate it in millimetres,
line the base up and pick it with the grasp verified (busarm.apps.transport.mobile_pick, with
retries), drive to the place point, put it down and look that it is there. The gripper
holds the block lightly and its heat is watched on the way (busarm.apps.transport.carry:
a rest first if it is too hot to finish the carry, an easier hold or a stop to cool
before its limit; the report keeps its peak and the margin to the limit). Every phase
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
from busarm.apps.transport.carry import BlockLost, CarryGuard, CarryTooHot
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
from busarm.nav.mapping import compose, inverse
from busarm.nav.points import WORK_AHEAD_M, NamedPoint, NamedPoints
from busarm.progress import Progress, quiet
from busarm.robot import Robot

__all__ = [
    "APPROACH_M",
    "KEEP_OUT_M",
    "MAX_RESTS",
    "PLACED_WITHIN_M",
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
PLACED_WITHIN_M = 0.03
"""A block seen this close to the place point's spot after it is let go is delivered."""
STOW_POSE = "home"
"""The arm's pose while the base drives (folded over the base)."""
MAX_RESTS = 3
"""A carry stops at most this many times for the gripper to cool (busarm.apps.transport.carry)."""
TEACH_LIMIT_S = 5.0
"""Teaching a point where the base stands: the longest it looks for itself on the map."""


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
    gripper_peak_c: float | None = None
    """The gripper's hottest reading from the pick to the place (None: no carry)."""
    gripper_limit_c: float | None = None
    joint_peak_c: float | None = None
    """The hottest arm joint's hottest reading over the same time."""
    rested_s: float = 0.0
    """Time spent letting the gripper cool (before or during the carry)."""

    @property
    def gripper_margin_c(self) -> float | None:
        """The gripper's temperature limit less its peak (None: no carry)."""
        if self.gripper_peak_c is None or self.gripper_limit_c is None:
            return None
        return self.gripper_limit_c - self.gripper_peak_c

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
            "gripper_peak_c": self.gripper_peak_c,
            "gripper_margin_c": self.gripper_margin_c,
            "joint_peak_c": self.joint_peak_c, "rested_s": round(self.rested_s, 1),
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
        self.guard = CarryGuard(robot, progress)

        def scanned(nav: Navigator, sensed: Any) -> None:
            if on_scan is not None:
                on_scan(nav, sensed)
            self.guard.on_scan(nav, sensed)

        self.nav = Navigator(robot, grid, settings=settings, seed=seed, on_scan=scanned)
        self.report = TransportReport(pick, place)
        self._cleared: set[str] = set()
        self._alike: list[Pose2D] = []
        """Places alike the base may be at, the one taken first (``_localise``)."""
        """Points whose spot the pick leaves bare (the one block seen there taken)."""
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
            while True:
                self._go("drive to " + self.pick_point.name, self.pick_point)
                block = self._phase("look for the block", self._look)
                if block is not None:
                    break
                self._phase("take the place alike", self._next_alike)
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
            g = self.guard
            self.report.gripper_peak_c, self.report.gripper_limit_c = g.gripper_peak_c, g.limit_c
            self.report.joint_peak_c, self.report.rested_s = g.joint_peak_c, g.rested_s
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
        estimate = self.nav.localize(start, alike_ok=True)
        if estimate.rivals:
            # A room that looks the same from several places: the likeliest is taken;
            # no block at the pick point from there, the next (the camera tells them
            # apart where the Lidar cannot).
            self._alike = list(estimate.alike)
            self.progress(f"the room looks the same from {len(self._alike)} places on the "
                          "map: going from the likeliest; the block at the pick point will "
                          "tell")
            self.nav.guess = True
            estimate = self.nav.localize(self._alike[0], wander=False)
        p = estimate.pose
        self.progress(f"localised at x {p.x_m:+.2f} m, y {p.y_m:+.2f} m, "
                      f"{p.yaw_deg:+.0f} deg")

    def _go(self, name: str, point: NamedPoint) -> None:
        def go() -> None:
            spots = {p.name: (*p.work_spot_m, KEEP_OUT_M) for p in (self.pick_point,
                                                                  self.place_point)
                     if p.name not in self._cleared}
            others = [spot for n, spot in spots.items() if n != point.name]
            for _ in range(MAX_RESTS):
                try:
                    return drive(spots, others)
                except CarryTooHot as exc:  # the base stopped: let the gripper cool
                    self.progress(str(exc))
                    self.guard.rest()
            drive(spots, others)

        def drive(spots: dict[str, tuple[float, float, float]],
                  others: list[tuple[float, float, float]]) -> None:
            # Over the spot's keep-out to a pose behind the point, then straight in on
            # one trip (no stop between): the base ends with its disc over the spot's
            # margin (its front stops short of it).
            driven, before = 0.0, len(self.nav.trips)
            try:
                trip = self.nav.go_to(point.pose, keep_out=list(spots.values()),
                                      approach_m=APPROACH_M, approach_keep_out=others)
            except (CarryTooHot, BlockLost):
                raise  # the carry's watch stopped the trip (not a way that failed)
            except NavigationError as exc:
                failed = self.nav.trips[before:]
                if failed and failed[0].on_approach:
                    raise  # it failed on the way straight in: as a trip to the point
                driven = sum(t.driven_m for t in failed)
                self.progress(f"no way to {APPROACH_M:g} m behind {point.name} ({exc}): "
                              "going straight to it")
                trip = self.nav.go_to(point.pose, keep_out=others)
            self.nav.settle(point.pose, SETTLE_TOLERANCE_M, SETTLE_TOLERANCE_DEG, SETTLE_SCANS)
            self.progress(f"arrived at {point.name} ({driven + trip.driven_m:.2f} m)")

        self._phase(name, go)

    def _look(self) -> BlockSeen | None:
        surface = Surface(self.pick_point.name, self.pick_point.surface_m)
        every = look_for_blocks(self.robot, surface, None)
        seen = [b for b in every if self.color in (None, b.color)]
        if len(every) == 1:  # once it is taken, the base may drive over the spot
            self._cleared.add(self.pick_point.name)
        if not seen and len(self._alike) > 1:
            return None  # (then it stands at the place alike: _next_alike)
        if not seen:
            what = f"{self.color} block" if self.color else "block"
            raise _PhaseFailed(f"no {what} seen at {self.pick_point.name}")
        self.nav.guess = False  # the block where the map says: this place it is
        block = min(seen, key=lambda b: math.hypot(b.x_m - WORK_AHEAD_M, b.y_m))
        self.pictures.append((f"seen-{block.color}", block.image))
        return block

    def _next_alike(self) -> None:
        """Nothing at the pick point: the base stands where the next place alike says
        (the way driven since, from there); localised there afresh."""
        taken, other = self._alike[0], self._alike[1]
        here = compose(other, compose(inverse(taken), self.nav.pose))
        self._alike = self._alike[1:]
        self.progress(f"no block at {self.pick_point.name}: the base is at the place alike, "
                      f"x {here.x_m:+.2f} m, y {here.y_m:+.2f} m, {here.yaw_deg:+.0f} deg")
        self.nav.localize(here, wander=False)

    def _pick(self, block: BlockSeen) -> PickResult:
        surface = Surface(self.pick_point.name, self.pick_point.surface_m)
        self.guard.before_carry(self._carry_s())
        result = pick_block(self.robot, surface, block, retries=self.retries)
        self.report.pick_attempts = result.attempts
        self.guard.carrying = result.ok
        if not result.ok:
            raise _PhaseFailed(f"the pick did not hold the block after {result.attempts} "
                               f"attempt(s): {result.why}")
        self.report.color = result.color
        return result

    def _carry_s(self) -> float:
        """How long a block is held, pick to place, at most: the way there driven at
        half the cruise speed, and a minute for the pick, the approach and the place."""
        a, b = self.pick_point.pose, self.place_point.pose
        way_m = 1.5 * math.dist((a.x_m, a.y_m), (b.x_m, b.y_m))
        return way_m / (self.nav.settings.max_speed_m_s / 2) + 60.0

    def _place(self) -> PlaceResult:
        if self.guard.carrying:
            self.guard.check(arrived=True)  # (BlockLost if it fell on the way in)
        point = self.place_point
        surface = Surface(point.name, point.surface_m)
        # The spot as the map has it, from where the base stands (it settled to within
        # SETTLE_TOLERANCE_M of the point: that much off the spot, else).
        want = Pose2D(*point.work_spot_m, 0.0)
        ahead = want.relative_to(self.nav.pose)
        result = place_block(self.robot, surface, (ahead.x_m, ahead.y_m))
        off_m = math.inf
        if result.where_m is not None:
            spot = compose(self.nav.pose, Pose2D(result.where_m[0], result.where_m[1], 0.0))
            self.report.placed_at_m = (spot.x_m, spot.y_m)
            off_m = math.dist(self.report.placed_at_m, (want.x_m, want.y_m))
        if not result.ok:
            raise _PhaseFailed(f"the block was let go at {point.name} but the look "
                               f"afterwards did not see it there: {result.why}")
        if off_m > PLACED_WITHIN_M:
            raise _PhaseFailed(f"the block was put down {off_m * 100:.1f} cm from "
                               f"{point.name}'s spot (at most {PLACED_WITHIN_M * 100:g} cm "
                               "is delivered)")
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
