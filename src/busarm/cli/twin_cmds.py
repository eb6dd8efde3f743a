"""``twin serve | snapshot | scene``: the digital twin from the command line.

MuJoCo is imported when a command runs, so the rest of the CLI never depends on it.
"""

from __future__ import annotations

import sys
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.cli.common import (
    Settings,
    announced,
    arena_from_spec,
    make_scene,
    parse_float_list,
    pass_settings,
    scene_options,
)
from busarm.errors import ConfigError
from busarm.twin.scene import MAX_BLOCKS

if TYPE_CHECKING:
    from busarm.arm.config import ArmConfig
    from busarm.twin.arena import Arena
    from busarm.twin.scene import Scene
    from busarm.twin.twin import Twin
    from busarm.vision.camera import UInt8Image

__all__ = [
    "COMMANDS",
    "scene",
    "serve",
    "snapshot",
    "twin",
]


@click.group()
def twin() -> None:
    """The digital twin: a physically simulated arm, table, blocks and camera (MuJoCo).

    Programs drive it through the same servo bytes as a real arm: `--port twin` in this
    process, or `busarm twin serve` on a pseudo-terminal for any program.
    """


@twin.command()
@scene_options
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm config name or TOML file.")
@click.option("--echo", is_flag=True, help="Echo every byte the host sends (one-wire adapter).")
@click.option("--camera-port", type=click.IntRange(0, 65535), default=0, show_default=True,
              help="TCP port on 127.0.0.1 for the camera (0: any free port).")
@click.option("--board", is_flag=True,
              help="Behind a simulated controller board: the board's frames at 1,000,000 "
                   "baud on the pty (port board:///dev/pts/N), IMU and battery reports, four "
                   "wheel motors.")
@click.option("--arena", "arena_spec", default=None, metavar="SEED|FILE",
              help="The mobile robot in an arena instead of the arm on a table: a seed (a "
                   "seeded arena) or an arena TOML file. Its base runs on the board's "
                   "wheels (implies --board); its Lidar is on a second pseudo-terminal.")
@pass_settings
def serve(settings: Settings, scene_file: Path | None, seed: int | None, blocks: int | None,
          colors: str | None, config: str, echo: bool, camera_port: int, board: bool,
          arena_spec: str | None) -> None:
    """Serve the twin's servos on a pseudo-terminal and its camera on 127.0.0.1.

    The first line of stdout is the port to give --port (the device path, or with --board
    board:///dev/pts/N: the twin behind a simulated controller board), the
    second the camera source for `--camera` (twin://127.0.0.1:PORT), with --arena a third:
    the Lidar's device path for `--lidar`. Runs until SIGINT (Ctrl+C) or SIGTERM, its way
    to stop: exit code 0.
    """
    from busarm.arm.config import load_arm_config
    from busarm.cli.common import serve_until_stopped
    from busarm.sim.board import SimBoard
    from busarm.sim.bus import WireTiming
    from busarm.sim.pty import PtyServer
    from busarm.twin.camera import CameraServer
    from busarm.twin.lidar import lidar_for_twin
    from busarm.twin.twin import Twin

    if arena_spec is not None and (scene_file or seed is not None or blocks is not None
                                   or colors is not None):
        raise ConfigError("--arena is the whole world: give it or --scene/--seed/--blocks/"
                          "--colors, not both")
    arena = arena_from_spec(arena_spec) if arena_spec is not None else None
    board = board or arena is not None
    if board and echo:
        raise ConfigError("--echo: a controller board's link does not echo (give one of "
                          "--board/--arena and --echo)")
    scene = None if arena is not None else make_scene(scene_file, seed, blocks, colors)
    with Twin(load_arm_config(config), scene, timing=WireTiming(settings.baudrate),
              echo=echo, arena=arena) as tw:
        camera = CameraServer(tw, camera_port)
        sim_board = SimBoard(tw.bus) if board else None
        if sim_board is not None and tw.mobile is not None:
            tw.mobile.attach(sim_board)
        server = PtyServer(sim_board or tw.bus)
        path = server.open()
        path = f"board://{path}" if board else path
        lidar = PtyServer(lidar_for_twin(tw)) if arena is not None else None
        lidar_path = lidar.start() if lidar is not None else None
        url = camera.start()
        try:
            # Found by commands without --port while it runs; written before the path is
            # shown, so that no client waits for it.
            with announced("twin", path, url, lidar_path):
                for line in (path, url, lidar_path):
                    if line is not None:
                        click.echo(line)
                sys.stdout.flush()
                _say_serving(tw, path, url, lidar_path)
                serve_until_stopped(server)
        finally:
            camera.stop()
            if lidar is not None:
                lidar.stop()
    click.echo("twin stopped", err=True)


def _say_serving(tw: Twin, path: str, url: str, lidar_path: str | None) -> None:
    if tw.arena is not None:
        a = tw.arena
        click.echo(f"twin: the mobile robot in {a.name} ({a.source}: {len(a.tables)} tables, "
                   f"{len(a.boxes)} boxes, {len(a.blocks)} blocks), board on {path}, camera "
                   f"on {url}, Lidar on {lidar_path}; Ctrl+C or SIGTERM to stop; commands "
                   "without --port (and lidar without --lidar) use it", err=True)
        return
    scene = tw.scene
    click.echo(f"twin: {len(scene.blocks)} blocks ({scene.source}), servos on "
               f"{path}, camera on {url}; Ctrl+C or SIGTERM to stop; commands "
               "without --port use it", err=True)
    if scene.bins:  # what pick-sort on it needs (--bins): it cannot ask
        bins = ";".join(f"{b.color}={b.x_mm:g},{b.y_mm:g}" for b in scene.bins)
        click.echo(f"bins: {bins} (busarm --port {path} pick-sort --camera "
                   f"{url} --bins '{bins}')", err=True)


@twin.command()
@scene_options
@click.option("--png", "png", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Where to write the picture (arm camera left, overview right).")
@click.option("--pose", default="look", show_default=True, metavar="NAME",
              help="Named pose of the arm config to render the arm in.")
@click.option("--joints", "joints", default=None,
              help="Joint angles in deg, e.g. 0,-60,0,-90,0 (instead of --pose).")
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm config name or TOML file.")
@click.option("--lens", type=click.Choice(["wide", "vendor", "none"]), default="wide",
              show_default=True, help="The arm camera's lens distortion.")
@click.option("--view", type=click.Choice(["both", "arm", "overview"]), default="both",
              show_default=True,
              help="Both cameras side by side, or one (arm: a raw camera frame for vision).")
@click.option("--arena", "arena_spec", default=None, metavar="SEED|FILE",
              help="Render the mobile robot's arena from above instead (a seed or an arena "
                   "file): the robot, one Lidar scan's returns and its path.")
@click.pass_context
def snapshot(ctx: click.Context, scene_file: Path | None, seed: int | None, blocks: int | None,
             colors: str | None, png: Path, pose: str, joints: str | None, config: str,
             lens: str, view: str, arena_spec: str | None) -> None:
    """Render the scene from the arm camera and from an overview camera, without a viewer.

    The overview shows the base frame's origin and x/y axes (ticks every 50 mm) and each
    bin in its colour; a caption under the picture says what it is (scene, seed, arm,
    when). --view arm writes the camera frame alone, unmarked, as vision gets it.
    --arena draws the mobile robot's arena from straight above instead.
    """
    if arena_spec is not None:
        _refuse_with_arena(ctx, {"--scene": scene_file, "--seed": seed, "--blocks": blocks,
                                 "--colors": colors, "--joints": joints})
        _arena_snapshot(arena_from_spec(arena_spec), png, config)
        return

    from busarm.arm.config import load_arm_config
    from busarm.twin.lens import lens_by_name
    from busarm.twin.snapshot import marked_overview
    from busarm.twin.twin import Twin
    from busarm.vision.annotate import save_image

    cfg = load_arm_config(config)
    if joints is not None and ctx.get_parameter_source("pose") is not \
            click.core.ParameterSource.DEFAULT:
        raise ConfigError("give either --pose or --joints, not both")
    start = _start_joints(cfg, pose, joints)
    scene = make_scene(scene_file, seed, blocks, colors)
    _check_picture_file(png)  # before rendering anything
    with Twin(cfg, scene, lens=lens_by_name(lens), start_joints_deg=start,
              realtime=False) as tw:
        arm_view = tw.render_camera()
        overview = marked_overview(tw) if view != "arm" else None
    if overview is None:  # a raw frame, for vision: no marks, no caption
        picture, caption = arm_view, "arm camera frame, unmarked"
    else:
        at = f"joints {joints}" if joints is not None else f"pose {pose}"
        picture, caption = _captioned(arm_view, overview, f"arm camera ({lens} lens), {at}",
                                      scene, cfg.name, view)
    save_image(png, picture)
    click.echo(f"wrote {png}: {'arm camera and overview' if view == 'both' else view} "
               f"({picture.shape[1]}x{picture.shape[0]}): {caption}")


def _refuse_with_arena(ctx: click.Context, options: dict[str, object]) -> None:
    """--arena draws the arena from above: the scene and arm ``options`` (by name), and
    --pose/--lens/--view, do not apply to it."""
    given = [name for name, value in options.items() if value is not None]
    given += [f"--{name}" for name in ("pose", "lens", "view") if ctx.get_parameter_source(
        name) is not click.core.ParameterSource.DEFAULT]
    if given:
        raise ConfigError(f"--arena draws the arena from above: {', '.join(given)} "
                          f"{'does' if len(given) == 1 else 'do'} not apply to it")


def _start_joints(cfg: ArmConfig, pose: str, joints: str | None) -> tuple[float, ...]:
    """The joints to render the arm in (--joints, else the pose named --pose), refused if
    they put the tool into the table."""
    from busarm.arm.kinematics import ArmKinematics

    start = cfg.check_joints(
        parse_float_list(joints, "joint angle") if joints is not None else cfg.pose(pose))
    tool_z = ArmKinematics.from_config(cfg, check_table=False).fk(start).z_mm
    if tool_z < cfg.table_z_mm:
        raise ConfigError(f"those joints put the tool {cfg.table_z_mm - tool_z:.0f} mm into the "
                          "table; the arm cannot stand there")
    return start


def _captioned(arm_view: UInt8Image, overview: UInt8Image, title: str, scene: Scene,
               arm_name: str, view: str) -> tuple[UInt8Image, str]:
    """The overview (with the titled arm camera's picture on its left for ``view`` both)
    over a caption saying what it is; the picture and the caption."""
    import cv2
    import numpy as np

    from busarm.twin.snapshot import titled, with_caption

    arm_view = titled(arm_view, title)
    h = arm_view.shape[0]
    scaled = np.asarray(cv2.resize(overview, (round(overview.shape[1] * h /
                                                    overview.shape[0]), h)), dtype=np.uint8)
    seed_text = f", seed {scene.seed}" if scene.seed is not None and \
        f"seed {scene.seed}" not in scene.source else ""
    caption = (f"busarm twin snapshot: scene {scene.source}{seed_text} "
               f"({len(scene.blocks)} blocks, {len(scene.bins)} bins), {arm_name}; "
               f"{datetime.now().astimezone():%Y-%m-%d %H:%M:%S %Z}")
    picture = with_caption(overview if view == "overview" else
                           np.hstack([arm_view, scaled]), [caption])
    return picture, caption


def _check_picture_file(png: Path) -> None:
    """--png must name a picture file we write (checked before rendering anything)."""
    from busarm.vision.annotate import IMAGE_EXTENSIONS

    if png.suffix.lower() not in IMAGE_EXTENSIONS:
        raise ConfigError(f"--png {png}: extension {png.suffix or '(none)'!r} is not one of "
                          f"{', '.join(IMAGE_EXTENSIONS)}")


def _arena_snapshot(arena: Arena, png: Path, config: str) -> None:
    from busarm.arm.config import load_arm_config
    from busarm.robot.lidar_port import twin_lidar
    from busarm.twin.arena_picture import arena_picture
    from busarm.twin.snapshot import with_caption
    from busarm.twin.twin import Twin
    from busarm.vision.annotate import save_image

    _check_picture_file(png)  # before rendering anything
    with Twin(load_arm_config(config), arena=arena, realtime=False) as tw:
        with twin_lidar(tw) as device:
            one = device.read_scan(2.0)
        picture = arena_picture(tw, scan=one, title=f"{arena.name}, seen from above")
    caption = (f"busarm twin snapshot --arena: {arena.source} ({len(arena.tables)} tables, "
               f"{len(arena.boxes)} boxes, {len(arena.blocks)} blocks, "
               f"{len(arena.lines)} taped line{'' if len(arena.lines) == 1 else 's'}), room "
               f"{arena.room.size_m[0]:g} x {arena.room.size_m[1]:g} m; "
               f"{datetime.now().astimezone():%Y-%m-%d %H:%M:%S %Z}")
    picture = with_caption(picture, [caption])
    save_image(png, picture)
    click.echo(f"wrote {png}: the arena from above ({picture.shape[1]}x{picture.shape[0]}): "
               f"{caption}")


@twin.command()
@click.option("--seed", type=click.IntRange(0, 2**32 - 1), default=0, show_default=True,
              help="Seed of the random scene.")
@click.option("--blocks", type=click.IntRange(0, MAX_BLOCKS), default=5, show_default=True,
              help="How many blocks.")
@click.option("--colors", default="red,green,blue", show_default=True,
              help="Block colours, comma separated.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The scene file to write: NAME.toml or NAME.json.")
def scene(seed: int, blocks: int, colors: str, output: Path) -> None:
    """Write a seeded random scene to a file (TOML or JSON by its extension), to edit and
    use with --scene."""
    from busarm.twin.scene import SCENE_WRITERS, save_scene

    if output.suffix.lower() not in SCENE_WRITERS:  # before drawing the scene
        raise ConfigError(f"-o {output}: a scene file is named .toml or .json, not "
                          f"{output.suffix or '(no extension)'}")
    s = make_scene(None, seed, blocks, colors)
    save_scene(output, s)
    click.echo(f"wrote {output}: {len(s.blocks)} block(s), {len(s.bins)} bin(s)")


COMMANDS = [twin]
