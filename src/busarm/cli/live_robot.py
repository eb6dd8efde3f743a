"""Open the robot for a live interface (the dashboard, the ROS bridge): on a twin, one
that runs in real time, as a person watching it or a remote program driving it expects."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qsl, urlsplit

from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.cli.common import Settings
    from busarm.robot import Robot
    from busarm.robot.calibration_store import CalibrationStore

__all__ = [
    "DEFAULT_PORT",
    "Table",
    "open_live_robot",
    "realtime_port",
    "twin_store_port",
]


DEFAULT_PORT = "twin://?realtime=1"


def realtime_port(port: str) -> str:
    """A twin or simulator URL in this process (``twin``, ``twin://?...``, ``sim``,
    ``sim://?...``, or either behind a simulated board, ``board://twin?...``) that follows
    the wall clock (in-process simulations otherwise run as fast as they compute, which
    no person can watch or stop in time); any other port as it is."""
    from busarm.bus.transport import board_target
    from busarm.sim.board import split_board_keys
    from busarm.twin.transport import is_twin_url, twin_query

    behind = board_target(port)
    inner = behind if behind is not None else port
    if is_twin_url(inner):
        query = twin_query(split_board_keys(inner)[0])  # the twin's keys (not a board's)
    elif inner == "sim" or inner.startswith("sim://"):
        query = dict(parse_qsl(urlsplit(inner).query)) if "://" in inner else {}
    else:
        return port
    if "pace" in query:
        raise ConfigError(f"--port {port}: the dashboard runs the robot in real time; "
                          "leave out pace=")
    if query.get("realtime") == "1":
        return port
    if port in ("twin", "sim"):
        return f"{port}://?realtime=1"
    return port + ("&" if "?" in port else "?") + "realtime=1"


def twin_store_port(port: str) -> str:
    """The port whose robot folder keeps the calibration and poses: a twin behind a
    simulated board is the twin (the same arm and camera as ``twin``'s)."""
    from busarm.bus.transport import board_target
    from busarm.twin.transport import is_twin_url

    behind = board_target(port)
    return "twin" if behind is not None and is_twin_url(behind) else port



Table = tuple[Path | None, int | None, int | None, str | None]
"""--scene, --seed, --blocks, --colors."""


@contextmanager
def open_live_robot(settings: Settings, table: Table, **options: Any
                    ) -> Iterator[tuple[Robot, CalibrationStore]]:
    """The robot on --port, a twin in real time (with ``table`` on its table) when none
    is given, or the arm of a running ``sim serve``/``twin serve`` when there is one and
    no table was asked for; with the calibration store its poses and calibration live in.
    ``options`` go to ``Robot.open``."""
    from busarm.cli.common import calibration_store, find_session, make_scene
    from busarm.robot.calibration_store import CalibrationStore

    scene_file, seed, blocks, colors = table
    table_given = any(v is not None for v in table)
    # Without --port: the arm of a running `sim serve`/`twin serve` (watch what other
    # commands do to it), unless a table was asked for; else a twin of its own.
    default = "sim" if not settings.port_given and not table_given and (
        find_session() is not None) else DEFAULT_PORT
    on_twin = default == DEFAULT_PORT if not settings.port_given else (
        settings.port.startswith("twin"))
    scene = (make_scene(scene_file, seed, blocks, colors) if on_twin and (
        table_given or not settings.port_given) else None)
    if settings.port_given:
        if table_given and twin_store_port(settings.port) != settings.port:
            raise ConfigError(f"--port {settings.port}: a twin behind the board stands in "
                              "an arena (family=arena&seed=N), not at a table: leave out "
                              "--scene/--seed/--blocks/--colors")
        settings.port = realtime_port(settings.port)
    # A twin behind a simulated board keeps its calibration and poses as `twin` does.
    store = (CalibrationStore.for_port("twin") if settings.port_given
             and twin_store_port(settings.port) == "twin" else
             calibration_store(settings, default=default if default == "sim" else "twin"))
    with settings.open_robot(default=default, scene=scene, calibration_store=store,
                             **options) as robot:
        yield robot, store
