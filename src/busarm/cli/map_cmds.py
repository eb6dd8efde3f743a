"""``map build | show``: occupancy maps (ROS map_server's YAML + PGM): built by exploring
with the Lidar, described, and drawn."""

from __future__ import annotations

from pathlib import Path

import click

from busarm.cli.common import (
    RangeType,
    Settings,
    check_writable,
    mobile_options,
    open_mobile_robot,
    pass_settings,
)


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
@mobile_options
@pass_settings
def build(settings: Settings, out_file: Path, time_limit_s: float, png: Path | None,
          arena_spec: str, chassis: str | None, lidar_port: str | None) -> None:
    """Explore and map the place the robot stands in: the base drives itself to each
    frontier between the known free floor and the unknown until none is left, every
    scan placed where it fits the map so far. The map's origin is where the base started.
    Without --port: a twin of its own in --arena."""
    from busarm.apps.explore import build_map
    from busarm.nav.map_files import save_map

    check_writable(out_file)
    with open_mobile_robot(settings, arena_spec, chassis, lidar_port) as robot:
        settings.err.print(f"exploring with {robot!r} (at most {time_limit_s:g} s)",
                           highlight=False, markup=False)
        run = build_map(robot, time_limit_s=time_limit_s)
    save_map(out_file, run.grid)
    s = run.grid.spec
    settings.out.print(
        f"map {out_file}: {s.width} x {s.height} cells of {s.resolution_m * 100:g} cm "
        f"({s.width * s.resolution_m:.2f} x {s.height * s.resolution_m:.2f} m) from "
        f"{run.scans} scans over {run.driven_m:.1f} m in {run.seconds:.0f} s; stopped: "
        f"{run.finished}", highlight=False, markup=False)
    if png is not None:
        from busarm.nav.map_picture import map_picture
        from busarm.vision.annotate import save_image

        path = [(p.x_m, p.y_m) for p in run.poses]
        save_image(png, map_picture(run.grid, path=path))
        settings.out.print(f"drawn to {png}")


COMMANDS = [map_group]
