"""A job's run in Foxglove: ``--foxglove PORT`` (live) and ``--mcap FILE`` (recorded), and
the view that ``busarm view`` and ``busarm record`` start (re-exported by
busarm.cli.common). foxglove-sdk is imported only when a view is asked for.

The view only watches: a port in use or a file that cannot be written is refused while
the command line is read, before the robot is opened; a view that fails to start leaves
no file; what goes wrong in it while the job runs is said when the job ends, never the
job's end.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

import click

from busarm.errors import BusArmError, ConfigError

if TYPE_CHECKING:
    from busarm.apps.line_follow.job import LineFollowJob
    from busarm.apps.navigation.explore import Explorer
    from busarm.apps.navigation.navigator import Navigator
    from busarm.apps.navigation.sensing import SensedScan
    from busarm.cli.common import Settings
    from busarm.nav.points import NamedPoints
    from busarm.robot import Robot
    from busarm.view.live import RobotView, ViewSettings
    from busarm.view.recording import McapRecording

__all__ = [
    "JOB_VIEW_FPS",
    "JOB_VIEW_HZ",
    "Recorder",
    "explore_hook",
    "line_follow_hook",
    "messages_text",
    "navigation_hook",
    "need_view",
    "say_view_errors",
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


def messages_text(count: int) -> str:
    return f"{count} message" if count == 1 else f"{count} messages"


class Recorder:
    """A view recorded into a file until the stack it is on closes. If it closes before
    ``began()`` (the view failed to start, its port was taken) the file is abandoned:
    none is left. Else it is finished and what it holds is said: on stdout topic by
    topic (``per_topic``) and in one line on stderr, or, when the command ends on an
    exception (a signal, an error), as a detail of the one line that reports it."""

    def __init__(self, running: RobotView, path: Path, settings: Settings,
                 per_topic: bool) -> None:
        from busarm.view.recording import McapRecording

        self.view, self.settings, self.per_topic = running, settings, per_topic
        self.recording: McapRecording = McapRecording(running, path)
        self._began = False

    def began(self) -> None:
        self._began = True

    def summary(self) -> str:
        counts = {t: n for t, n in self.view.counts.items() if n}
        if not counts:
            return f"recorded no messages into {self.recording.path}"
        return (f"recorded {messages_text(sum(counts.values()))} on {len(counts)} "
                f"channel{'s' if len(counts) != 1 else ''} into {self.recording.path}")

    def __call__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> bool:
        """The stack's exit: finish the file (or abandon it); never swallows ``exc``."""
        from busarm.cli.common import add_detail  # common re-exports this module

        if not self._began:
            self.recording.abandon()
            return False
        try:
            self.recording.close()
        except BusArmError as error:
            if exc is None:
                raise
            add_detail(exc, f"the recording could not be finished: {error}")
            return False
        if self.per_topic:
            for topic, count in sorted(self.view.counts.items()):
                if count:
                    self.settings.out.print(f"{topic}: {messages_text(count)}",
                                            highlight=False, markup=False)
        if exc is None:
            self.settings.err.print(self.summary(), highlight=False, markup=False)
        else:
            add_detail(exc, self.summary())
        return False


def start_view(robot: Robot, view_settings: ViewSettings, stack: ExitStack,
               settings: Settings, record_into: Path | None = None, *,
               per_topic: bool = True) -> tuple[RobotView, Recorder | None]:
    """A RobotView of ``robot``, started, closed with ``stack``; recording into
    ``record_into`` (when given) until after it is closed, so that the file has all.
    The recording is kept only once the caller says the run ``began()``."""
    from busarm.view.live import RobotView

    running = RobotView(robot, view_settings)
    recorder = None
    if record_into is not None:
        recorder = Recorder(running, record_into, settings, per_topic)
        stack.push(recorder)
    stack.callback(running.close)  # last in, first out: before the recording finishes
    running.start()
    return running, recorder


def say_view_errors(settings: Settings, running: RobotView, said: int = 0, *,
                    failure: bool = True) -> int:
    """What went wrong in the view (each once, from the ``said``-th on), on stderr; the
    error that stopped a loop too unless not ``failure`` (the command's own error line
    says it). Returns how many there were."""
    errors = list(running.errors)
    for error in errors[said:]:
        if failure or error != running.failure:
            settings.err.print(f"warning: Foxglove view: {error}", highlight=False,
                               markup=False, soft_wrap=True)
    return len(errors)


def _port_free(ctx: click.Context, param: click.Parameter, port: int | None) -> int | None:
    """--foxglove's port is refused while argv is read, before the robot is opened."""
    if port is not None:
        from busarm.netaddr import check_can_listen

        check_can_listen("127.0.0.1", port, "--foxglove")
    return port


def _writable(ctx: click.Context, param: click.Parameter, path: Path | None) -> Path | None:
    if path is not None:
        from busarm.cli.common import check_writable

        check_writable(path)
    return path


def view_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """--foxglove N (a TCP port) and --mcap FILE, for a job: watch it live, record its
    run."""
    func = click.option(
        "--mcap", "mcap_file", default=None, metavar="OUT.mcap", callback=_writable,
        type=click.Path(dir_okay=False, path_type=Path),
        help="Record the run into this MCAP file, which Foxglove replays: the robot and "
             "what the job shows (as --foxglove)  [default: none]")(func)
    return click.option(
        "--foxglove", "foxglove_port", type=click.IntRange(0, 65535), default=None,
        callback=_port_free,
        help="Serve the run live to Foxglove on ws://127.0.0.1:N, this TCP port (8765 is "
             "Foxglove's default; 0: any free port)  [default: none]")(func)


JOB_VIEW_FPS = 5.0
"""A job's view: its own pictures come first, the view's camera at a few frames a second."""
JOB_VIEW_HZ = 20.0


@contextmanager
def watching(settings: Settings, robot: Robot, foxglove_port: int | None,
             mcap_file: Path | None) -> Iterator[RobotView | None]:
    """A RobotView of ``robot`` served on ``foxglove_port`` (loopback) and/or recorded
    into ``mcap_file`` while the body runs (None when neither is asked for). What went
    wrong in the view is said when it ends."""
    if foxglove_port is None and mcap_file is None:
        yield None
        return
    need_view()
    from busarm.view.live import ViewSettings
    from busarm.view.server import serve_view

    with ExitStack() as stack:
        running, recorder = start_view(
            robot, ViewSettings(state_hz=JOB_VIEW_HZ, camera_fps=JOB_VIEW_FPS), stack,
            settings, mcap_file, per_topic=False)
        if foxglove_port is not None:
            server = serve_view(running, "127.0.0.1", foxglove_port, option="--foxglove")
            stack.callback(server.stop)
            settings.err.print(f"Foxglove: open a connection to {server.url}",
                               highlight=False, markup=False, soft_wrap=True)
        if recorder is not None:
            recorder.began()
        try:
            yield running
        finally:
            running.close()  # (again, from the stack: harmless) so that all is said
            say_view_errors(settings, running)


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
