"""The mobile jobs from the dashboard: navigation transport and line following.

``MobileJobs(robot, setup, reports)`` checks a request before its job starts (a base and
a Lidar, the camera's calibration, the points and colours named) and runs it in the
dashboard's job thread (busarm.dashboard.service) as the command line runs it
(busarm.cli.transport_cmd, line_follow_cmd); each job's report goes in a folder of
``reports``. While it runs, its hooks hand the map view (busarm.dashboard.map_view) the
map, the path driven, the plan, the base's pose and the latest Lidar returns, about once
a second.

Transport needs a map and named points: the files the dashboard was given (``--points``,
``--map``); or, on a twin in an arena, none: the first transport explores the arena to
map it and sets the job up from the arena as a person would (busarm.twin.arena_tasks).
The map and the points are kept for the later jobs, with where the base last was on
that map (carried on by the odometry: the next job localises near there).

Stopping: a stop or an e-stop halts the bus, which latches the wheels as well as the
servos (``BoardServoBus.halt``: the servos hold, a wheel speed is refused); the hooks
also end the job at its next scan when its cancel event is set. Every job stops the
wheels on its way out.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy.typing as npt

from busarm.base.base import Base
from busarm.base.odometry import Pose2D
from busarm.dashboard.jobs import report_folder
from busarm.dashboard.map_view import MapScene, MapView, Point
from busarm.dashboard.protocol import (
    LineFollow,
    Localise,
    NamePoint,
    NavTransport,
    RequestError,
)
from busarm.errors import BusArmError, ConfigError, HaltedError, NavigationError
from busarm.fileio import write_text_atomic
from busarm.lidar.scan import LaserScan, to_points
from busarm.nav.grid import GridSpec, OccupancyGrid, cropped
from busarm.nav.mapping import compose, inverse, transform_points
from busarm.nav.points import NamedPoints
from busarm.progress import Progress
from busarm.robot import Robot
from busarm.twin.arena import Arena

if TYPE_CHECKING:
    from busarm.apps.line_follow.job import LineFollowJob, LineFollowReport
    from busarm.apps.navigation.explore import Explorer
    from busarm.apps.navigation.navigator import Navigator
    from busarm.apps.navigation.sensing import SensedScan

__all__ = [
    "ARENA_POINTS",
    "CANVAS_MARGIN_M",
    "CANVAS_RESOLUTION_M",
    "EXPLORE_LIMIT_S",
    "MobileJobs",
    "MobileSetup",
    "block_colors",
]


EXPLORE_LIMIT_S = 300.0
"""The longest a transport's exploring of the arena may take (the command line's)."""
CANVAS_MARGIN_M = 1.0
"""Line following's picture: the odometry's path with this much room around it."""
CANVAS_RESOLUTION_M = 0.02
ARENA_POINTS = ("pick", "place")
"""The points a twin's arena gives (``transport_points``)."""


@dataclass(frozen=True)
class MobileSetup:
    """What the dashboard was given for transport on a robot: the named points and the
    map (default: the one the points file names)."""

    points_file: Path | None = None
    map_file: Path | None = None

    def load(self) -> tuple[OccupancyGrid, NamedPoints] | None:
        """The map and the points (None when neither file is given); ConfigError naming
        what is missing or wrong."""
        from busarm.nav.map_files import load_map
        from busarm.nav.points import load_points

        if self.points_file is None and self.map_file is None:
            return None
        if self.points_file is None:
            raise ConfigError("--map without --points: the named points on that map are "
                              "needed (a points file; see `busarm transport --help`)")
        points = load_points(self.points_file)
        map_file = self.map_file or points.map_path
        if map_file is None:
            raise ConfigError(f"--points {self.points_file} names no map: give --map "
                              "MAP.yaml (made by `busarm map build`)")
        return load_map(map_file), points


def block_colors() -> list[str]:
    """The colours a block may have (the shipped thresholds' but the line's and table's)."""
    from busarm.perception.locate import NOT_BLOCK_COLORS
    from busarm.vision.color_thresholds import default_thresholds

    return [c for c in default_thresholds().names if c not in NOT_BLOCK_COLORS]


def _stop_if(cancel: threading.Event) -> None:
    if cancel.is_set():
        raise HaltedError("stopped from the dashboard")


def _points_seen(local: npt.ArrayLike, pose: Pose2D) -> tuple[Point, ...]:
    """Points (N x 2) of the base's frame at ``pose``, in the frame ``pose`` is in."""
    return tuple((float(x), float(y)) for x, y in transform_points(pose, local))


def _driven_m(path: Sequence[Point]) -> float:
    return sum(math.dist(a, b) for a, b in itertools.pairwise(path))


class MobileJobs:
    """Transport and line following on ``robot`` for the dashboard; ``view``: their map."""

    def __init__(self, robot: Robot, setup: MobileSetup | None = None,
                 reports: Path = Path("dashboard-reports")) -> None:
        self.robot = robot
        self.reports = reports
        self.view = MapView()
        self._grid: OccupancyGrid | None = None
        self._points: NamedPoints | None = None
        self._where: tuple[Pose2D, Pose2D] | None = None
        """(the base's pose on the map, the odometry's pose then) when a job last knew."""
        self._canvas: OccupancyGrid | None = None
        self._points_file: Path | None = None
        """Where the named points are kept (a point named on the page is saved there)."""
        self._map_file: Path | None = None
        loaded = None if setup is None else setup.load()
        if loaded is not None:
            if not self.available:
                raise ConfigError("--points and --map are for a robot with a base and a "
                                  "Lidar (--port board://..., --chassis and --lidar)")
            self._grid, self._points = loaded
            assert setup is not None
            self._points_file = setup.points_file
            self._map_file = setup.map_file or self._points.map_path

    @property
    def available(self) -> bool:
        """Whether the robot has a base and a Lidar (else no mobile job can run)."""
        return self.robot.base is not None and self.robot.lidar is not None

    @property
    def has_map(self) -> bool:
        """Whether there is a map (given, or made by a transport's exploring)."""
        return self._grid is not None

    def _arena(self) -> Arena | None:
        sim = self.robot.sim
        return None if sim is None else sim.arena

    def point_names(self) -> list[str]:
        if self._points is not None:
            return sorted(self._points.points)
        return list(ARENA_POINTS) if self._arena() is not None else []

    def describe(self) -> dict[str, Any] | None:
        """What the page's Mobile panel offers (None: no base and Lidar, no panel)."""
        if not self.available:
            return None
        return {"points": self.point_names(), "arena": self._arena() is not None,
                "colors": block_colors(), "map": self._grid is not None,
                "points_file": None if self._points_file is None else str(self._points_file)}

    def job_for(self, request: NavTransport | LineFollow | Localise
                ) -> tuple[Callable[[threading.Event, Progress], str], str]:
        """The job ``request`` asks for (checked first: RequestError) and its name; run
        it with its cancel event and progress."""
        self.check(request)
        if isinstance(request, NavTransport):
            return (lambda cancel, progress: self.transport(request, cancel, progress),
                    "transport")
        if isinstance(request, LineFollow):
            return (lambda cancel, progress: self.line_follow(request, cancel, progress),
                    "line follow")
        return lambda cancel, progress: self.localise(request, cancel, progress), "localise"

    # ------------------------------------------------------------------ checks

    def check(self, request: NavTransport | LineFollow | Localise) -> None:
        """Refuse (RequestError) a job that cannot run here, before anything moves."""
        kind = request.type
        if not self.available:
            raise RequestError(f"{kind}: this robot has no base and Lidar; open the dashboard "
                               "on one (--port board://twin?family=arena&seed=N, or "
                               "board://DEVICE with --chassis and --lidar)")
        if isinstance(request, Localise):
            if self._grid is None:
                raise RequestError(f"{kind}: no map yet: run transport (a twin in an arena "
                                   "maps itself first) or start the dashboard with --points "
                                   "and --map")
            if request.near is None and self._where is None:
                raise RequestError(f"{kind}: where the base is on the map is not known yet: "
                                   "click the map where it stands and press 'The base is "
                                   "here' (its heading too)")
            return
        colors = list(request.colors) if isinstance(request, LineFollow) else (
            [request.color] if request.color is not None else [])
        allowed = block_colors()
        bad = [c for c in colors if c not in allowed]
        if bad:
            raise RequestError(f"{kind}: {', '.join(bad)}: not a block colour; allowed: "
                               f"{', '.join(allowed)}")
        self.robot.require_camera_calibration()
        if isinstance(request, NavTransport):
            names = self.point_names()
            if not names:
                raise RequestError("transport: no named points: start the dashboard with "
                                   "--points FILE (and --map MAP.yaml), or on a twin in an "
                                   "arena")
            for key, name in (("pick", request.pick), ("place", request.place)):
                if name not in names:
                    raise RequestError(f"transport: {key} = {name!r}: no such point; "
                                       f"points: {', '.join(names)}")

    # ------------------------------------------------------------------ transport

    def transport(self, request: NavTransport, cancel: threading.Event,
                  progress: Progress) -> str:
        """The transport job (its report in a new folder of ``reports``); raises
        HaltedError when stopped, NavigationError when the block was not delivered."""
        from busarm.apps.transport.job import TransportJob
        from busarm.apps.transport.report import write_transport_report

        try:
            grid, points, start = self._map_and_points(cancel, progress)
            said = [f"{request.pick} to {request.place}"]

            def say(text: str) -> None:
                said[0] = text
                progress(text)

            job = TransportJob(self.robot, grid, points, request.pick, request.place,
                               color=request.color, progress=say,
                               on_scan=self._nav_hook(cancel, points, request, said))
            try:
                report = job.run(start)
            except HaltedError as exc:  # a stop (the job's own report says so): kept too
                path = write_transport_report(_report_folder(self.reports, "transport"),
                                              job.report, grid, points, job.pictures)
                exc.notes = [*getattr(exc, "notes", []),  # type: ignore[attr-defined]
                             f"the report so far: {path}"]
                raise
            self._remember(job.nav)
            folder = _report_folder(self.reports, "transport")
            path = write_transport_report(folder, report, grid, points, job.pictures)
        finally:
            self._stop_wheels()
        if cancel.is_set():
            stopped = HaltedError(f"stopped: {report.why}")
            stopped.notes = [f"the report so far: {path}"]  # type: ignore[attr-defined]
            raise stopped
        if not report.delivered:
            raise NavigationError(f"not delivered: {report.why}; report {path}")
        return (f"delivered the {report.color or 'block'} from {request.pick} to "
                f"{request.place} in {report.seconds:.0f} s ({report.driven_m:.1f} m driven, "
                f"{report.pick_attempts} grasp(s)); report {path}")

    def _map_and_points(self, cancel: threading.Event, progress: Progress
                        ) -> tuple[OccupancyGrid, NamedPoints, Pose2D | None]:
        """The map and points (made by exploring, on a twin in an arena, the first time)
        and where the base is on the map, when known."""
        if self._grid is not None and self._points is not None:
            return self._grid, self._points, self._start()
        from busarm.apps.navigation.explore import build_map
        from busarm.nav.map_files import save_map
        from busarm.nav.points import save_points
        from busarm.twin.arena_tasks import twin_transport_points

        sim = self.robot.sim
        assert sim is not None
        # The set-up, as a person measuring the room for the points file (in the frame
        # of the map about to be built: taken before exploring).
        points = twin_transport_points(sim.twin, self._base())
        progress("no map yet: exploring the arena to map it")
        run = build_map(self.robot, time_limit_s=EXPLORE_LIMIT_S,
                        on_scan=self._explore_hook(cancel, progress))
        folder = _report_folder(self.reports, "map")
        save_map(folder / "map.yaml", run.grid)
        save_points(folder / "points.toml", points, "map.yaml")
        progress(run.summary(folder / "map.yaml"))
        self._grid, self._points = run.grid, points
        self._points_file, self._map_file = folder / "points.toml", folder / "map.yaml"
        return run.grid, points, run.poses[-1] if run.poses else None

    def _start(self) -> Pose2D | None:
        """Where the base is on the map: where a job last knew, moved on by the odometry
        since; None when no job has known (localised from anywhere)."""
        if self._where is None:
            return None
        on_map, then = self._where
        return compose(on_map, compose(inverse(then), self._base().odometry().pose))

    def _remember(self, nav: Navigator) -> None:
        if nav.estimate is not None and nav.estimate.converged and nav.last_scan is not None:
            self._where = (nav.pose, nav.last_scan.odometry_now)

    def _explore_hook(self, cancel: threading.Event, progress: Progress
                      ) -> Callable[[Explorer], None]:
        def hook(explorer: Explorer) -> None:
            _stop_if(cancel)
            if not self.view.due():
                return
            path = tuple((p.x_m, p.y_m) for p in explorer.builder.poses)
            text = (f"exploring to map the arena: {len(path)} scans, "
                    f"{_driven_m(path):.1f} m driven")
            marks = {"frontier": explorer.goal} if explorer.goal is not None else {}
            self.view.show(MapScene(cropped(explorer.builder.grid), text, path,
                                    pose=explorer.pose, marks=marks))
            progress(text)
        return hook

    def _nav_hook(self, cancel: threading.Event, points: NamedPoints, request: NavTransport,
                  said: list[str]) -> Callable[[Navigator, SensedScan], None]:
        marks = _marks(points)

        def hook(nav: Navigator, sensed: SensedScan) -> None:
            _stop_if(cancel)
            if not self.view.due():
                return
            local, _ = nav.returns_m(sensed)
            plan = nav.latest_plan()
            path, plans = tuple(nav.path_driven()), ((tuple(plan),) if plan else ())
            self.view.show(MapScene(nav.grid, f"transport: {said[0]}", path, plans, nav.pose,
                                    _points_seen(local, nav.pose), marks))
        return hook

    # ------------------------------------------------------------------ line following

    def line_follow(self, request: LineFollow, cancel: threading.Event,
                    progress: Progress) -> str:
        """The line-following job (its report in a new folder of ``reports``)."""
        from busarm.apps.line_follow.job import LineFollowJob

        job = LineFollowJob(self.robot, laps=request.laps, speed_m_s=request.speed_m_s,
                            colors=list(request.colors), on_step=self._line_hook(cancel),
                            progress=progress)
        try:
            report = job.run()
        except BusArmError as exc:
            notes = [*getattr(exc, "notes", []),
                     f"the report so far: {self._write_line(job.report)}"]
            exc.notes = notes  # type: ignore[attr-defined]  # for the job's end message
            raise
        finally:
            self._stop_wheels()
        path = self._write_line(report)
        cleared = sum(b.ok for b in report.blocks)
        failed = sum(b.outcome == "failed" for b in report.blocks)
        return (f"followed {report.laps_done:.2f} lap(s), {report.travelled_m:.2f} m in "
                f"{report.seconds:.0f} s; {cleared} block(s) cleared"
                + (f", {failed} not" if failed else "")
                + f", {len(report.stops)} stop(s) for obstacles; report {path}")

    def _line_hook(self, cancel: threading.Event) -> Callable[[LineFollowJob], None]:
        mount = self._base().config.lidar

        def hook(job: LineFollowJob) -> None:
            _stop_if(cancel)
            if not self.view.due():
                return
            r = job.report
            path = tuple((p.x_m, p.y_m) for p in r.path)
            returns = () if job.sensed is None else _points_seen(
                to_points(job.sensed.scan, mount), job.odometry)
            marks = {f"{i + 1} {b.color}": b.found_m for i, b in enumerate(r.blocks)}
            marks |= {f"stop {i + 1}": (s.at.x_m, s.at.y_m) for i, s in enumerate(r.stops)}
            title = (f"line following (odometry frame): {r.laps_done:.2f} of {r.laps_wanted:g}"
                     f" lap(s), {r.travelled_m:.1f} m")
            self.view.show(MapScene(self._blank((*path, *marks.values())), title, path,
                                    pose=job.odometry, returns=returns, marks=marks,
                                    frame="odometry"))
        return hook

    def _blank(self, points: Sequence[Point]) -> OccupancyGrid:
        """An empty map (all unknown) around ``points``, whole metres wide: the same one
        while the points stay inside it."""
        xs = [x for x, _ in points] or [0.0]
        ys = [y for _, y in points] or [0.0]
        spec = GridSpec.covering(math.floor(min(xs) - CANVAS_MARGIN_M),
                                 math.ceil(max(xs) + CANVAS_MARGIN_M),
                                 math.floor(min(ys) - CANVAS_MARGIN_M),
                                 math.ceil(max(ys) + CANVAS_MARGIN_M), CANVAS_RESOLUTION_M)
        if self._canvas is None or self._canvas.spec != spec:
            self._canvas = OccupancyGrid(spec)
        return self._canvas

    def _write_line(self, report: LineFollowReport) -> Path:
        folder = _report_folder(self.reports, "line-follow")
        path = folder / "report.json"
        write_text_atomic(path, json.dumps(report.to_dict(), indent=2) + "\n", "report")
        return path

    # ------------------------------------------------------------------ localising

    def localise(self, request: Localise, cancel: threading.Event, progress: Progress) -> str:
        """Find where the base stands on the map (the base does not move): near the
        request's guess, else where the odometry has carried it since a job last knew."""
        from busarm.apps.navigation.navigator import Navigator, NavSettings
        from busarm.apps.transport.job import TEACH_LIMIT_S

        grid, points = self._grid, self._points
        if grid is None:
            raise RequestError("localise: no map yet")
        marks = _marks(points) if points is not None else {}

        def hook(nav: Navigator, sensed: SensedScan) -> None:
            _stop_if(cancel)
            if self.view.due() and nav.estimate is not None:
                local, _ = nav.returns_m(sensed)
                self.view.show(MapScene(grid, "localising: where is the base on the map?",
                                        pose=nav.pose, returns=_points_seen(local, nav.pose),
                                        marks=marks))

        near = self._start() if request.near is None else Pose2D(
            request.near[0], request.near[1], math.radians(request.near[2]))
        assert near is not None  # checked (check)
        progress(f"finding the base on the map near x {near.x_m:+.2f} m, y {near.y_m:+.2f} m")
        nav = Navigator(self.robot, grid, settings=NavSettings(localize_limit_s=TEACH_LIMIT_S),
                        on_scan=hook)
        try:
            nav.localize(near, wander=False)
        finally:
            self._stop_wheels()
        self._remember(nav)
        p = nav.pose
        return f"the base is at x {p.x_m:+.2f} m, y {p.y_m:+.2f} m, {p.yaw_deg:+.0f} deg on the map"

    # ------------------------------------------------------------------ between jobs

    def show_idle(self, scan: LaserScan) -> None:
        """Between jobs (about once a second): the map, when there is one, with the named
        points, the base where the odometry has carried it since a job last knew where it
        was, and ``scan``'s returns around it."""
        if self._grid is None or not self.view.due():
            return
        pose = self._start()
        if pose is None:
            title = "map: where the base is on it is not known yet (a job localises it)"
            returns: tuple[Point, ...] = ()
        else:
            title = "map: the base now (odometry since the last job), the Lidar's returns"
            returns = _points_seen(to_points(scan, self._base().config.lidar), pose)
        marks = _marks(self._points) if self._points is not None else {}
        self.view.show(MapScene(self._grid, title, pose=pose, returns=returns, marks=marks))

    def name_point(self, request: NamePoint) -> Path:
        """Keep a named point on the map (for transport) in the points file, atomically;
        the file it is in. RequestError when there is no map to name it on."""
        if self._grid is None or self._points_file is None:
            raise RequestError("name_point: no map yet: run transport (a twin in an arena "
                               "maps itself first) or start the dashboard with --points and "
                               "--map")
        from busarm.nav.points import NamedPoint, check_point_name, map_reference, save_points

        name = check_point_name(request.name)
        _check_free(self._grid, request)
        known = self._points or NamedPoints(self._points_file.stem)
        point = NamedPoint(name, Pose2D(request.x_m, request.y_m,
                                        math.radians(request.yaw_deg)))
        points = NamedPoints(known.name, {**known.points, name: point}, self._map_file,
                             str(self._points_file))
        save_points(self._points_file, points, None if self._map_file is None else
                    map_reference(self._map_file, self._points_file))
        self._points = points
        return self._points_file

    # ------------------------------------------------------------------ the base

    def _base(self) -> Base:
        assert self.robot.base is not None
        return self.robot.base

    def _stop_wheels(self) -> None:
        """The wheels stopped (allowed while halted); a link that fails is said by the job."""
        with contextlib.suppress(BusArmError):
            self._base().stop()


def _check_free(grid: OccupancyGrid, request: NamePoint) -> None:
    """RequestError unless the point is on the map, on floor the map knows is free (the
    map file's own threshold): where the base can stand."""
    from busarm.nav.map_files import FREE_THRESH, OCCUPIED_THRESH

    spec = grid.spec
    rows, cols = spec.cells([(request.x_m, request.y_m)])
    x_max = spec.origin_x_m + spec.width * spec.resolution_m
    y_max = spec.origin_y_m + spec.height * spec.resolution_m
    where = f"name_point: {request.name} at x {request.x_m:g} m, y {request.y_m:g} m"
    if not spec.inside(rows, cols)[0]:
        raise RequestError(f"{where} is off the map; allowed: x {spec.origin_x_m:.2f}.."
                           f"{x_max:.2f} m, y {spec.origin_y_m:.2f}..{y_max:.2f} m")
    p = float(grid.probability[rows[0], cols[0]])
    if p >= FREE_THRESH:
        said = "occupied" if p >= OCCUPIED_THRESH else "not known to be free"
        raise RequestError(f"{where} is {said} on the map: a point is where the base "
                           "stands, on free floor")


def _marks(points: NamedPoints) -> dict[str, Point]:
    return {name: (p.pose.x_m, p.pose.y_m) for name, p in points.points.items()}


def _report_folder(reports: Path, kind: str) -> Path:
    """A new folder for a ``kind`` job's report in ``reports``, made."""
    folder = report_folder(reports, kind)
    try:
        folder.mkdir(parents=True)
    except OSError as exc:
        raise ConfigError(f"cannot make the report folder {folder}: {exc.strerror}") from exc
    return folder
