"""``busarm bench transport``: navigation transport over seeded twin arenas, against the
twin's truth.

Each arena (``busarm.twin.arena_tasks.transport_arena``: tables, boxes, the taped loop and
one block on the floor) is first explored and mapped by the robot itself from where it
starts (``busarm map build``'s code). The two points are taught as a person teaches them:
the robot is put where it should stand (facing the block; facing a clear spot), told
roughly where it is, and its own estimate is saved (``teach_point``). Then a person
carries it elsewhere (the chassis is put down at a random clear pose: nothing tells the
code), and the transport job runs with an unknown start: global localisation, the drive
to the pick point, the pick, the drive to the place point, the place. Scored with the
twin's truth, which only this module reads: the block within ``DELIVERED_M`` of the spot
ahead of the place stand (on the floor, let go), a run that reports delivered when it is
not, every contact of the chassis with anything (a wall, a table, a box, a block), the
localisation error at every scan along the runs, the time to localise from the unknown
start, and the map's accuracy (its occupied cells' distance from the true surfaces).
"""

from __future__ import annotations

import functools
import math
import random
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from busarm.base.odometry import Pose2D, wrap_rad
from busarm.bench.common import (
    Progress,
    SeededBenchReport,
    Verdict,
    machine_info,
    machine_line,
    quiet,
    run_seeded_bench,
)
from busarm.nav.grid import OccupancyGrid
from busarm.nav.mapping import compose, inverse
from busarm.nav.planner import path_length_m
from busarm.nav.points import WORK_AHEAD_M, NamedPoints
from busarm.robot import Robot
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.sim.spec import BoardSettings
from busarm.twin.arena_families import transport_task
from busarm.twin.arena_tasks import (
    free_pose,
    map_in_arena,
    start_pose,
    transport_points,
    true_map_surfaces,
)
from busarm.twin.spec import TwinSpec

if TYPE_CHECKING:
    from busarm.apps.navigation.navigator import Trip

__all__ = [
    "DELIVERED_M",
    "MAP_TIME_S",
    "MAP_TIME_S_PER_M2",
    "MAX_WORKERS",
    "PUT_DOWN_S",
    "TARGET_DELIVERED",
    "TARGET_GLOBAL_S",
    "TARGET_HEADING_DEG",
    "TARGET_LOCALISATION_M",
    "TEACH_GUESS",
    "VENDOR_GRASP_S",
    "ArenaRun",
    "TransportBenchReport",
    "run_arena",
    "run_transport_bench",
]


DELIVERED_M = 0.03
TARGET_DELIVERED = 0.95
TARGET_LOCALISATION_M = 0.03
TARGET_HEADING_DEG = 2.0
TARGET_GLOBAL_S = 10.0
VENDOR_GRASP_S = 5.0
"""The vendor's fixed grasp sequence alone (field notes, section 5)."""
MAP_TIME_S = 300.0
MAP_TIME_S_PER_M2 = 10.0
"""A room's exploring is given MAP_TIME_S, or this much a square metre of floor if more."""
PUT_DOWN_S = 1.0
"""After being put down the robot stands this long before anything is asked of it."""
TEACH_GUESS = Pose2D(0.05, -0.04, math.radians(3.0))
"""How far off the rough guess is that a person gives when teaching a point."""
MAX_WORKERS = 8


@dataclass
class ArenaRun:
    seed: int
    delivered: bool = False
    reported_delivered: bool = False
    why: str = ""
    placed_error_m: float = math.nan
    mission_s: float = math.nan
    """From the unknown start to the block put down (twin seconds)."""
    localise_s: float = math.nan
    map_s: float = math.nan
    map_error_median_m: float = math.nan
    map_error_p95_m: float = math.nan
    map_turn_deg: float = math.nan
    """How far the map is turned from the room (``map_in_arena``): its own frame, in
    which the localisation errors are measured."""
    contacts: list[str] = field(default_factory=list)
    position_errors_m: list[float] = field(default_factory=list, repr=False)
    heading_errors_deg: list[float] = field(default_factory=list, repr=False)
    pick_attempts: int = 0
    wall_s: float = 0.0
    gripper_peak_c: float | None = None
    """The gripper's hottest reading while it held the block (the report's)."""
    gripper_margin_c: float | None = None
    """Its temperature limit less that peak."""
    first_plans_cpu_s: float = 0.0
    first_plans_m: float = 0.0
    """The global planner's CPU time for the first plan of each trip, and those plans'
    length (the figure set beside Nav2's planners: time per metre of a whole path)."""
    all_plans_cpu_s: float = 0.0
    all_plans_m: float = 0.0
    """The same over every plan (the re-plans on the way too)."""


def _teleport(robot: Robot, pose: Pose2D) -> None:
    """A person carries the robot to ``pose`` (arena frame) and puts it down."""
    assert robot.twin is not None
    robot.twin.put_base(pose.x_m, pose.y_m, pose.yaw_rad)
    robot.clock.sleep(PUT_DOWN_S)


def _taught(robot: Robot, grid: OccupancyGrid, stands: NamedPoints, origin: Pose2D
            ) -> NamedPoints:
    """The points as a person teaches them: the robot put at each stand (arena frame),
    told roughly where it is (TEACH_GUESS off), its own estimate saved (``teach_point``)."""
    from busarm.apps.transport.job import teach_point

    taught = {}
    to_map = inverse(origin)
    for name, stand in stands.points.items():
        _teleport(robot, stand.pose)
        guess = compose(compose(to_map, stand.pose), TEACH_GUESS)
        taught[name] = teach_point(robot, grid, name, surface_m=stand.surface_m, near=guess)
    return NamedPoints("taught", taught)


def run_arena(seed: int, intrinsics: Path, hand_eye: Path, family: str = "standard"
              ) -> ArenaRun:
    """Map, carry, transport: one seeded room of ``family`` on a twin of its own (this
    process)."""
    from busarm.apps.navigation.explore import build_map
    from busarm.apps.transport.job import TransportJob

    wall = time.monotonic()
    out = ArenaRun(seed)
    task = transport_task(family, seed)
    arena = task.arena
    origin = start_pose(arena)
    stands, index, _ = transport_points(arena, Pose2D(), seed, place_within=task.place_within,
                                        min_trip_m=task.min_trip_m)  # in the arena's frame
    want = compose(stands.get("place").pose, Pose2D(WORK_AHEAD_M, 0.0, 0.0))
    with Robot.open(RobotConfig(
            TwinSpec(arena=arena, controller=BoardSettings()),
            camera=CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye))) as robot:
        twin = robot.twin
        assert twin is not None and twin.mobile is not None
        mobile = twin.mobile
        area_m2 = arena.room.size_m[0] * arena.room.size_m[1]
        run = build_map(robot, time_limit_s=max(MAP_TIME_S, MAP_TIME_S_PER_M2 * area_m2))
        out.map_s = run.seconds
        p = run.grid.probability
        rows, cols = np.nonzero(p >= 0.65)
        errors = true_map_surfaces(arena, origin, run.grid.spec.centres(rows, cols))
        out.map_error_median_m = float(np.median(errors))
        out.map_error_p95_m = float(np.percentile(errors, 95))
        points = _taught(robot, run.grid, stands, origin)
        here = mobile.pose(twin.data)
        _teleport(robot, free_pose(arena, random.Random(seed), away_from=(here.x_m, here.y_m)))
        frame = map_in_arena(arena, run.grid, origin)
        out.map_turn_deg = math.degrees(wrap_rad(frame.yaw_rad - origin.yaw_rad))
        to_map = inverse(frame)

        def on_scan(nav: Any, sensed: Any) -> None:
            if nav.estimate is None or not nav.estimate.converged or nav.guess:
                return  # (judged where the robot claims to know where it is)
            truth = compose(to_map, mobile.pose(twin.data))
            out.position_errors_m.append(math.dist((truth.x_m, truth.y_m),
                                                   (nav.pose.x_m, nav.pose.y_m)))
            out.heading_errors_deg.append(
                abs(math.degrees(wrap_rad(truth.yaw_rad - nav.pose.yaw_rad))))

        job = TransportJob(robot, run.grid, points, "pick", "place", seed=seed,
                           on_scan=on_scan)
        report = job.run(None)
        twin.sync()
        with twin.lock:
            x, y, z = (float(v) for v in twin.data.xpos[twin.model.body(f"block{index}").id])
        on_floor = z < 0.025  # let go: a block held is lifted over the deck
        out.placed_error_m = math.dist((x, y), (want.x_m, want.y_m))
        out.delivered = on_floor and out.placed_error_m <= DELIVERED_M
        out.reported_delivered = report.delivered
        out.why = report.why
        out.mission_s = report.seconds
        out.localise_s = next((ph.seconds for ph in report.phases if ph.name == "localise"),
                              math.nan)
        out.pick_attempts = report.pick_attempts
        out.gripper_peak_c, out.gripper_margin_c = report.gripper_peak_c, report.gripper_margin_c
        out.contacts = [name for _, name in twin.mobile.contacts]
        _planning(out, report.trips)
    out.wall_s = time.monotonic() - wall
    return out


def _planning(out: ArenaRun, trips: list[Trip]) -> None:
    """The planner's CPU time and the planned length, first plans and all (``out``)."""
    for trip in trips:
        lengths = [path_length_m(plan) for plan in trip.plans]
        if lengths:
            out.first_plans_cpu_s += trip.plan_cpu_s[0]
            out.first_plans_m += lengths[0]
        out.all_plans_cpu_s += sum(trip.plan_cpu_s)
        out.all_plans_m += sum(lengths)


@dataclass
class TransportBenchReport(SeededBenchReport[ArenaRun]):
    family: str = "standard"

    @property
    def delivered_share(self) -> float:
        return sum(r.delivered for r in self.runs) / len(self.runs) if self.runs else 0.0

    @property
    def false_reports(self) -> int:
        return sum(r.reported_delivered and not r.delivered for r in self.runs)

    @property
    def collisions(self) -> int:
        return sum(len(r.contacts) for r in self.runs)

    def _all(self, name: str) -> list[float]:
        return [v for r in self.runs for v in getattr(r, name)]

    def summary(self) -> dict[str, float | None]:
        pos, head = self._all("position_errors_m"), self._all("heading_errors_deg")
        done = [r.mission_s for r in self.runs if r.reported_delivered]
        loc = [r.localise_s for r in self.runs if math.isfinite(r.localise_s)]

        def q(values: list[float], at: float) -> float | None:
            return round(float(np.percentile(values, at)), 4) if values else None

        first_m, all_m = (sum(getattr(r, f"{w}_plans_m") for r in self.runs)
                          for w in ("first", "all"))

        def ms_per_m(what: str, metres: float) -> float | None:
            cpu = sum(getattr(r, f"{what}_plans_cpu_s") for r in self.runs)
            return round(1000.0 * cpu / metres, 3) if metres > 0 else None

        return {"delivered_share": self.delivered_share, "false_reports": self.false_reports,
                "collisions": self.collisions,
                "position_error_median_m": q(pos, 50), "position_error_p95_m": q(pos, 95),
                "position_error_max_m": q(pos, 100),
                "heading_error_median_deg": q(head, 50), "heading_error_p95_deg": q(head, 95),
                "mission_median_s": q(done, 50), "mission_p95_s": q(done, 95),
                "localise_median_s": q(loc, 50),
                "localise_max_s": q(loc, 100),
                "placed_error_median_m": q([r.placed_error_m for r in self.runs
                                            if r.delivered], 50),
                "map_error_median_m": q([r.map_error_median_m for r in self.runs], 50),
                "map_error_p95_m": q([r.map_error_p95_m for r in self.runs], 50),
                "map_turn_max_deg": q([abs(r.map_turn_deg) for r in self.runs], 100),
                "gripper_peak_max_c": max((r.gripper_peak_c for r in self.runs
                                           if r.gripper_peak_c is not None), default=None),
                "plan_ms_per_m": ms_per_m("first", first_m),
                "replan_ms_per_m": ms_per_m("all", all_m)}

    def text(self, verdict: Verdict) -> str:
        s = self.summary()

        def cm(key: str) -> str:
            value = s[key]
            return "-" if value is None else f"{value * 100:.1f} cm"

        pos, head, loc = (s["position_error_median_m"], s["heading_error_median_deg"],
                          s["localise_max_s"])
        return (
            f"{len(self.runs)} seeded rooms of the {self.family} family, unknown starts\n"
            f"{machine_line(self.machine, with_os=False)}\n"
            f"delivered within {DELIVERED_M * 100:g} cm: {self.delivered_share:.0%} "
            f"{verdict(self.delivered_share >= TARGET_DELIVERED)} >= "
            f"{TARGET_DELIVERED:.0%}; reported delivered but not: {self.false_reports} "
            f"{verdict(self.false_reports == 0)}; collisions: {self.collisions} "
            f"{verdict(self.collisions == 0)}\n"
            f"localisation along the runs: position median {cm('position_error_median_m')} "
            f"{verdict(pos is not None and pos <= TARGET_LOCALISATION_M)} <= "
            f"{TARGET_LOCALISATION_M * 100:g} cm (p95 {cm('position_error_p95_m')}, max "
            f"{cm('position_error_max_m')}), heading median {head} deg "
            f"{verdict(head is not None and head <= TARGET_HEADING_DEG)} <= "
            f"{TARGET_HEADING_DEG:g} deg; from an unknown start localised in at most {loc} s "
            f"{verdict(loc is not None and loc <= TARGET_GLOBAL_S)} <= {TARGET_GLOBAL_S:g} s\n"
            f"mission (twin time, localise to put down): median {s['mission_median_s']} s "
            f"(p95 {s['mission_p95_s']} s); the vendor's grasp sequence alone is about "
            f"{VENDOR_GRASP_S:g} s\n"
            f"global planner: {s['plan_ms_per_m']} ms of CPU a metre of path (each trip's "
            f"first plan; with the re-plans on the way {s['replan_ms_per_m']} ms/m)\n"
            f"placed: median {cm('placed_error_median_m')} from the place point's spot; maps: "
            f"occupied cells {cm('map_error_median_m')} from the true surfaces (median of the "
            f"arenas' medians; p95 {cm('map_error_p95_m')}); a map turned from the room at "
            f"most {s['map_turn_max_deg']} deg (localisation is judged in the map's frame)\n"
            f"time: {self.time_text}")

    def run_dict(self, run: ArenaRun) -> dict[str, Any]:
        d = asdict(run)
        d.pop("position_errors_m")
        d.pop("heading_errors_deg")
        return d


def _arena_line(done: int, total: int, r: ArenaRun) -> str:
    state = "delivered" if r.delivered else f"NOT delivered ({r.why})"
    claim = "" if r.reported_delivered == r.delivered else " [report says otherwise]"
    touch = f", touched {', '.join(r.contacts)}" if r.contacts else ""
    return (f"arena {done}/{total} (seed {r.seed}): {state}{claim}, {r.placed_error_m * 100:.1f}"
            f" cm off, mission {r.mission_s:.0f} s (localised in {r.localise_s:.1f} s), map "
            f"{r.map_s:.0f} s{touch}; {r.wall_s:.0f} s here")


def run_transport_bench(*, arenas: int = 30, seed: int = 0, workers: int = 1,
                        family: str = "standard", progress: Progress = quiet
                        ) -> TransportBenchReport:
    """Transport over ``arenas`` seeded rooms of ``family`` (seeds ``seed``..; see
    busarm.twin.arena_families), ``workers`` processes."""
    transport_task(family, seed)  # a bad family refused before anything starts
    return run_seeded_bench(TransportBenchReport(machine_info(), workers=workers,
                                                 family=family),
                            functools.partial(run_arena, family=family),
                            _arena_line, what="arenas", count=arenas, seed=seed,
                            max_workers=MAX_WORKERS, progress=progress)
