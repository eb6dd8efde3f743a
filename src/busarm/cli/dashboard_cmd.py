"""``busarm dashboard``: watch, drive and stop the robot from a web page.

The server and the page are busarm.dashboard; this opens the robot (the twin in real
time by default, so that a person watches it move as a real arm would), prints the
page's address and serves until Ctrl+C, which stops the robot, holding.
"""

from __future__ import annotations

import socket
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from busarm.cli.common import (
    Settings,
    interrupt_on_signals,
    open_live_robot,
    pass_settings,
    scene_options,
)

if TYPE_CHECKING:
    from busarm.dashboard.access import Access
    from busarm.dashboard.mobile import MobileSetup

__all__ = [
    "COMMANDS",
    "dashboard",
]


@click.command()
@scene_options
@click.option("--camera", "camera_src", default=None,
              help="The wrist camera: a device, file or stream URL  [default: the twin's; "
                   "on hardware none]")
@click.option("--bind", default="127.0.0.1", show_default=True,
              help="Address to listen on; any other than loopback needs a token.")
@click.option("--http-port", type=click.IntRange(0, 65535), default=8000, show_default=True,
              help="TCP port of the page (0: any free port).")
@click.option("--token", default=None,
              help="The token every request must carry  [default: none on loopback, "
                   "else a new one, printed]")
@click.option("--reports", "reports_dir", type=click.Path(file_okay=False, path_type=Path),
              default=Path("dashboard-reports"), show_default=True,
              help="Folder for the jobs' reports (pick-sort, transport, line-follow).")
@click.option("--fps", type=click.FloatRange(1, 30), default=20, show_default=True,
              help="Camera frames per second (frames/s) at most, per camera.")
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--chassis", default=None,
              help="With --port board://DEVICE: the mobile base's chassis config (a shipped "
                   "name, jetauto, or a TOML file)  [default: no base; a board://twin in an "
                   "arena has its own]")
@click.option("--lidar", "lidar_port", default=None,
              help="With --port board://DEVICE: the Lidar's serial port  [default: none; a "
                   "board://twin in an arena has its own]")
@click.option("--points", "points_file", default=None,
              type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="The named points for transport (TOML, busarm.points)  [default: none; "
                   "on a twin in an arena the first transport maps it and sets them]")
@click.option("--map", "map_file", default=None, metavar="MAP.yaml",
              type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="The saved map for transport  [default: the points file's]")
@pass_settings
def dashboard(settings: Settings, scene_file: Path | None, seed: int | None,
              blocks: int | None, colors: str | None, camera_src: str | None, bind: str,
              http_port: int, token: str | None, reports_dir: Path, fps: float,
              config: str, chassis: str | None, lidar_port: str | None,
              points_file: Path | None, map_file: Path | None) -> None:
    """Serve a web page that shows the robot live and drives it: joints, tool pose,
    servos, gripper, cameras, jogging with a deadman, named poses, action groups,
    pick-and-sort, and an e-stop (button or Escape) that holds every servo (and the
    wheels). On a mobile robot also transport and line following, with its map.

    Without --port it runs the twin in real time (its camera calibration kept for the
    robot, made first if there is none); --port 'board://twin?family=arena&seed=N' is
    the mobile robot's twin in an arena. Prints the page's address; Ctrl+C stops the
    robot (holding) and the server.
    """
    from busarm.dashboard.access import Access
    from busarm.dashboard.mobile import MobileSetup
    from busarm.dashboard.server import bind_socket

    parts = {k: v for k, v in (("chassis", chassis), ("lidar", lidar_port)) if v is not None}
    mobile = (MobileSetup(points_file, map_file), parts)
    mobile[0].load()  # a bad points or map file is refused before the robot is opened
    access = Access.for_bind(bind, token)
    sock = bind_socket(bind, http_port)  # a taken port is refused before the twin starts
    restore = interrupt_on_signals()  # SIGTERM while starting: stopped as by Ctrl+C
    try:
        _run(settings, sock, access, (scene_file, seed, blocks, colors), camera_src,
             reports_dir, fps, config, mobile)
    finally:
        restore()
        sock.close()
    click.echo("dashboard stopped: every servo was told to stop where it is (MOVE_STOP)",
               err=True)


def _run(settings: Settings, sock: socket.socket, access: Access,
         table: tuple[Path | None, int | None, int | None, str | None],
         camera_src: str | None, reports_dir: Path, fps: float, config: str,
         mobile: tuple[MobileSetup, dict[str, str]]) -> None:
    from busarm.arm.config import load_arm_config
    from busarm.dashboard.feeds import robot_feeds
    from busarm.dashboard.server import serve
    from busarm.dashboard.service import RobotService

    def say(text: str) -> None:
        if " view " not in text:
            settings.err.print(text, highlight=False, soft_wrap=True)

    with open_live_robot(settings, table, camera=camera_src, config=load_arm_config(config),
                         progress=say, **mobile[1]) as (robot, store):
        # Its saved poses and recorded groups are the robot's, where the commands find them
        # (the folder its calibration is kept in: a served arm's kind, `twin`, a device).
        service = RobotService(robot, folder=store.folder, reports=reports_dir,
                               mobile=mobile[0]).start()
        feeds = robot_feeds(robot, fps)

        def announce(link: str) -> None:
            click.echo(link)
            sys.stdout.flush()
            where = "the twin (real time)" if robot.is_twin else (
                settings.session.describe() if settings.session is not None else robot.port)
            settings.err.print(
                f"dashboard of the {robot.config.name} on {where}: open {link} in a browser"
                + ("" if access.loopback else " (the token is in the link: keep it to "
                                              "yourself)")
                + "; Ctrl+C stops the robot and the server", highlight=False, soft_wrap=True)

        serve(service, access, feeds, sock=sock, announce=announce)


COMMANDS = [dashboard]
