"""What a line-following run did (``LineFollowReport``): laps, the offsets from the line,
the stops for obstacles (``ObstacleStop``) and the blocks cleared (``BlockCleared``); the
odometry's frame, metres, the robot's clock."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from busarm.base.odometry import Pose2D

__all__ = ["BlockCleared", "LineFollowReport", "ObstacleStop"]


@dataclass(frozen=True)
class ObstacleStop:
    """The base stopped for something the Lidar saw in its way."""

    at: Pose2D
    """Where the base stood (odometry frame)."""
    obstacle_m: tuple[float, float]
    """The nearest return in the way, base frame."""
    began_s: float
    seconds: float
    cleared: bool

    def to_dict(self) -> dict[str, Any]:
        return {"at": _pose_list(self.at), "obstacle_m": _xy_list(self.obstacle_m),
                "began_s": round(self.began_s, 2), "seconds": round(self.seconds, 2),
                "cleared": self.cleared}


@dataclass(frozen=True)
class BlockCleared:
    """A block found on the base's path, and what was done with it."""

    color: str
    found_m: tuple[float, float]
    """Where it was seen (odometry frame)."""
    put_m: tuple[float, float] | None
    """Where it was seen after it was put down (odometry frame; None if not seen)."""
    outcome: Literal["cleared", "failed", "not there"]
    """``not there``: a closer look found no block where the look ahead saw one (a block
    on a table, seen from afar as if on the floor): the base went on."""
    why: str = ""
    side: str = ""
    attempts: int = 0
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return self.outcome == "cleared"

    def to_dict(self) -> dict[str, Any]:
        return {"color": self.color, "outcome": self.outcome,
                "found_m": _xy_list(self.found_m),
                "put_m": None if self.put_m is None else _xy_list(self.put_m),
                "why": self.why, "side": self.side, "attempts": self.attempts,
                "seconds": round(self.seconds, 2)}


@dataclass
class LineFollowReport:
    """One line-following run (odometry frame, m; the robot's clock, s)."""

    laps_wanted: float
    laps_done: float = 0.0
    loop_length_m: float | None = None
    """The loop's length as the first lap measured it (None before)."""
    travelled_m: float = 0.0
    seconds: float = 0.0
    finished: bool = False
    why: str = ""
    path: list[Pose2D] = field(default_factory=list)
    """The odometry's pose at each scan."""
    lateral: list[tuple[float, float]] = field(default_factory=list)
    """(travelled m, the line's offset from the base's centre m, + left) as the tracker
    measured it, each scan the line was known under the base (but while it slides back
    onto the line after lining up with a block: ``LineFollowJob.rejoining``)."""
    stops: list[ObstacleStop] = field(default_factory=list)
    blocks: list[BlockCleared] = field(default_factory=list)
    searches: int = 0
    tape: str = ""
    """The tape's colour followed: given, or measured on the first look (``tape_measured``)."""
    tape_measured: bool = False

    def lateral_mm(self, after_m: float = 0.0) -> tuple[float, float] | None:
        """(median, max) of the tracker's |lateral| offsets (mm) after ``after_m`` driven."""
        values = [abs(v) for s, v in self.lateral if s >= after_m]
        if not values:
            return None
        return float(np.median(values)) * 1000.0, max(values) * 1000.0

    def to_dict(self) -> dict[str, Any]:
        lateral = self.lateral_mm()
        return {
            "format": "busarm.line_follow_report", "version": 1,
            "finished": self.finished, "why": self.why, "laps_wanted": self.laps_wanted,
            "laps_done": round(self.laps_done, 3),
            "loop_length_m": None if self.loop_length_m is None else round(self.loop_length_m, 3),
            "travelled_m": round(self.travelled_m, 3), "seconds": round(self.seconds, 2),
            "lateral_median_mm": None if lateral is None else round(lateral[0], 2),
            "lateral_max_mm": None if lateral is None else round(lateral[1], 2),
            "searches": self.searches, "tape": self.tape,
            "tape_measured": self.tape_measured,
            "stops": [s.to_dict() for s in self.stops],
            "blocks": [b.to_dict() for b in self.blocks],
            "path": [_pose_list(p) for p in self.path],
            "lateral": [[round(s, 3), round(v, 4)] for s, v in self.lateral],
        }


def _pose_list(pose: Pose2D) -> list[float]:
    return [round(pose.x_m, 4), round(pose.y_m, 4), round(pose.yaw_deg, 2)]


def _xy_list(xy: tuple[float, float]) -> list[float]:
    return [round(xy[0], 4), round(xy[1], 4)]
