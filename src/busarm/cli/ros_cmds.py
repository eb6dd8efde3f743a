"""``ros bridge | topics | echo``: the robot on ROS 2 (rmw_zenoh's wire format, no ROS).

``bridge`` opens the robot (the twin in real time by default, as the dashboard does) and
publishes it on a Zenoh session with rmw_zenoh's keys, attachments and liveliness tokens;
``topics`` and ``echo`` look at such a session from outside, as ``ros2 topic list -t`` and
``ros2 topic echo`` would. Needs the ``busarm[ros]`` extra.
"""

from __future__ import annotations

import json
import signal
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.cli.common import (
    RangeType,
    Settings,
    Terminated,
    interrupt_on_signals,
    note_the_stop,
    open_live_robot,
    pass_settings,
    scene_options,
    stop_wheels,
)
from busarm.errors import ConfigError

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "COMMANDS",
    "DEFAULT_ENDPOINT",
    "bridge",
    "echo",
    "record",
    "ros",
    "topics",
]


DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def _session_options(func: Any) -> Any:
    func = click.option("--token", default=None, envvar="BUSARM_TOKEN",
                        help="Zenoh user-password token every peer gives (needed to listen "
                             "off this computer; or $BUSARM_TOKEN)  [default: none]")(func)
    func = click.option("--domain", "domain_id", type=click.IntRange(0, 232), default=0,
                        show_default=True,
                        help="ROS_DOMAIN_ID, as ROS 2 nodes have it (0..232).")(func)
    return func


def _open(listen: tuple[str, ...], connect: tuple[str, ...], token: str | None
          ) -> zenoh.Session:
    from busarm.bus.zenoh_session import need_zenoh, open_session

    need_zenoh()
    return open_session(listen=listen, connect=connect, token=token)


@click.group()
def ros() -> None:
    """The robot on ROS 2 over Zenoh (rmw_zenoh's wire format): no ROS install needed."""


@ros.command()
@scene_options
@click.option("--listen", multiple=True, metavar="ENDPOINT",
              help=f"Zenoh endpoint to listen on (repeatable)  [default: {DEFAULT_ENDPOINT} "
                   "unless --connect is given]")
@click.option("--connect", multiple=True, metavar="ENDPOINT",
              help="Zenoh endpoint to connect to (repeatable), e.g. a zenohd router's "
                   "tcp/HOST:7447  [default: none]")
@_session_options
@click.option("--rate", "state_hz", type=RangeType("rate", 1.0, 200.0, "Hz"), default=60.0,
              show_default=True, metavar="HZ", help="/joint_states and /tf a second, in Hz.")
@click.option("--fps", type=RangeType("fps", 1.0, 30.0, "frames/s"), default=15.0,
              show_default=True, metavar="FPS", help="Camera frames a second at most, in frames/s.")
@click.option("--camera", "camera_src", default=None,
              help="The wrist camera: a device, file or stream URL  [default: the twin's; "
                   "on hardware none]")
@click.option("--name", "robot_name", default="busarm", show_default=True,
              help="The robot's name for other busarm processes: they open it as "
                   "--port zenoh://HOST?robot=NAME (the default name needs no ?robot=).")
@click.option("--map", "map_file", default=None, metavar="MAP.yaml",
              type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="A saved map (busarm map build) to publish on /map  [default: none]")
@click.option("--no-camera", is_flag=True,
              help="Publish no camera (nor blocks): a twin renders nothing, and makes no "
                   "camera calibration.")
@click.option("--config", default="jetauto_pro", show_default=True,
              help="Arm description: a shipped name or a TOML file.")
@click.option("--time", "duration_s", type=RangeType("time", 0.1, 1e6, "s"), metavar="S",
              default=None, help="Stop after this many s  [default: until Ctrl+C]")
@pass_settings
def bridge(settings: Settings, scene_file: Path | None, seed: int | None, blocks: int | None,
           colors: str | None, listen: tuple[str, ...], connect: tuple[str, ...],
           token: str | None, domain_id: int, state_hz: float, fps: float,
           camera_src: str | None, robot_name: str, map_file: Path | None,
           no_camera: bool, config: str,
           duration_s: float | None) -> None:
    """Publish the robot to ROS 2 and take commands from it: /joint_states, /tf,
    /robot_description, /diagnostics, the wrist camera (image_raw, compressed,
    camera_info), /blocks, on a mobile robot /odom and /scan, and /map with --map;
    /joint_trajectory,
    /gripper/command, /cmd_vel, /estop and /rearm in. Every command is checked against
    the robot's limits before anything moves; a bad one is logged and dropped.

    Without --port it runs the twin in real time. Prints one line when it is up;
    Ctrl+C (or --time) stops the robot (the arm holds, the wheels stop); SIGTERM or
    SIGHUP too, said in one line as every command says it (exit code 143 or 129).
    """
    from busarm.arm.config import load_arm_config
    from busarm.nav.map_files import load_map
    from busarm.ros.bridge import BridgeSettings, RosBridge
    from busarm.ros.node import RosNode

    if no_camera and camera_src is not None:
        raise ConfigError("--camera and --no-camera: give one")
    grid = load_map(map_file) if map_file is not None else None  # refused before opening
    listen = listen or (() if connect else (DEFAULT_ENDPOINT,))
    session = _open(listen, connect, token)  # a taken port is refused before the twin starts
    # Ctrl+C ends it as a server ends (exit 0); SIGTERM and SIGHUP as every job (Terminated).
    restore = interrupt_on_signals((signal.SIGINT,))
    try:
        with open_live_robot(settings, (scene_file, seed, blocks, colors),
                             camera=camera_src, config=load_arm_config(config),
                             calibrate=not no_camera) as (robot, _):
            node = RosNode(session, domain_id=domain_id)
            running = RosBridge(robot, node, BridgeSettings(
                state_hz=state_hz, camera_fps=fps, camera=not no_camera, map_grid=grid),
                serve_as=robot_name).start()
            where = "the twin (real time)" if robot.is_twin else robot.port
            click.echo(f"ROS 2 bridge of the {robot.config.name} on {where}: node /busarm, "
                       f"domain {domain_id}, "
                       + ", ".join([*(f"listening on {e}" for e in listen),
                                    *(f"connected to {e}" for e in connect)])
                       + ("; other busarm processes: --port zenoh://HOST"
                          + ("" if robot_name == "busarm" else f"?robot={robot_name}")
                          if running.server is not None else "")
                       + "; Ctrl+C stops the robot")
            sys.stdout.flush()
            signalled: Terminated | None = None
            try:
                deadline = time.monotonic() + (duration_s or float("inf"))
                while time.monotonic() < deadline and not running.errors:
                    time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
            except Terminated as exc:
                signalled = exc
            except KeyboardInterrupt:
                pass
            finally:
                running.close()
            if signalled is not None:  # one line: the arm held (read back), the wheels
                note_the_stop(signalled, robot.arm.bus, robot.config.servo_ids)
                stop_wheels(robot, signalled)
                raise signalled
            if running.errors:
                raise ConfigError(f"the bridge stopped: {running.errors[0]}")
    finally:
        restore()
        session.close()
    click.echo("bridge stopped: every servo was told to stop where it is (MOVE_STOP)",
               err=True)


@ros.command()
@click.option("--connect", multiple=True, metavar="ENDPOINT",
              help=f"Zenoh endpoint to connect to  [default: {DEFAULT_ENDPOINT}]")
@_session_options
@click.option("--json", "as_json", is_flag=True, help="Print the graph as JSON.")
def topics(connect: tuple[str, ...], token: str | None, domain_id: int,
           as_json: bool) -> None:
    """List the ROS 2 topics on the session, with their types, publishers and
    subscribers (as `ros2 topic list -t` would, from rmw_zenoh's liveliness tokens)."""
    from busarm.ros.graph import read_graph

    session = _open((), connect or (DEFAULT_ENDPOINT,), token)
    try:
        graph = read_graph(session, domain_id)
    finally:
        session.close()
    if as_json:
        click.echo(json.dumps(graph.as_dict(), indent=2))
        return
    if not graph.topics:
        click.echo(f"no ROS 2 topics on domain {domain_id} (is a bridge or a ROS 2 node "
                   "with rmw_zenoh connected?)")
    for topic in graph.topics:
        click.echo(f"{topic.name} [{topic.ros_type}] publishers {topic.publishers}, "
                   f"subscribers {topic.subscribers}")


@ros.command()
@click.argument("topic")
@click.option("--connect", multiple=True, metavar="ENDPOINT",
              help=f"Zenoh endpoint to connect to  [default: {DEFAULT_ENDPOINT}]")
@_session_options
@click.option("--count", type=click.IntRange(1, 1_000_000), default=1, show_default=True,
              help="How many messages to print (a count).")
@click.option("--timeout", "timeout_s", type=RangeType("timeout", 0.1, 3600.0, "s"),
              default=5.0, show_default=True,
              help="Give up when nothing comes for this many s.")
def echo(topic: str, connect: tuple[str, ...], token: str | None, domain_id: int,
         count: int, timeout_s: float) -> None:
    """Print messages of TOPIC as JSON, one a line (its type found from its publisher's
    liveliness token, as `ros2 topic echo` does)."""
    from busarm.ros.graph import echo_messages

    session = _open((), connect or (DEFAULT_ENDPOINT,), token)
    try:
        for line in echo_messages(session, domain_id, topic, count, timeout_s):
            click.echo(line)
            sys.stdout.flush()
    finally:
        session.close()


@ros.command()
@click.argument("out", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--connect", multiple=True, metavar="ENDPOINT",
              help=f"Zenoh endpoint to connect to  [default: {DEFAULT_ENDPOINT}]")
@_session_options
@click.option("--topic", "topics", multiple=True,
              help="A topic to record (repeatable)  [default: every published topic]")
@click.option("--time", "duration_s", type=RangeType("time", 0.1, 1e6, "s"), metavar="S",
              default=None, help="Stop after this many s  [default: until Ctrl+C]")
def record(out: Path, connect: tuple[str, ...], token: str | None, domain_id: int,
           topics: tuple[str, ...], duration_s: float | None) -> None:
    """Record the session's ROS 2 topics into OUT (an MCAP file, as rosbag2 writes one:
    `ros2 bag play` and Foxglove replay it) until Ctrl+C or --time."""
    from busarm.ros.recorder import McapRecorder

    session = _open((), connect or (DEFAULT_ENDPOINT,), token)
    restore = interrupt_on_signals()
    try:
        recorder = McapRecorder(session, out, domain_id=domain_id, topics=list(topics))
        until = "until Ctrl+C" if duration_s is None else f"for {duration_s:g} s"
        click.echo(f"recording {len(recorder.topics)} topics into {out} {until}", err=True)
        try:
            deadline = time.monotonic() + (duration_s or float("inf"))
            while time.monotonic() < deadline:
                time.sleep(min(0.2, max(0.0, deadline - time.monotonic())))
        except KeyboardInterrupt:
            pass
        path = recorder.close()
    finally:
        restore()
        session.close()
    for topic, count in sorted(recorder.counts.items()):
        click.echo(f"{topic}: {count} messages")
    click.echo(f"recorded {sum(recorder.counts.values())} messages into {path}", err=True)


COMMANDS = [ros]
