"""``busarm robot``: the robot file that describes the whole robot (``init``, ``show``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click

from busarm.cli.common import Settings, arm_options, pass_settings
from busarm.errors import ConfigError

__all__ = [
    "COMMANDS",
    "init",
    "robot",
    "show",
]


@click.group()
def robot() -> None:
    """The robot file: one TOML file with the whole robot (its port, arm, base, Lidar,
    camera and bins). Write it once with `robot init`; give it to any command with
    `busarm --robot FILE ...` (or $BUSARM_ROBOT)."""


@robot.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--name", default="my robot", show_default=True, help="The robot's name.")
@arm_options
@click.option("--chassis", default=None,
              help="The base's chassis config (jetauto, or a TOML file): a board:// port only.")
@click.option("--lidar", "lidar_port", default=None,
              help="The Lidar's port (/dev/ttyUSB1, or lidar://sim).")
@click.option("--camera", default=None, help="The wrist camera (/dev/video0, an index, a URL).")
@click.option("--intrinsics", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="The camera's intrinsics file (busarm camera calibrate).")
@click.option("--hand-eye", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="The camera's hand-eye file (busarm camera handeye).")
@click.option("--force", is_flag=True, help="Replace FILE if it exists.")
@pass_settings
def init(settings: Settings, file: Path, name: str, config: str,
         calibration: str | None, chassis: str | None, lidar_port: str | None,
         camera: str | None, intrinsics: Path | None, hand_eye: Path | None,
         force: bool) -> None:
    """Write FILE, a robot file for the robot on --port (and the options here), checked
    as every command will read it; `busarm --robot FILE ...` then opens that robot."""
    from busarm.cli.common import describe_robot
    from busarm.robot.robot_file import load_robot_file, save_robot_file

    if file.exists() and not force:
        raise ConfigError(f"{file} exists: give --force to replace it")
    world = settings.world(settings.port)  # as given (default: sim), not a running server
    description = describe_robot(world, settings.line(),
                                 config=None if config == "jetauto_pro" else config,
                                 arm_calibration=calibration, chassis=chassis,
                                 lidar=lidar_port, camera=camera, intrinsics=intrinsics,
                                 hand_eye=hand_eye)
    # A program opening the file keeps its camera calibration as the commands do.
    description = replace(description, camera=replace(description.camera, keep=True))
    save_robot_file(file, description, name)
    load_robot_file(file)  # what was written reads back (paths, every key)
    settings.out.print(f"wrote {file}: {description}", highlight=False, soft_wrap=True)


@robot.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path), required=False)
@pass_settings
def show(settings: Settings, file: Path | None) -> None:
    """Check a robot file (FILE, else --robot's) and say the robot it describes."""
    from busarm.robot.robot_file import load_robot_file

    file = file or settings.robot_file
    if file is None:
        raise ConfigError("give a robot file: busarm robot show FILE (or --robot FILE)")
    description, name = load_robot_file(file)
    settings.out.print(f"{name}: {description}", highlight=False, soft_wrap=True)


COMMANDS = [robot]
