"""What the mobile jobs' commands share: the arena option, opening the mobile robot
(re-exported by busarm.cli.common).

Without ``--port`` a mobile job runs on a twin of its own in an arena (``--arena SEED|FILE``),
as pick-sort runs on its own table; with ``--port board://...`` it runs on that robot,
its Lidar on ``--lidar`` (or the Lidar of a running ``twin serve --arena``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import click

from busarm.errors import BusArmError, ConfigError

if TYPE_CHECKING:
    from busarm.cli.common import Settings
    from busarm.robot import Robot
    from busarm.twin.arena import Arena

__all__ = [
    "MAX_SEED",
    "arena_from_spec",
    "keeping_what_was_done",
    "mobile_options",
    "open_mobile_robot",
    "stop_wheels",
]


MAX_SEED = 2**32 - 1


def arena_from_spec(spec: str) -> Arena:
    """--arena's value: a seed (digits) or an arena file."""
    from busarm.twin.arena import load_arena
    from busarm.twin.arena_gen import random_arena

    if spec.isdigit():
        if int(spec) > MAX_SEED:
            raise ConfigError(f"--arena {spec}: a seed must be 0..{MAX_SEED}")
        return random_arena(int(spec))
    return load_arena(spec)


def mobile_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--arena, --chassis, --lidar."""
    func = click.option(
        "--lidar", "lidar_port", default=None, envvar="BUSARM_LIDAR",
        help="With --port: the Lidar's serial port  [default: a running `twin serve "
             "--arena`'s]")(func)
    func = click.option(
        "--chassis", default=None,
        help="With --port: the chassis config (a shipped name, jetauto, or a TOML file).")(func)
    return click.option(
        "--arena", "arena_spec", default="0", show_default=True, metavar="SEED|FILE",
        help="Without --port: the twin's arena, a seed or an arena TOML file.")(func)


@contextmanager
def open_mobile_robot(settings: Settings, arena_spec: str, chassis: str | None,
                      lidar_port: str | None, *, camera: bool = False,
                      **robot_options: Any) -> Iterator[Robot]:
    """The robot on --port (a board:// port with a chassis and a Lidar), or without
    --port a twin of its own in ``arena_spec``'s arena; ``robot_options`` go to
    ``Robot.open`` (``config``, ``calibration_store``...). An exception leaving the body
    after a write to the arm stops it and says what its servos do (as ``open_robot``)."""
    from busarm.cli.common import (
        describe_robot,
        marking_the_stop,  # common re-exports this module
    )
    from busarm.progress import quiet
    from busarm.robot import Robot
    from busarm.sim.spec import BoardSettings
    from busarm.twin.spec import TwinSpec

    if not settings.port_given:
        if chassis is not None or lidar_port is not None:
            raise ConfigError("--chassis and --lidar are for a robot on --port; the twin "
                              "has its own (--arena chooses its world)")
        twin = TwinSpec(arena=arena_from_spec(arena_spec), controller=BoardSettings())
        needs = robot_options.pop("needs", ())
        progress = robot_options.pop("progress", quiet)
        robot = Robot.open(describe_robot(twin, settings.line(), calibrate=camera,
                                          **robot_options), needs=needs, progress=progress)
        with marking_the_stop(robot, robot.arm.bus, robot.config.servo_ids):
            yield robot
        return
    world = settings.world()
    if not world.through_board:
        raise ConfigError(f"--port {settings.port}: a mobile job drives the base through the "
                          "controller board: give a board:// port (e.g. board:///dev/rrc)")
    options: dict[str, Any] = dict(robot_options)
    if not isinstance(world, TwinSpec) or lidar_port is not None:
        options["lidar"] = _lidar_port(lidar_port)
    if chassis is not None:
        options["chassis"] = chassis
    with settings.open_robot(world=world, **options) as robot:
        yield robot


def stop_wheels(robot: Robot, exc: BaseException) -> None:
    """The wheels stopped again (a job stops them on its way out), said on the one line
    that reports ``exc`` if it worked."""
    from busarm.cli.common import add_detail  # common re-exports this module

    if robot.base is None:
        return
    try:
        robot.base.stop()
    except BusArmError:
        return
    add_detail(exc, "the wheels stopped")


@contextmanager
def keeping_what_was_done(robot: Robot, keep: Callable[[BaseException], str]
                          ) -> Iterator[None]:
    """The body of a mobile job: an exception leaving it (Ctrl+C, SIGTERM or SIGHUP, an
    error) stops the wheels and keeps what the job did so far: ``keep(exc)`` writes it
    and says where ("the report so far: PATH"). Both join the one line that reports the
    exception, after what the servos were left doing: the one format of every job."""
    from busarm.cli.common import add_detail  # common re-exports this module

    try:
        yield
    except BaseException as exc:
        stop_wheels(robot, exc)
        try:
            said = keep(exc)
        except (BusArmError, OSError) as error:  # the stop's own exception is the one
            said = f"the report could not be written: {error}"
        if said:
            add_detail(exc, said)
        raise


def _lidar_port(given: str | None) -> str:
    from busarm.cli.common import lidar_port_or_default  # common re-exports this module
    from busarm.robot.port_url import SIM_LIDAR

    port = lidar_port_or_default(given)
    if port == SIM_LIDAR and given is None:
        raise ConfigError("a mobile job needs the robot's Lidar: give --lidar PORT (e.g. "
                          "/dev/ttyUSB1; `busarm ports` lists the serial ports)")
    return port
