"""``map build | show``: occupancy maps (ROS map_server's YAML + PGM): built by exploring
with the Lidar, described, and drawn."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.cli.common import (
    RangeType,
    Settings,
    check_writable,
    explore_hook,
    keeping_what_was_done,
    mobile_options,
    open_mobile_robot,
    parse_pose,
    pass_settings,
    view_options,
    watching,
)
from busarm.errors import why_stopped

if TYPE_CHECKING:
    from busarm.apps.navigation.explore import MapRun

__all__ = [
    "COMMANDS",
    "build",
    "map_group",
    "point",
    "show",
]


@click.group("map")
def map_group() -> None:
    """Occupancy maps in ROS map_server's format (NAME.yaml beside NAME.pgm)."""


@map_group.command()
@click.argument("map_file", metavar="MAP.yaml", type=click.Path(path_type=Path))
@click.option("--png", type=click.Path(dir_okay=False, path_type=Path),
              help="Also draw it (occupied black, free white, unknown grey; the origin's "
                   "axes, a 1 m bar) to this PNG file.")
@pass_settings
def show(settings: Settings, map_file: Path, png: Path | None) -> None:
    """Say what a map covers and how much of it is known; --png draws it."""
    from busarm.nav.map_files import grid_pixels, load_map

    grid = load_map(map_file)
    s = grid.spec
    pixels = grid_pixels(grid)
    share = {name: float((pixels == value).mean()) for name, value in
             (("occupied", 0), ("free", 254), ("unknown", 205))}
    settings.out.print(
        f"map {map_file}: {s.width} x {s.height} cells of {s.resolution_m * 100:g} cm "
        f"({s.width * s.resolution_m:.2f} x {s.height * s.resolution_m:.2f} m), lower-left "
        f"corner at x {s.origin_x_m:+.3f} m, y {s.origin_y_m:+.3f} m; occupied "
        f"{share['occupied']:.1%}, free {share['free']:.1%}, unknown {share['unknown']:.1%}")
    if png is not None:
        from busarm.nav.map_picture import map_picture
        from busarm.vision.annotate import save_image

        save_image(png, map_picture(grid))
        settings.out.print(f"drawn to {png}")


@map_group.command()
@click.option("--out", "out_file", default="map.yaml", show_default=True,
              type=click.Path(dir_okay=False, path_type=Path),
              help="Where to save the map (MAP.pgm is written beside it).")
@click.option("--time", "time_limit_s", default=300.0, show_default=True,
              type=RangeType("--time", 5.0, 3600.0, "s"),
              help="The longest it may explore (simulated seconds on the twin).")
@click.option("--png", type=click.Path(dir_okay=False, path_type=Path),
              help="Also draw the map with the path driven to this PNG file.")
@view_options
@mobile_options
@pass_settings
def build(settings: Settings, out_file: Path, time_limit_s: float, png: Path | None,
          foxglove_port: int | None, mcap_file: Path | None, arena_spec: str,
          chassis: str | None, lidar_port: str | None) -> None:
    """Explore and map the place the robot stands in: the base drives itself to each
    frontier between the known free floor and the unknown until none is left, every
    scan placed where it fits the map so far. The map's origin is where the base started.
    Without --port: a twin of its own in --arena."""
    from busarm.apps.navigation.explore import Explorer

    check_writable(out_file)
    with open_mobile_robot(settings, arena_spec, chassis, lidar_port) as robot, \
            watching(settings, robot, foxglove_port, mcap_file) as view:
        settings.err.print(f"exploring with {robot!r} (at most {time_limit_s:g} s)",
                           highlight=False, markup=False)
        explorer = Explorer(robot, time_limit_s=time_limit_s, on_scan=explore_hook(view),
                            progress=lambda line: settings.err.print(
                                line, highlight=False, markup=False))
        # A stop keeps the map explored so far (what `map show` and transport read).
        with keeping_what_was_done(robot, lambda exc: _keep(
                explorer.so_far(why_stopped(exc)), out_file, png)):
            run = explorer.run()
    _save(run, out_file, png)
    s = run.grid.spec
    settings.out.print(
        f"map {out_file}: {s.width} x {s.height} cells of {s.resolution_m * 100:g} cm "
        f"({s.width * s.resolution_m:.2f} x {s.height * s.resolution_m:.2f} m) from "
        f"{run.scans} scans over {run.driven_m:.1f} m in {run.seconds:.0f} s; stopped: "
        f"{run.finished}", highlight=False, markup=False)
    if png is not None:
        settings.out.print(f"drawn to {png}")


def _save(run: MapRun, out_file: Path, png: Path | None) -> None:
    """The map in ``out_file`` (and beside it its PGM); drawn with the path to ``png``."""
    from busarm.nav.map_files import save_map

    save_map(out_file, run.grid)
    if png is not None:
        from busarm.nav.map_picture import map_picture
        from busarm.vision.annotate import save_image

        path = [(p.x_m, p.y_m) for p in run.poses]
        save_image(png, map_picture(run.grid, path=path))


def _keep(run: MapRun, out_file: Path, png: Path | None) -> str:
    """A stopped build: the map so far saved as a finished one is, and where it is."""
    if not run.scans:
        return "no map kept (stopped before the first scan)"
    _save(run, out_file, png)
    return f"the map so far ({run.scans} scans): {out_file}"


@map_group.command("point")
@click.argument("name")
@click.option("--map", "map_file", required=True, type=click.Path(dir_okay=False, path_type=Path),
              metavar="MAP.yaml", help="The map the point is on.")
@click.option("--points", "points_file", required=True,
              type=click.Path(dir_okay=False, path_type=Path),
              help="The points file to add it to (made if missing; it names the map).")
@click.option("--near", "near_text", metavar="X,Y,YAW",
              help="Roughly where the base stands (m, m, deg); without it, found from "
                   "anywhere on the map (the base does not move either way).")
@click.option("--surface", "surface_m", default=0.0, show_default=True,
              type=RangeType("--surface", 0.0, 0.5, "m"),
              help="The height the blocks stand on there, in m (0: the floor).")
@mobile_options
@pass_settings
def point(settings: Settings, name: str, map_file: Path, points_file: Path,
          near_text: str | None, surface_m: float, arena_spec: str, chassis: str | None,
          lidar_port: str | None) -> None:
    """Save where the base stands now as the named point NAME (put the robot there, facing
    the blocks' spot, about 0.2 m ahead): localised on the map with the Lidar."""
    from busarm.apps.transport.job import teach_point
    from busarm.nav.map_files import load_map
    from busarm.nav.points import (
        NamedPoints,
        check_point_name,
        load_points,
        map_reference,
        save_points,
    )

    check_point_name(name)
    grid = load_map(map_file)
    near = parse_pose(near_text, "--near") if near_text is not None else None
    known = load_points(points_file) if points_file.exists() else NamedPoints(
        points_file.stem)
    with open_mobile_robot(settings, arena_spec, chassis, lidar_port) as robot:
        taught = teach_point(robot, grid, name, surface_m=surface_m, near=near)
    points = NamedPoints(known.name, {**known.points, name: taught}, source=str(points_file))
    save_points(points_file, points, map_reference(map_file, points_file))
    p = taught.pose
    settings.out.print(f"{name}: x {p.x_m:+.3f} m, y {p.y_m:+.3f} m, {p.yaw_deg:+.1f} deg on "
                       f"{map_file}; saved in {points_file}", highlight=False, markup=False)


COMMANDS = [map_group]
