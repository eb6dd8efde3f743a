"""``vision locate``: where the blocks are on the table, in mm in the arm's base frame.

Needs the arm (for the camera's pose: forward kinematics of the measured joints) and
both camera calibrations (``busarm camera calibrate``, ``busarm camera handeye``): the
files given, else the ones kept for the robot (busarm.robot.calibration_store).
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from busarm.cli.common import (
    ArmContext,
    RangeType,
    Settings,
    calibration_store,
    pass_settings,
)
from busarm.cli.text import number

__all__ = [
    "BLOCK",
    "locate",
]


BLOCK = RangeType("block size", 10.0, 60.0, "mm")


@click.command()
@click.option("--camera", "camera_src", default=None,
              help="Camera source (/dev/video0...)  [default: the twin's with --port twin]")
@click.option("--intrinsics", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              default=None,
              help="Camera intrinsics from `busarm camera calibrate`  [default: the ones kept "
                   "for this robot, in $XDG_CONFIG_HOME/busarm/ROBOT/ (~/.config/busarm/ROBOT/ "
                   "without it)]")
@click.option("--hand-eye", "hand_eye", type=click.Path(dir_okay=False, exists=True,
                                                         path_type=Path),
              default=None,
              help="Camera pose on the wrist from `busarm camera handeye`  [default: the one "
                   "kept for this robot]")
@click.option("--pose", default="look", show_default=True, metavar="NAME",
              help="Named pose of the arm config to look from.")
@click.option("--here", is_flag=True, help="Look from where the arm is (do not move).")
@click.option("--frames", type=click.IntRange(1, 100), default=3, show_default=True,
              help="Pictures to average.")
@click.option("--thresholds", type=click.Path(dir_okay=False), default=None,
              help="Colour thresholds (our TOML or the vendor's lab_config.yaml).")
@click.option("--colors", default=None, help="Only these colours, comma separated.")
@click.option("--block-mm", "block_mm", type=BLOCK, default=30.0, show_default=True,
              help="Side of the (cubic) blocks in mm.")
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--save", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Write the annotated picture to this folder.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object with every block.")
@pass_settings
def locate(settings: Settings, camera_src: str | None, intrinsics: Path | None,
           hand_eye: Path | None,
           pose: str, here: bool, frames: int, thresholds: str | None, colors: str | None,
           block_mm: float, config: str, save: Path | None, as_json: bool) -> None:
    """Find the blocks and print where they are on the table (mm, base frame).

    x and y are the block's centre, z its top face; "reach" says whether a grasp at the
    block reaches (top-down, tilted, or why not). Blobs that are not block-sized are
    left out, and so are the vendor's black and white (lines, the table) unless asked.
    """
    from busarm.vision.annotate import annotate, save_image
    from busarm.vision.color_thresholds import (
        default_thresholds,
        load_thresholds,
        parse_color_names,
    )

    ac = ArmContext(settings, config, None)
    table = load_thresholds(thresholds) if thresholds else default_thresholds()
    names = parse_color_names(colors) if colors else None
    store = calibration_store(settings) if intrinsics is None and hand_eye is None else None
    with settings.open_robot(camera=camera_src, config=ac.config, intrinsics=intrinsics,
                             hand_eye=hand_eye, calibrate=False, calibration_store=store,
                             needs=("camera", "camera_calibration"),
                             progress=lambda text: settings.err.print(
                                 text, highlight=False, soft_wrap=True)) as robot:
        locator = robot.locator(names, table, block_mm)
        if not here:
            robot.arm.move_joints(ac.config.pose(pose))
            robot.clock.sleep(0.3)  # let the arm settle and the camera deliver a new frame
        pictures = []
        for _ in range(frames):
            image = robot.camera.read().image
            pictures.append((image, robot.arm.read_joints_deg()))
    sightings = locator.locate_averaged(pictures)
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        lines = [f"{s.color} ({number(s.location.x_mm)}, {number(s.location.y_mm)}) mm"
                 + ("" if s.reachable else " out of reach") for s in sightings]
        dets = [s.detection for s in sightings if s.detection is not None]
        save_image(save / "locate.png", annotate(pictures[-1][0], dets, text_lines=lines))
    if as_json:
        click.echo(json.dumps({"frames": frames, "blocks": [s.to_dict() for s in sightings]}))
        return
    if not sightings:
        click.echo("no blocks found")
        return
    for s in sightings:
        loc = s.location
        reach = ("top-down" if s.top_down else "tilted") if s.reachable else \
            f"out of reach ({s.reason})"
        click.echo(
            f"{s.color:7s} x {number(loc.x_mm):>7}  y {number(loc.y_mm):>7}  z "
            f"{number(loc.z_mm):>5} mm  yaw {number(loc.yaw_deg):>6} deg  frames {loc.frames} "
            f"(spread {number(loc.spread_max_mm)} mm)  reach: {reach}")
