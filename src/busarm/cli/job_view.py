"""A job's run in Foxglove: ``--foxglove PORT`` (live) and ``--mcap FILE`` (recorded), and
the view that ``busarm view`` and ``busarm record`` start (re-exported by
busarm.cli.common). foxglove-sdk is imported only when a view is asked for.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from busarm.errors import ConfigError

if TYPE_CHECKING:
    from busarm.apps.line_follow.job import LineFollowJob
    from busarm.apps.navigation.explore import Explorer
    from busarm.apps.navigation.navigator import Navigator
    from busarm.apps.navigation.sensing import SensedScan
    from busarm.cli.common import Settings
    from busarm.nav.points import NamedPoints
    from busarm.robot import Robot
    from busarm.view.live import RobotView, ViewSettings

__all__ = [
    "JOB_VIEW_FPS",
    "JOB_VIEW_HZ",
    "explore_hook",
    "line_follow_hook",
    "navigation_hook",
    "need_view",
    "start_view",
    "view_options",
    "watching",
]


def need_view() -> None:
    """ConfigError saying what to install when the ``busarm[view]`` extra is missing."""
    try:
        import foxglove  # noqa: F401
    except ImportError as exc:
        raise ConfigError("this needs foxglove-sdk: pip install 'busarm[view]'") from exc


def start_view(robot: Robot, view_settings: ViewSettings, stack: ExitStack,
               settings: Settings, record_into: Path | None = None) -> RobotView:
    """A RobotView of ``robot``, started, closed with ``stack``; recording into
    ``record_into`` (when given) until after it is closed, so that the file has all."""
    from busarm.view.live import RobotView

    running = RobotView(robot, view_settings)
    if record_into is not None:
        _record_into(running, record_into, stack, settings)
    stack.callback(running.close)  # last in, first out: before the recording finishes
    return running.start()


def _record_into(running: RobotView, path: Path, stack: ExitStack,
                 settings: Settings) -> None:
    """Record ``running`` into ``path`` until the stack closes, then say what it holds."""
    from busarm.view.recording import McapRecording

    recording = McapRecording(running, path)

    def finish() -> None:
        done = recording.close()
        counts = dict(sorted(running.counts.items()))
        for topic, count in counts.items():
            settings.out.print(f"{topic}: {count} messages", highlight=False, markup=False)
        settings.err.print(f"recorded {sum(counts.values())} messages on {len(counts)} "
                           f"channels into {done}", highlight=False, markup=False)
    stack.callback(finish)


def view_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--foxglove N (a TCP port) and --mcap FILE, for a job: watch it live, record its
    run."""
    func = click.option(
        "--mcap", "mcap_file", default=None, metavar="OUT.mcap",
        type=click.Path(dir_okay=False, path_type=Path),
        help="Record the run (the robot, the map, the plan, the path) into this MCAP "
             "file, which Foxglove replays  [default: none]")(func)
    return click.option(
        "--foxglove", "foxglove_port", type=click.IntRange(0, 65535), default=None,
        help="Serve the run live to Foxglove on ws://127.0.0.1:N, this TCP port (8765 is "
             "Foxglove's default)  [default: none]")(func)


JOB_VIEW_FPS = 5.0
"""A job's view: its own pictures come first, the view's camera at a few frames a second."""
JOB_VIEW_HZ = 20.0


@contextmanager
def watching(settings: Settings, robot: Robot, foxglove_port: int | None,
             mcap_file: Path | None) -> Iterator[RobotView | None]:
    """A RobotView of ``robot`` served on ``foxglove_port`` (loopback) and/or recorded
    into ``mcap_file`` while the body runs (None when neither is asked for)."""
    if foxglove_port is None and mcap_file is None:
        yield None
        return
    need_view()
    from busarm.cli.common import check_writable
    from busarm.view.live import ViewSettings
    from busarm.view.server import serve_view

    if mcap_file is not None:
        check_writable(mcap_file)
    with ExitStack() as stack:
        running = start_view(robot, ViewSettings(state_hz=JOB_VIEW_HZ, camera_fps=JOB_VIEW_FPS),
                             stack, settings, mcap_file)
        if foxglove_port is not None:
            server = serve_view(running, "127.0.0.1", foxglove_port)
            stack.callback(server.stop)
            settings.err.print(f"Foxglove: open a connection to {server.url}",
                               highlight=False, markup=False, soft_wrap=True)
        yield running


def explore_hook(view: RobotView | None) -> Callable[[Explorer], None] | None:
    """An Explorer's ``on_scan`` that shows its map and path (None without a view)."""
    if view is None:
        return None
    from busarm.view.jobs import explore_hook as hook

    return hook(view)


def navigation_hook(view: RobotView | None, points: NamedPoints, names: tuple[str, ...]
                    ) -> Callable[[Navigator, SensedScan], None] | None:
    """A Navigator's ``on_scan`` that shows its map, plan, path and the points ``names``
    (None without a view)."""
    if view is None:
        return None
    from busarm.view.jobs import navigation_hook as hook

    return hook(view, points, names)


def line_follow_hook(view: RobotView | None) -> Callable[[LineFollowJob], None] | None:
    """A LineFollowJob's ``on_step`` that shows its path and what it found (None without a
    view)."""
    if view is None:
        return None
    from busarm.view.jobs import line_follow_hook as hook

    return hook(view)
