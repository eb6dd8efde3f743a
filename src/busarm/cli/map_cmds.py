"""``map show``: a saved map (ROS map_server's YAML + PGM) described, and drawn."""

from __future__ import annotations

from pathlib import Path

import click

from busarm.cli.common import Settings, pass_settings


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


COMMANDS = [map_group]
