"""The mobile jobs' hooks that feed a RobotView: the map, the plan, the path driven, the
base's place on the map, as the job knows them.

A job calls its hook at each Lidar revolution (about 10 a second); the map and the
picture of the path go out at most ``MAP_EVERY_S`` and ``PATH_EVERY_S`` apart (of the
view's stamps: a twin in simulated time records at its own pace), the base's place on
the map at every revolution (it is one transform).

A hook runs in the job's own loop: whatever fails in it (a sink, the odometry read) is
noted once in the view's ``errors`` and the job goes on; the view only watches.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar, cast

from busarm.nav.grid import cropped
from busarm.nav.points import NamedPoints
from busarm.robot.frames import ODOM_FRAME
from busarm.view.live import RobotView
from busarm.view.messages import Point2

if TYPE_CHECKING:
    from busarm.apps.line_follow.job import LineFollowJob
    from busarm.apps.navigation.explore import Explorer
    from busarm.apps.navigation.navigator import Navigator
    from busarm.apps.navigation.sensing import SensedScan

__all__ = [
    "MAP_EVERY_S",
    "PATH_EVERY_S",
    "explore_hook",
    "line_follow_hook",
    "navigation_hook",
]


MAP_EVERY_S = 2.0
PATH_EVERY_S = 0.5
_Hook = TypeVar("_Hook", bound=Callable[..., None])


def _harmless(view: RobotView, hook: _Hook) -> _Hook:
    """``hook`` that never raises into the job calling it: an error is noted once in
    ``view.errors`` (a Ctrl+C or a signal still stops the job)."""
    def run(*args: Any) -> None:
        try:
            hook(*args)
        except Exception as exc:  # the view only watches: its failure is never the job's
            view.note(f"a job's view: {type(exc).__name__}: {exc}")
    return cast(_Hook, run)


class _Every:
    """True at most once per ``period_s`` of the view's stamps."""

    def __init__(self, view: RobotView, period_s: float) -> None:
        self.view, self.period_s = view, period_s
        self._last = -float("inf")

    def __call__(self) -> bool:
        now = self.view.now_s()
        if now - self._last < self.period_s:
            return False
        self._last = now
        return True


def navigation_hook(view: RobotView, points: NamedPoints | None = None,
                    names: tuple[str, ...] = ()) -> Callable[[Navigator, SensedScan], None]:
    """A Navigator's ``on_scan`` (a transport's): its map once, then the latest plan, the
    path driven and the named ``points`` (those in ``names``; all when empty)."""
    marks: dict[str, Point2] = {} if points is None else {
        name: (p.pose.x_m, p.pose.y_m) for name, p in points.points.items()
        if not names or name in names}
    path_due = _Every(view, PATH_EVERY_S)
    shown: list[object] = []

    def hook(nav: Navigator, sensed: SensedScan) -> None:
        if not shown or shown[0] is not nav.grid:
            view.show_map(nav.grid)
            shown[:] = [nav.grid]
        view.show_pose_on_map(nav.pose, sensed.odometry_now)
        if not path_due():
            return
        view.show_path(nav.latest_plan(), nav.path_driven(), marks)
    return _harmless(view, hook)


def explore_hook(view: RobotView) -> Callable[[Explorer], None]:
    """An Explorer's ``on_scan`` (``map build``, a transport's first exploring): the map
    as it grows, the path driven and the frontier it heads for."""
    map_due, path_due = _Every(view, MAP_EVERY_S), _Every(view, PATH_EVERY_S)

    def hook(explorer: Explorer) -> None:
        # The Explorer keeps no odometry of its own: read now, as its pose was just set.
        view.show_pose_on_map(explorer.pose, explorer.base.odometry().pose)
        if map_due():
            view.show_map(cropped(explorer.builder.grid))
        if path_due():
            driven = [(p.x_m, p.y_m) for p in explorer.builder.poses]
            marks = {"frontier": explorer.goal} if explorer.goal is not None else {}
            view.show_path((), driven, marks)
    return _harmless(view, hook)


def line_follow_hook(view: RobotView) -> Callable[[LineFollowJob], None]:
    """A LineFollowJob's ``on_step``: the path driven (in ``odom``: the job has no map),
    the blocks found on the line and the stops for obstacles."""
    path_due = _Every(view, PATH_EVERY_S)

    def hook(job: LineFollowJob) -> None:
        if not path_due():
            return
        r = job.report
        marks = {f"{i + 1} {b.color}": b.found_m for i, b in enumerate(r.blocks)}
        marks |= {f"stop {i + 1}": (s.at.x_m, s.at.y_m) for i, s in enumerate(r.stops)}
        view.show_path((), [(p.x_m, p.y_m) for p in r.path], marks, frame_id=ODOM_FRAME)
    return _harmless(view, hook)
