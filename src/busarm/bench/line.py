"""``busarm bench line``: line following over seeded twin layouts, against the twin's truth.

Each layout is a seeded arena (``random_arena``: a wobbly taped loop no tighter than
0.35 m, tables and boxes off the tape) with 0-3 blocks on or beside the tape and 0-2
other obstacles: one of the arena's boxes is moved onto the tape ahead of the robot (a
person stepping in) when it has driven a while, and taken away once the robot has
stood still for it ``OBSTACLE_STAY_S``. One lap each (``busarm line-follow``'s code).
Scored with the twin's truth, which only this module reads: the chassis centre's distance
from the tape's centreline at every step (not while the base lines up with a block or
slides back onto the line, which is the job, not following), every block's distance from
the tape at the end (cleared: more than ``CLEARED_M``), every contact of the chassis, and
whether the robot stopped short of each obstacle.

Families (``family``): the tape's colour, the same seeded layouts taped in it: ``black``
(the default: the layouts as they always were), ``blue``, ``red``, ``green``, ``yellow``
and ``white`` (on a dark floor). The job is not told the colour: it measures it on the
first look, and the colour it measured is scored too. Every stop for something in the
way is checked against the truth: a stop is false when no box, table, wall or block
stood within ``STOP_REACH_M`` ahead of the chassis's centre (the Lidar's stop range and
a margin) when it began.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import random
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.bench.common import (
    Progress,
    SeededBenchReport,
    Verdict,
    machine_info,
    quiet,
    run_seeded_bench,
)
from busarm.errors import BusArmError
from busarm.robot import Robot
from busarm.robot.description import CameraSpec, RobotConfig
from busarm.sim.spec import BoardSettings
from busarm.twin.arena import Arena, Solid
from busarm.twin.arena_gen import distance_to_line_m, random_arena
from busarm.twin.footprints import Footprint
from busarm.twin.spec import TwinSpec

__all__ = [
    "CLEARED_M",
    "FAMILIES",
    "MAX_WORKERS",
    "OBSTACLE_AFTER_M",
    "OBSTACLE_AHEAD_M",
    "OBSTACLE_STAY_S",
    "STOP_REACH_M",
    "TARGET_LATERAL_MAX_M",
    "TARGET_LATERAL_MEDIAN_M",
    "LayoutRun",
    "LineBenchReport",
    "family_arena",
    "run_layout",
    "run_line_bench",
]


TARGET_LATERAL_MEDIAN_M = 0.01
TARGET_LATERAL_MAX_M = 0.03
CLEARED_M = 0.12
"""A block farther than this from the tape's centreline is off the line (the chassis's
half width is 0.13 m: a block that far out is beside the robot's path, not in it)."""
OBSTACLE_AFTER_M = (1.5, 4.5)
"""An obstacle steps in once the robot has driven this far (each its own distance)."""
OBSTACLE_AHEAD_M = 0.55
OBSTACLE_STAY_S = 3.0
MAX_WORKERS = 8
FAMILIES = ("black", "blue", "red", "green", "yellow", "white")
"""The tape's colours (``white`` on a dark floor); ``black`` is the layouts as they were."""
STOP_REACH_M = 0.65
"""A stop is true when something stood this near the chassis's centre, ahead of it (the
stop rule's reach, 0.55 m, and a margin for the Lidar's noise and the base's coasting)."""


@dataclass
class LayoutRun:
    seed: int
    blocks: int = 0
    obstacles: int = 0
    finished: bool = False
    why: str = ""
    lateral_median_m: float = math.nan
    lateral_max_m: float = math.nan
    blocks_cleared: int = 0
    obstacles_stopped_for: int = 0
    contacts: list[str] = field(default_factory=list)
    seconds: float = 0.0
    wall_s: float = 0.0
    family: str = "black"
    tape_seen: str = ""
    """The tape's colour as the job measured it on the first look."""
    stops: int = 0
    false_stops: int = 0
    """Stops with nothing truly within ``STOP_REACH_M`` ahead."""


class _Obstacles:
    """Boxes that step onto the tape ahead of the robot and away again (truth side)."""

    def __init__(self, robot: Robot, count: int, rng: random.Random) -> None:
        self.robot = robot
        twin = robot.twin
        assert twin is not None and twin.arena is not None
        self.twin = twin
        self.line = twin.arena.lines[0]
        self.pending = sorted(rng.uniform(*OBSTACLE_AFTER_M) + 3.0 * k for k in range(count))
        self.boxes = list(range(min(count, len(twin.arena.boxes))))
        self.active: tuple[int, tuple[float, float, float], float | None] | None = None
        self.stopped_for = 0
        self.driven_m = 0.0
        self._last: tuple[float, float] | None = None

    def step(self, speed_m_s: float) -> None:
        mobile = self.twin.mobile
        assert mobile is not None
        pose = mobile.pose(self.twin.data)
        if self._last is not None:
            self.driven_m += math.dist(self._last, (pose.x_m, pose.y_m))
        self._last = (pose.x_m, pose.y_m)
        now = self.robot.clock.now()
        if self.active is None and self.pending and self.boxes and \
                self.driven_m >= self.pending[0]:
            self.pending.pop(0)
            box = self.boxes.pop(0)
            home = self._box_pose(box)
            self._move_box(box, self._ahead(pose))
            self.active = (box, home, None)
        elif self.active is not None:
            box, home, still_since = self.active
            if abs(speed_m_s) < 0.005 and still_since is None:
                self.active = (box, home, now)
            elif still_since is not None and now - still_since >= OBSTACLE_STAY_S:
                self._move_box(box, home)
                self.stopped_for += 1
                self.active = None

    def _ahead(self, pose: Any) -> tuple[float, float, float]:
        """The tape's point OBSTACLE_AHEAD_M ahead of the robot along its heading."""
        pts = np.array(self.line.points_m)
        ahead = np.array([pose.x_m + OBSTACLE_AHEAD_M * math.cos(pose.yaw_rad),
                          pose.y_m + OBSTACLE_AHEAD_M * math.sin(pose.yaw_rad)])
        k = int(np.argmin(np.hypot(*(pts - ahead).T)))
        return float(pts[k, 0]), float(pts[k, 1]), 0.0

    def _box_pose(self, box: int) -> tuple[float, float, float]:
        body = self.twin.model.body(f"box{box}")
        x, y, z = (float(v) for v in self.twin.data.mocap_pos[int(body.mocapid[0])])
        return x, y, z

    def _move_box(self, box: int, xyz: tuple[float, float, float]) -> None:
        twin = self.twin
        with twin.lock:
            body = twin.model.body(f"box{box}")
            pos = twin.data.mocap_pos[int(body.mocapid[0])]
            pos[0], pos[1] = xyz[0], xyz[1]
            twin.mujoco.mj_forward(twin.model, twin.data)


def family_arena(seed: int, blocks: int, family: str = "black") -> Arena:
    """Layout ``seed``'s arena (``blocks`` on the floor) taped in ``family``'s colour."""
    if family not in FAMILIES:
        raise BusArmError(f"line family {family!r}: allowed: {', '.join(FAMILIES)}")
    arena = random_arena(seed, floor_blocks=blocks)
    if family == "black":
        return arena
    lines = tuple(dataclasses.replace(line, color=family) for line in arena.lines)
    return dataclasses.replace(arena, lines=lines,
                               floor="dark" if family == "white" else arena.floor)


class _Truth:
    """What truly stood ahead of the chassis at each step (for the stops' check)."""

    def __init__(self, robot: Robot, arena: Arena) -> None:
        twin = robot.twin
        assert twin is not None
        self.twin, self.arena, self.clock = twin, arena, robot.clock
        fixed: list[Solid] = [*arena.tables, *getattr(arena, "walls", ())]
        self.fixed = [_outline_m(s.footprint()) for s in fixed]
        r = arena.room
        edge = np.linspace(0.0, 1.0, 200)[:, None]
        corners = np.array([(r.x_min_m, r.y_min_m), (r.x_max_m, r.y_min_m),
                            (r.x_max_m, r.y_max_m), (r.x_min_m, r.y_max_m)])
        self.fixed += [a + edge * (b - a) for a, b in zip(corners, np.roll(corners, -1, 0),
                                                          strict=True)]
        self.boxes = [_outline_m(dataclasses.replace(b, x_m=0.0, y_m=0.0).footprint())
                      for b in arena.boxes]
        self.steps: list[tuple[float, bool]] = []

    def step(self) -> None:
        twin = self.twin
        assert twin.mobile is not None
        pose = twin.mobile.pose(twin.data)
        points = list(self.fixed)
        for i, outline in enumerate(self.boxes):
            body = twin.model.body(f"box{i}")
            points.append(outline + twin.data.mocap_pos[int(body.mocapid[0])][:2])
        for i in range(len(self.arena.blocks)):
            points.append(np.array([twin.data.xpos[twin.model.body(f"block{i}").id][:2]]))
        p = np.vstack(points) - [pose.x_m, pose.y_m]
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        x, y = p[:, 0] * c + p[:, 1] * s, -p[:, 0] * s + p[:, 1] * c
        ahead = bool(np.any((x > 0.0) & (np.hypot(x, y) <= STOP_REACH_M)))
        self.steps.append((self.clock.now(), ahead))

    def false_stops(self, began_s: list[float]) -> int:
        """How many of the stops begun at ``began_s`` had nothing ahead (at the last step
        before each)."""
        times = np.array([t for t, _ in self.steps])
        out = 0
        for t in began_s:
            k = int(np.searchsorted(times, t + 1e-9)) - 1
            out += k >= 0 and not self.steps[k][1]
        return out


def _outline_m(fp: Footprint) -> npt.NDArray[np.float64]:
    """Points along a footprint's outline every centimetre or so (m)."""
    corners = np.array(fp.corners()) / 1000.0
    edge = np.linspace(0.0, 1.0, 40)[:, None]
    return np.vstack([a + edge * (b - a) for a, b in zip(corners, np.roll(corners, -1, 0),
                                                         strict=True)])


def run_layout(seed: int, intrinsics: Path, hand_eye: Path, family: str = "black"
               ) -> LayoutRun:
    """One seeded layout taped in ``family``'s colour, one lap, on a twin of its own
    (this process)."""
    from busarm.apps.line_follow.job import LineFollowJob

    wall = time.monotonic()
    rng = random.Random(seed)
    out = LayoutRun(seed, blocks=rng.randint(0, 3), obstacles=rng.randint(0, 2), family=family)
    arena = family_arena(seed, out.blocks, family)
    out.obstacles = min(out.obstacles, len(arena.boxes))
    with Robot.open(RobotConfig(
            TwinSpec(arena=arena, controller=BoardSettings()),
            camera=CameraSpec(intrinsics=intrinsics, hand_eye=hand_eye))) as robot:
        twin = robot.twin
        assert twin is not None and twin.mobile is not None
        mobile, line = twin.mobile, arena.lines[0]
        offsets: list[float] = []
        obstacles = _Obstacles(robot, out.obstacles, rng)
        truth = _Truth(robot, arena)

        def on_step(job: LineFollowJob) -> None:
            pose = mobile.pose(twin.data)
            speed = math.hypot(*mobile.speed(twin.data)[:2])
            obstacles.step(speed)
            truth.step()
            if not job.rejoining:
                offsets.append(distance_to_line_m(line, pose.x_m, pose.y_m))

        job = LineFollowJob(robot, laps=1.0, on_step=on_step)
        try:
            report = job.run()
        except BusArmError as exc:
            report = job.report
            out.why = str(exc)
        out.finished = report.finished
        out.why = out.why or report.why
        out.seconds = report.seconds
        out.tape_seen = report.tape
        out.stops = len(report.stops)
        out.false_stops = truth.false_stops([s.began_s for s in report.stops])
        twin.sync()
        with twin.lock:
            ends = [(float(twin.data.xpos[twin.model.body(f"block{i}").id][0]),
                     float(twin.data.xpos[twin.model.body(f"block{i}").id][1]))
                    for i in range(len(arena.blocks)) if arena.blocks[i].on is None]
        out.blocks = len(ends)
        out.blocks_cleared = sum(distance_to_line_m(line, x, y) > CLEARED_M for x, y in ends)
        out.obstacles_stopped_for = obstacles.stopped_for
        out.contacts = [name for _, name in mobile.contacts]
        if offsets:
            out.lateral_median_m = float(np.median(offsets))
            out.lateral_max_m = float(np.max(offsets))
    out.wall_s = time.monotonic() - wall
    return out


@dataclass
class LineBenchReport(SeededBenchReport[LayoutRun]):
    family: str = "black"

    def summary(self) -> dict[str, Any]:
        medians = [r.lateral_median_m for r in self.runs if math.isfinite(r.lateral_median_m)]
        maxes = [r.lateral_max_m for r in self.runs if math.isfinite(r.lateral_max_m)]
        return {
            "layouts": len(self.runs), "finished": sum(r.finished for r in self.runs),
            "lateral_median_m": round(float(np.median(medians)), 4) if medians else None,
            "lateral_worst_median_m": round(max(medians), 4) if medians else None,
            "lateral_max_m": round(max(maxes), 4) if maxes else None,
            "blocks": sum(r.blocks for r in self.runs),
            "blocks_cleared": sum(r.blocks_cleared for r in self.runs),
            "obstacles": sum(r.obstacles for r in self.runs),
            "obstacles_stopped_for": sum(r.obstacles_stopped_for for r in self.runs),
            "collisions": sum(len(r.contacts) for r in self.runs),
            "family": self.family,
            "tape_measured_right": sum(r.tape_seen == r.family for r in self.runs),
            "stops": sum(r.stops for r in self.runs),
            "false_stops": sum(r.false_stops for r in self.runs),
            "lap_median_s": round(float(np.median([r.seconds for r in self.runs])), 1)
            if self.runs else None}

    def text(self, verdict: Verdict) -> str:
        s = self.summary()
        med, top = s["lateral_median_m"], s["lateral_max_m"]
        return (
            f"{s['layouts']} seeded layouts, {s['finished']} laps done "
            f"{verdict(s['finished'] == s['layouts'])}\n"
            f"off the tape (chassis centre): median {med * 1000:.1f} mm "
            f"{verdict(med <= TARGET_LATERAL_MEDIAN_M)} <= "
            f"{TARGET_LATERAL_MEDIAN_M * 1000:g} mm, max {top * 1000:.1f} mm "
            f"{verdict(top <= TARGET_LATERAL_MAX_M)} <= {TARGET_LATERAL_MAX_M * 1000:g} mm\n"
            f"blocks cleared off the tape: {s['blocks_cleared']}/{s['blocks']} "
            f"{verdict(s['blocks_cleared'] == s['blocks'])}; obstacles stopped for: "
            f"{s['obstacles_stopped_for']}/{s['obstacles']} "
            f"{verdict(s['obstacles_stopped_for'] == s['obstacles'])}; collisions: "
            f"{s['collisions']} {verdict(s['collisions'] == 0)}\n"
            f"{s['family']} tape, its colour measured right on the first look: "
            f"{s['tape_measured_right']}/{s['layouts']} "
            f"{verdict(s['tape_measured_right'] == s['layouts'])}; stops without something "
            f"truly in the way: {s['false_stops']} of {s['stops']} "
            f"{verdict(s['false_stops'] == 0)}\n"
            f"a lap: median {s['lap_median_s']} s of twin time; {self.time_text}")


def _layout_line(done: int, total: int, r: LayoutRun) -> str:
    touch = f", touched {', '.join(r.contacts)}" if r.contacts else ""
    state = "lap done" if r.finished else f"STOPPED ({r.why})"
    return (f"layout {done}/{total} (seed {r.seed}): {state}; off the tape median "
            f"{r.lateral_median_m * 1000:.1f} mm, max {r.lateral_max_m * 1000:.1f} mm; blocks "
            f"cleared {r.blocks_cleared}/{r.blocks}; obstacles stopped for "
            f"{r.obstacles_stopped_for}/{r.obstacles}{touch}; {r.tape_seen or 'no'} tape "
            f"seen; {r.false_stops} of {r.stops} stops false; {r.seconds:.0f} s twin, "
            f"{r.wall_s:.0f} s here")


def run_line_bench(*, layouts: int = 20, seed: int = 0, workers: int = 1,
                   family: str = "black", progress: Progress = quiet) -> LineBenchReport:
    """Line following over ``layouts`` seeded layouts (seeds ``seed``..) taped in
    ``family``'s colour (``FAMILIES``)."""
    if family not in FAMILIES:
        raise BusArmError(f"--family {family!r}: allowed: {', '.join(FAMILIES)}")
    report = LineBenchReport(machine_info(), workers=workers)
    report.family = family
    return run_seeded_bench(report, functools.partial(run_layout, family=family),
                            _layout_line, what="layouts", count=layouts, seed=seed,
                            max_workers=MAX_WORKERS, progress=progress)
