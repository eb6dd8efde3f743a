"""``transport``: fetch a block from one named point of a map and deliver it to another.

On hardware it needs the map (``busarm map build`` made it) and the named points (a TOML
file; see busarm.nav.points). Without ``--port`` it runs on a twin of its own in an arena
(``--arena SEED``): with no map it explores the arena first, and with no points file it
sets the job up as a person would in that room: ``pick`` in front of the block on the
floor, ``place`` facing a clear spot (both written to the report folder, with the map).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.cli.common import (
    DEFAULT_COLORS,
    JobNotDone,
    Settings,
    check_writable,
    explore_hook,
    keeping_what_was_done,
    mobile_options,
    navigation_hook,
    open_mobile_robot,
    parse_pose,
    pass_settings,
    view_options,
    watching,
)
from busarm.errors import ConfigError, why_stopped

if TYPE_CHECKING:
    from busarm.apps.navigation.explore import Explorer
    from busarm.base.odometry import Pose2D
    from busarm.nav.grid import OccupancyGrid
    from busarm.nav.points import NamedPoints
    from busarm.robot import Robot
    from busarm.view.live import RobotView

__all__ = [
    "COMMANDS",
    "DEFAULT_REPORT",
    "ON_A_ROBOT",
    "transport",
]


DEFAULT_REPORT = "transport-report"
ON_A_ROBOT = ("on a robot, give --map MAP.yaml (made by `busarm map build`) and --points FILE "
              "(where to pick and place)")


def _setup(settings: Settings, robot: Robot, points_file: Path | None, map_file: Path | None,
           report: Path, names: tuple[str, str], view: RobotView | None = None
           ) -> tuple[OccupancyGrid, NamedPoints, Pose2D | None]:
    """The map, the points and (when known) where the base stands on the map."""
    from busarm.apps.navigation.explore import Explorer
    from busarm.nav.map_files import load_map, save_map
    from busarm.nav.points import load_points, save_points

    points = load_points(points_file) if points_file is not None else None
    map_file = map_file or (points.map_path if points is not None else None)
    if map_file is not None:
        if points is None:
            raise ConfigError("--map without --points: the named points on that map are "
                              "needed (a points file; see `busarm transport --help`)")
        return load_map(map_file), points, None
    if robot.twin is None or robot.twin.arena is None or robot.base is None:
        raise ConfigError(ON_A_ROBOT)
    from busarm.twin.arena_tasks import twin_transport_points

    # The points in the frame of the map about to be built (taken before exploring).
    named = points if points is not None else twin_transport_points(robot.twin, robot.base)
    settings.err.print("no map given: exploring the arena first", highlight=False, markup=False)
    explorer = Explorer(robot, time_limit_s=300.0, on_scan=explore_hook(view))
    with keeping_what_was_done(robot, lambda exc: _explored(
            report, explorer, named, names, why_stopped(exc))):
        run = explorer.run()
    report.mkdir(parents=True, exist_ok=True)
    save_map(report / "map.yaml", run.grid)
    if points is None:
        save_points(report / "points.toml", named, "map.yaml")
    settings.err.print(run.summary(report / "map.yaml"), highlight=False, markup=False)
    return run.grid, named, run.poses[-1]


def _explored(folder: Path, explorer: Explorer, points: NamedPoints, names: tuple[str, str],
              why: str) -> str:
    """A stop while exploring: the map so far (map.yaml) and a report saying so."""
    from busarm.apps.transport.job import TransportReport
    from busarm.apps.transport.report import write_transport_report
    from busarm.nav.map_files import save_map

    grid = explorer.so_far(why).grid
    folder.mkdir(parents=True, exist_ok=True)
    save_map(folder / "map.yaml", grid)
    report = TransportReport(*names, why=f"{why} while exploring the arena (the map so "
                                         "far: map.yaml)")
    return f"the report so far: {write_transport_report(folder, report, grid, points)}"


@click.command()
@click.option("--pick", default="pick", show_default=True, help="The point to fetch from.")
@click.option("--place", default="place", show_default=True, help="The point to deliver to.")
@click.option("--points", "points_file", type=click.Path(dir_okay=False, path_type=Path),
              help="The named points (TOML, format busarm.points); the map it names is used.")
@click.option("--map", "map_file", type=click.Path(dir_okay=False, path_type=Path),
              metavar="MAP.yaml", help="The saved map; without it, the points file's.")
@click.option("--start", "start_text", metavar="X,Y,YAW",
              help="Where the base stands on the map (m, m, deg); without it, found from "
                   "anywhere by the Lidar (global localisation).")
@click.option("--color", type=click.Choice(DEFAULT_COLORS.split(",")), default=None,
              help="Fetch a block of this colour; without it, the one nearest the point.")
@click.option("--report", "report_dir", default=DEFAULT_REPORT, show_default=True,
              type=click.Path(file_okay=False, path_type=Path),
              help="Where to write report.json and the pictures.")
@mobile_options
@view_options
@pass_settings
def transport(settings: Settings, pick: str, place: str, points_file: Path | None,
              map_file: Path | None, start_text: str | None, color: str | None,
              report_dir: Path, arena_spec: str, chassis: str | None,
              lidar_port: str | None, foxglove_port: int | None,
              mcap_file: Path | None) -> None:
    """Fetch a block from the named point --pick and deliver it to --place: localise on
    the map, drive there clear of everything, find the block with the wrist camera, line
    the base up and pick it (grasp checked), drive to --place, put it down and look that
    it is there. Without --port: a twin of its own in --arena. --foxglove and --mcap
    show the run in Foxglove live and record it (map, plan, path, scans, camera)."""
    from busarm.apps.transport.job import TransportJob
    from busarm.apps.transport.report import write_transport_report
    from busarm.twin.spec import TwinSpec

    start = parse_pose(start_text, "--start") if start_text is not None else None
    if (points_file is None and settings.port_given
            and not isinstance(settings.world(), TwinSpec)):
        raise ConfigError(ON_A_ROBOT)  # before anything is opened: only a twin has an arena
    check_writable(report_dir / "report.json" if report_dir.is_dir() else report_dir)
    with open_mobile_robot(settings, arena_spec, chassis, lidar_port, camera=True) as robot, \
            watching(settings, robot, foxglove_port, mcap_file) as view:
        grid, points, known = _setup(settings, robot, points_file, map_file, report_dir,
                                     (pick, place), view)
        points.get(pick), points.get(place)  # both named, before anything moves
        job = TransportJob(robot, grid, points, pick, place, color=color,
                           progress=lambda line: settings.err.print(
                               line, highlight=False, markup=False),
                           on_scan=navigation_hook(view, points, (pick, place)))
        with keeping_what_was_done(robot, lambda exc: "the report so far: " + str(
                write_transport_report(report_dir, job.report, grid, points, job.pictures))):
            report = job.run(start if start is not None else known)
    path = write_transport_report(report_dir, report, grid, points, job.pictures)
    settings.out.print(
        f"{'delivered' if report.delivered else 'not delivered'}: {report.color or 'block'} "
        f"from {pick} to {place} in {report.seconds:.1f} s ({report.driven_m:.1f} m driven, "
        f"{report.pick_attempts} grasp(s)); report {path}", highlight=False, markup=False)
    if not report.delivered:
        raise JobNotDone(f"the block was not delivered: {report.why}")


COMMANDS = [transport]
