"""``view`` and ``record``: the robot live in Foxglove, and recorded for it; and the
``--foxglove``/``--mcap`` options by which a job's run is watched and recorded.

``view`` opens the robot (the twin in real time by default, as the dashboard does) and
serves its channels (busarm.view) over Foxglove's WebSocket protocol until Ctrl+C;
``record`` writes the same channels into an MCAP file for ``--seconds`` or until Ctrl+C
(SIGTERM or SIGHUP end it as a job: the file finished, exit 143 or 129). Neither moves
the robot. Needs the ``busarm[view]`` extra.
"""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.cli.common import (
    RangeType,
    Settings,
    Terminated,
    check_writable,
    interrupt_on_signals,
    need_view,
    open_live_robot,
    pass_settings,
    say_view_errors,
    scene_options,
    start_view,
)
from busarm.errors import BusArmError, ConfigError

if TYPE_CHECKING:
    from busarm.nav.grid import OccupancyGrid
    from busarm.robot import Robot
    from busarm.view.live import RobotView, ViewSettings
    from busarm.view.server import ViewServer

__all__ = [
    "COMMANDS",
    "record",
    "view",
]


def _robot_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """What ``view`` and ``record`` share: the robot, and what to publish of it."""
    for option in reversed([
        scene_options,
        click.option("--camera", "camera_src", default=None,
                     help="The wrist camera: a device, file or stream URL  [default: the "
                          "twin's; on hardware none]"),
        click.option("--no-camera", is_flag=True,
                     help="Publish no camera (nor blocks): a twin renders nothing."),
        click.option("--fps", type=RangeType("fps", 1.0, 30.0, "frames/s"), default=10.0,
                     show_default=True, metavar="FPS",
                     help="Camera frames a second at most, in frames/s, 1..30."),
        click.option("--rate", "state_hz", type=RangeType("rate", 1.0, 100.0, "Hz"),
                     default=30.0, show_default=True, metavar="HZ",
                     help="/tf and /joint_states a second, in Hz, 1..100."),
        click.option("--map", "map_file", default=None, metavar="MAP.yaml",
                     type=click.Path(dir_okay=False, exists=True, path_type=Path),
                     help="A saved map (busarm map build) to show on /map  [default: none]"),
        click.option("--config", default="jetauto_pro", show_default=True,
                     help="Arm description: a shipped name or a TOML file."),
        click.option("--chassis", default=None,
                     help="With --port board://DEVICE: the mobile base's chassis config  "
                          "[default: no base; a board://twin in an arena has its own]"),
        click.option("--lidar", "lidar_port", default=None,
                     help="With --port board://DEVICE: the Lidar's serial port  [default: "
                          "none; a board://twin in an arena has its own]"),
    ]):
        func = option(func)
    return func


def _settings(no_camera: bool, camera_src: str | None, fps: float, state_hz: float,
              map_file: Path | None) -> tuple[ViewSettings, OccupancyGrid | None]:
    from busarm.nav.map_files import load_map
    from busarm.view.live import ViewSettings

    if no_camera and camera_src is not None:
        raise ConfigError("--camera and --no-camera: give one")
    grid = load_map(map_file) if map_file is not None else None  # refused before opening
    return ViewSettings(state_hz=state_hz, camera_fps=fps, camera=not no_camera,
                        map_grid=grid), grid


@contextmanager
def _live(settings: Settings, table: Any, camera_src: str | None, config: str,
          chassis: str | None, lidar_port: str | None, no_camera: bool
          ) -> Iterator[Robot]:
    from busarm.arm.config import load_arm_config

    parts = {k: v for k, v in (("chassis", chassis), ("lidar", lidar_port)) if v is not None}
    with open_live_robot(settings, table, camera=camera_src, config=load_arm_config(config),
                         calibrate=not no_camera, **parts) as (robot, _):
        yield robot


MAX_SECONDS = 86400.0
"""The longest --seconds: a day."""


def _seconds_option(help_text: str) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    return click.option("--seconds", "duration_s", default=None,
                        type=RangeType("seconds", 0.1, MAX_SECONDS, "s"),
                        help=f"{help_text} this many s, 0.1..{MAX_SECONDS:g}  [default: "
                             "until Ctrl+C]")


def _wait(settings: Settings, duration_s: float | None, view: RobotView) -> None:
    """Until Ctrl+C, ``duration_s``, or a loop of the view stops (BusArmError: exit 1);
    what goes wrong in the view meanwhile is said as it comes, once. SIGTERM and SIGHUP
    go through (``Terminated``) unless the command made them a Ctrl+C."""
    deadline = time.monotonic() + (duration_s or float("inf"))
    said = 0
    try:
        while time.monotonic() < deadline and view.failure is None:
            said = say_view_errors(settings, view, said, failure=False)
            time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
    except Terminated:
        raise
    except KeyboardInterrupt:
        pass
    say_view_errors(settings, view, said, failure=False)
    if view.failure is not None:
        raise BusArmError(f"the view stopped: {view.failure}")


@click.command()
@_robot_options
@click.option("--bind", default="127.0.0.1", show_default=True,
              help="Address to listen on; any other than loopback needs a token.")
@click.option("--ws-port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="TCP port of the WebSocket (Foxglove's default; 0: any free port).")
@click.option("--token", default=None,
              help="The token every client must give (?token= in the URL)  [default: none "
                   "on loopback, else a new one, printed]")
@click.option("--record", "record_file", default=None, metavar="OUT.mcap",
              type=click.Path(dir_okay=False, path_type=Path),
              help="Also record every channel into this MCAP file  [default: none]")
@_seconds_option("Stop after")
@pass_settings
def view(settings: Settings, scene_file: Path | None, seed: int | None, blocks: int | None,
         colors: str | None, camera_src: str | None, no_camera: bool, fps: float,
         state_hz: float, map_file: Path | None, config: str, chassis: str | None,
         lidar_port: str | None, bind: str, ws_port: int, token: str | None,
         record_file: Path | None, duration_s: float | None) -> None:
    """Serve the robot live to Foxglove (its WebSocket protocol): the robot model
    (/robot_description, a URDF) moving with its joints (/tf), the wrist camera, the
    blocks it sees, and on a mobile robot the odometry and the Lidar (/scan); /map with
    --map. Open Foxglove, "Open connection", Foxglove WebSocket, and give the URL printed.

    Without --port it runs the twin in real time; --port 'board://twin?family=arena&seed=N'
    is the mobile robot's twin in an arena. The view only watches: nothing is sent to
    the robot. Ctrl+C (or --seconds) stops it.
    """
    need_view()
    from busarm.netaddr import check_can_listen
    from busarm.view.server import MIN_TOKEN_CHARS, serve_view

    view_settings, _ = _settings(no_camera, camera_src, fps, state_hz, map_file)
    if record_file is not None:
        check_writable(record_file)
    if token is not None and len(token) < MIN_TOKEN_CHARS:
        raise ConfigError(f"--token of {len(token)} characters: give at least "
                          f"{MIN_TOKEN_CHARS} (or none, and one is made)")
    check_can_listen(bind, ws_port, "--ws-port")  # refused before the twin starts
    restore = interrupt_on_signals()
    try:
        with _live(settings, (scene_file, seed, blocks, colors), camera_src, config,
                   chassis, lidar_port, no_camera) as robot, ExitStack() as stack:
            running, recorder = start_view(robot, view_settings, stack, settings,
                                           record_file)
            server = serve_view(running, bind, ws_port, token)
            stack.callback(server.stop)
            if recorder is not None:
                recorder.began()
            click.echo(server.url)
            sys.stdout.flush()
            where = "the twin (real time)" if robot.is_twin else robot.port
            settings.err.print(f"Foxglove view of the {robot.config.name} on {where}: "
                               f"{_where_to_connect(server)}; channels: "
                               f"{', '.join(running.topics)}; Ctrl+C stops",
                               highlight=False, markup=False, soft_wrap=True)
            _wait(settings, duration_s, running)
    finally:
        restore()
    click.echo("view stopped (the robot was only watched)", err=True)


def _where_to_connect(server: ViewServer) -> str:
    """How to open the view in Foxglove: the URLs, and the web app's link (a browser on
    this computer only: an https page may open a plain ws:// here, not elsewhere)."""
    from busarm.view.server import is_loopback

    secret = "" if server.token is None else " (the token is in the URL: keep it to yourself)"
    if is_loopback(server.host):
        return (f"in Foxglove, open a connection (Foxglove WebSocket) to {server.url}, or "
                f"open {server.app_url}{secret}")
    others = server.urls[1:]
    return (f"from any computer, open a connection (Foxglove WebSocket) in Foxglove to "
            f"{server.url}" + (f" (or {', '.join(others)})" if others else "")
            + f"{secret}; in a browser on this computer only, Foxglove's web app: "
              f"{server.app_url}")


@click.command()
@click.argument("out", type=click.Path(dir_okay=False, path_type=Path))
@_robot_options
@_seconds_option("Record")
@pass_settings
def record(settings: Settings, out: Path, scene_file: Path | None, seed: int | None,
           blocks: int | None, colors: str | None, camera_src: str | None, no_camera: bool,
           fps: float, state_hz: float, map_file: Path | None, config: str,
           chassis: str | None, lidar_port: str | None, duration_s: float | None) -> None:
    """Record the robot's channels (those `busarm view` serves) into OUT, an MCAP file
    that Foxglove replays (open it in Foxglove), for --seconds or until Ctrl+C (exit 0);
    SIGTERM or SIGHUP finish the file too, and exit 143 or 129. The file appears under
    its name only when complete. To record a job's run with what it shows (its map,
    path), give the job --mcap OUT.mcap (transport, map build, line-follow).
    """
    need_view()
    view_settings, _ = _settings(no_camera, camera_src, fps, state_hz, map_file)
    check_writable(out)
    # Ctrl+C is how it ends when no --seconds; SIGTERM and SIGHUP end it as a job.
    restore = interrupt_on_signals((signal.SIGINT,))
    try:
        with _live(settings, (scene_file, seed, blocks, colors), camera_src, config,
                   chassis, lidar_port, no_camera) as robot, ExitStack() as stack:
            running, recorder = start_view(robot, view_settings, stack, settings, out)
            assert recorder is not None
            recorder.began()
            until = "until Ctrl+C" if duration_s is None else f"for {duration_s:g} s"
            settings.err.print(f"recording {', '.join(running.topics)} into {out} {until}",
                               highlight=False, markup=False, soft_wrap=True)
            _wait(settings, duration_s, running)
    finally:
        restore()


COMMANDS = [view, record]
