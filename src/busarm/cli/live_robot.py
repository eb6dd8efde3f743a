"""Open the robot for a live interface (the dashboard, the ROS bridge): on a twin, one
that runs in real time, as a person watching it or a remote program driving it expects."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.cli.common import Settings
    from busarm.robot import Robot
    from busarm.robot.calibration_store import CalibrationStore

__all__ = [
    "DEFAULT_PORT",
    "Table",
    "open_live_robot",
]


DEFAULT_PORT = "twin"
"""A live interface's robot without --port: a twin of its own, in real time."""


Table = tuple[Path | None, int | None, int | None, str | None]
"""--scene, --seed, --blocks, --colors."""


@contextmanager
def open_live_robot(settings: Settings, table: Table, **options: Any
                    ) -> Iterator[tuple[Robot, CalibrationStore]]:
    """The robot on --port, a twin in real time (with ``table`` on its table) when none
    is given, or the arm of a running ``sim serve``/``twin serve`` when there is one and
    no table was asked for; with the calibration store its poses and calibration live in.
    ``options`` go to ``Robot.open``."""
    from busarm.cli.common import calibration_store, find_session, make_scene, with_realtime
    from busarm.robot.calibration_store import CalibrationStore
    from busarm.twin.spec import TwinSpec

    scene_file, seed, blocks, colors = table
    table_given = any(v is not None for v in table)
    # Without --port: the arm of a running `sim serve`/`twin serve` (watch what other
    # commands do to it), unless a table was asked for; else a twin of its own.
    default = "sim" if not settings.port_given and not table_given and (
        find_session() is not None) else DEFAULT_PORT
    world = settings.world(settings.port if settings.port_given else
                           settings.default_port() if default == "sim" else DEFAULT_PORT)
    on_twin = isinstance(world, TwinSpec)
    scene = (make_scene(scene_file, seed, blocks, colors) if on_twin and (
        table_given or not settings.port_given) else None)
    if table_given and isinstance(world, TwinSpec) and world.controller is not None:
        raise ConfigError(f"--port {world.name}: a twin behind the board stands in an arena "
                          "(family=arena&seed=N), not at a table: leave out "
                          "--scene/--seed/--blocks/--colors")
    world = with_realtime(world)
    # A twin behind a simulated board keeps its calibration and poses as `twin` does.
    store = (CalibrationStore.for_port(world) if on_twin and (
        settings.port_given or default != "sim") else calibration_store(settings))
    if not settings.port_given and default == "sim" and settings.session is not None:
        options.setdefault("camera", settings.session.camera)
    with settings.open_robot(world=world, scene=scene, calibration_store=store,
                             **options) as robot:
        yield robot, store
