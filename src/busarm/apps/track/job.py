"""Colour tracking (the vendor's game): the arm looks down at the table and keeps a block
of one colour in the middle of the wrist camera's picture while a person slides it about.

``TrackJob(robot, "red").run()`` moves the arm to its ``look`` pose and then, each camera
frame (paced at ``frame_rate_hz`` on the robot's clock; a real camera's own rate when
slower):

- the biggest blob of the colour whose size fits a block's top face at that distance is
  the block, then the one nearest where the block followed should be (``GATE_MM``: a
  second block of the colour is not jumped to); its centroid is cast onto the plane of
  the blocks' tops through the camera's calibration and its pose from the MEASURED
  joints (busarm.vision.localize);
- an alpha-beta filter of those table points gives the block's place and velocity;
- position-based visual servo with feed-forward: the image centre is aimed (through the
  arm's IK, busarm.apps.track.aim) at where the block will be when the move now sent ends
  (``move_s``, two frame periods, after the command), the aim's speed over the table
  limited to ``max_aim_mm_s`` and each joint kept within its speed limit; the servos'
  uniform moves then carry the camera along with the block between frames, and the next
  frame's measurement corrects what the prediction missed.

It ends when ``seconds`` have passed, when the block "left the view" (not seen for
``lost_frames`` frames running) or "left the reach" (the camera cannot be held over where
it was seen for ``REACH_FRAMES`` frames running): the arm is stopped and held where it is
(MOVE_STOP) and ``report`` says why. A Ctrl+C or an error stops it the same way (the
report so far kept).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from busarm.apps.track.aim import CameraAim
from busarm.errors import ConfigError, UnreachableError, VisionError, why_stopped
from busarm.perception.locate import AREA_RANGE, NOT_BLOCK_COLORS
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.units import check_int_range, check_range
from busarm.vision.camera import CameraFrame
from busarm.vision.color import Detection
from busarm.vision.color_thresholds import default_thresholds

__all__ = [
    "CENTRED_PX",
    "GATE_GROWTH_MM_S",
    "GATE_MM",
    "REACH_FRAMES",
    "FrameHook",
    "TrackJob",
    "TrackReport",
    "TrackSettings",
    "block_colors",
    "check_color",
]


CENTRED_PX = 40.0
"""A frame counts as centred when the block is this near the image centre."""
REACH_FRAMES = 3
"""Out of reach this many frames running: the block has left the reach."""
ALPHA, BETA = 0.6, 0.25
"""The alpha-beta filter's gains: a fresh measurement mostly, velocity smoothed over a
few frames (a centroid jitters by a pixel or two)."""
MAX_BLOCK_MM_S = 300.0
"""A velocity estimate above this is a mistake (a wrong blob), not a hand."""

GATE_MM = 40.0
GATE_GROWTH_MM_S = 150.0
"""The block followed is looked for this near where it should be, the more so the longer
it has not been seen: a block of the same colour farther off is another block."""

FrameHook = Callable[[CameraFrame], None]


def block_colors() -> list[str]:
    """The block colours of the shipped thresholds (what can be tracked)."""
    return [c for c in default_thresholds().names if c not in NOT_BLOCK_COLORS]


def check_color(color: str) -> str:
    """``color`` if it is a block colour; ConfigError naming the allowed ones."""
    allowed = block_colors()
    name = color.strip().lower() if isinstance(color, str) else color
    if name not in allowed:
        raise ConfigError(f"colour {color!r} is not a block colour; allowed: "
                          f"{', '.join(allowed)}")
    return str(name)


@dataclass(frozen=True)
class TrackSettings:
    """How the tracking runs (checked when made)."""

    frame_rate_hz: float = 15.0
    seconds: float | None = None
    """Stop after this long (the robot's clock); None: until the block leaves."""
    lost_frames: int = 15
    max_aim_mm_s: float = 250.0
    """The image centre moves over the table at most this fast."""
    block_size_mm: float = 30.0

    def __post_init__(self) -> None:
        check_range("frame_rate_hz", self.frame_rate_hz, 1.0, 60.0, "Hz")
        if self.seconds is not None:
            check_range("seconds", self.seconds, 0.1, 86400.0, "s")
        check_int_range("lost_frames", self.lost_frames, 1, 1000)
        check_range("max_aim_mm_s", self.max_aim_mm_s, 10.0, 1000.0, "mm/s")
        check_range("block_size_mm", self.block_size_mm, 5.0, 200.0, "mm")

    @property
    def period_s(self) -> float:
        return 1.0 / self.frame_rate_hz

    @property
    def move_s(self) -> float:
        """Each command's move time: two frames, so the arm keeps moving if one is late."""
        return 2.0 * self.period_s


@dataclass
class TrackReport:
    """One tracking run: per frame the block's pixel error from the image centre (None:
    not seen) and the latency from the frame's time to the command sent (s)."""

    color: str
    frames: int = 0
    errors_px: list[float | None] = field(default_factory=list)
    latencies_s: list[float] = field(default_factory=list)
    compute_s: list[float] = field(default_factory=list)
    """Per command, this computer's time from having the frame to the command sent
    (the wall clock: on a twin's simulated clock the latency counts only the bus)."""
    seconds: float = 0.0
    stop: str = ""
    """``time``, ``left the view``, ``left the reach``, or what stopped it otherwise."""
    why: str = ""

    def within(self, radius_px: float = CENTRED_PX) -> float:
        """The share of frames with the block seen within ``radius_px`` of the centre."""
        if not self.errors_px:
            return 0.0
        return sum(e is not None and e <= radius_px for e in self.errors_px) / len(self.errors_px)

    def error_stats_px(self) -> tuple[float, float] | None:
        """(median, p95) of the pixel errors of the frames the block was seen in."""
        seen = [e for e in self.errors_px if e is not None]
        if not seen:
            return None
        return float(np.median(seen)), float(np.percentile(seen, 95))

    def latency_stats_s(self) -> tuple[float, float] | None:
        if not self.latencies_s:
            return None
        return float(np.median(self.latencies_s)), float(np.percentile(self.latencies_s, 95))

    def compute_stats_s(self) -> tuple[float, float] | None:
        if not self.compute_s:
            return None
        return float(np.median(self.compute_s)), float(np.percentile(self.compute_s, 95))

    def to_dict(self) -> dict[str, Any]:
        err, lat, cpu = self.error_stats_px(), self.latency_stats_s(), self.compute_stats_s()
        return {
            "format": "busarm.track_report", "version": 1, "color": self.color,
            "frames": self.frames, "seconds": round(self.seconds, 3), "stop": self.stop,
            "why": self.why, "within_40px": round(self.within(), 4),
            "median_error_px": None if err is None else round(err[0], 2),
            "p95_error_px": None if err is None else round(err[1], 2),
            "median_latency_ms": None if lat is None else round(lat[0] * 1000, 2),
            "p95_latency_ms": None if lat is None else round(lat[1] * 1000, 2),
            "median_compute_ms": None if cpu is None else round(cpu[0] * 1000, 2),
            "p95_compute_ms": None if cpu is None else round(cpu[1] * 1000, 2),
            "errors_px": [None if e is None else round(e, 2) for e in self.errors_px],
        }


class _Stop(Exception):
    """The game is over (the block left), with the report's words."""

    def __init__(self, stop: str, why: str) -> None:
        super().__init__(why)
        self.stop = stop


class TrackJob:
    """Keep a ``color`` block centred in the wrist camera (see the module docstring).

    ``on_frame`` hears each frame as soon as it is read (a benchmark scores it against the
    twin's truth then)."""

    def __init__(self, robot: Robot, color: str, *, settings: TrackSettings | None = None,
                 on_frame: FrameHook | None = None, progress: Progress = quiet) -> None:
        self.color = check_color(color)
        self.settings = settings or TrackSettings()
        self.robot = robot
        self.clock = robot.clock
        self.locator = robot.locator([self.color], block_size_mm=self.settings.block_size_mm)
        look = robot.config.pose("look")
        self.look_deg = robot.config.check_joints(look)
        self.aim = CameraAim(self.locator, robot.arm.kin.fk(self.look_deg).z_mm,
                             robot.config.table_z_mm + self.settings.block_size_mm)
        self.on_frame = on_frame
        self.progress = progress
        self.report = TrackReport(self.color)
        self._place: tuple[float, float] | None = None
        self._velocity = (0.0, 0.0)
        self._seen_s = 0.0
        self._unseen = 0
        self._unreachable = 0
        self._had_frame = 0.0

    # ------------------------------------------------------------------ the run

    def run(self) -> TrackReport:
        """Track until the time is up or the block leaves; the report (also in
        ``report``, kept when a stop or an error raises)."""
        began = self.clock.now()
        try:
            self.robot.arm.move_joints(self.look_deg, speed_deg_s=60.0)
            self.progress(f"looking down at the table: keeping the {self.color} block centred")
            began = self.clock.now()
            next_s = began
            while True:
                if self.settings.seconds is not None and \
                        self.clock.now() - began >= self.settings.seconds:
                    raise _Stop("time", f"{self.settings.seconds:g} s are up")
                self._step()
                # A late frame (a slow camera or computer) is not made up for with a burst.
                next_s = max(next_s + self.settings.period_s, self.clock.now())
                self.clock.sleep(max(next_s - self.clock.now(), 0.0))
        except _Stop as stop:
            self.robot.arm.stop()  # held where it is, not carried on to the last target
            self.report.stop, self.report.why = stop.stop, str(stop)
            self.progress(f"stopped: {stop}")
        except BaseException as exc:
            self.report.stop = self.report.why = why_stopped(exc)
            raise
        finally:
            self.report.seconds = self.clock.now() - began
        return self.report

    def _step(self) -> None:
        """One frame: find the block, aim the camera where it is going."""
        frame = self.robot.camera.read()
        if self.on_frame is not None:
            self.on_frame(frame)
        self._had_frame = time.perf_counter()
        joints = self.robot.arm.read_joints_deg()
        self.report.frames += 1
        found = self._find(frame.image, joints, frame.timestamp_s)
        if found is None:
            self.report.errors_px.append(None)
            self._unseen += 1
            if self._unseen >= self.settings.lost_frames:
                raise _Stop("left the view", f"left the view: the {self.color} block was not "
                            f"seen for {self._unseen} frames")
            return
        self._unseen = 0
        detection, (x, y) = found
        cu, cv = detection.centroid_px
        self.report.errors_px.append(math.hypot(cu - self.aim.centre_px[0],
                                                cv - self.aim.centre_px[1]))
        self._filter(x, y, frame.timestamp_s)
        self._command(joints, frame.timestamp_s)

    def _find(self, image: Any, joints: Sequence[float], t_s: float
              ) -> tuple[Detection, tuple[float, float]] | None:
        """The block: the biggest block-sized blob of the colour at first, then the one
        nearest where the block followed so far should be (within ``gate_mm``: another
        block of the colour is not jumped to); its centroid on the plane of the blocks'
        tops (mm). None if there is none."""
        blobs = self.locator.detector.detect(image)
        if not blobs:
            return None
        try:
            points = self.aim.cast([d.centroid_px for d in blobs], joints)
        except VisionError:
            return None
        cam = self.locator.cam2base(joints)[:3, 3]
        fx = float(self.locator.intrinsics.camera_matrix[0, 0])
        lo, hi = AREA_RANGE
        found = []
        for k, d in enumerate(blobs):
            p = points[k]
            face_px = (fx * self.settings.block_size_mm / float(np.linalg.norm(p - cam))) ** 2
            if lo * face_px <= d.area_px <= hi * face_px:
                found.append((d, (float(p[0]), float(p[1]))))
        if not found:
            return None
        if self._place is None:
            return max(found, key=lambda f: f[0].area_px)
        dt = t_s - self._seen_s
        px, py = (self._place[0] + self._velocity[0] * dt,
                  self._place[1] + self._velocity[1] * dt)
        near = min(found, key=lambda f: math.hypot(f[1][0] - px, f[1][1] - py))
        gate = GATE_MM + GATE_GROWTH_MM_S * dt
        return near if math.hypot(near[1][0] - px, near[1][1] - py) <= gate else None

    def _filter(self, x: float, y: float, t_s: float) -> None:
        """The alpha-beta filter of the block's place and velocity on the table."""
        if self._place is None:
            self._place, self._velocity, self._seen_s = (x, y), (0.0, 0.0), t_s
            return
        dt = max(t_s - self._seen_s, 1e-3)
        vx, vy = self._velocity
        px, py = self._place[0] + vx * dt, self._place[1] + vy * dt
        rx, ry = x - px, y - py
        vx, vy = vx + BETA * rx / dt, vy + BETA * ry / dt
        speed = math.hypot(vx, vy)
        if speed > MAX_BLOCK_MM_S:
            vx, vy = vx * MAX_BLOCK_MM_S / speed, vy * MAX_BLOCK_MM_S / speed
        self._place, self._velocity, self._seen_s = (px + ALPHA * rx, py + ALPHA * ry), (
            vx, vy), t_s

    def _command(self, joints: Sequence[float], frame_s: float) -> None:
        """Aim the image centre where the block will be when the move sent now ends."""
        assert self._place is not None
        move_s = self.settings.move_s
        lead_s = self.clock.now() - self._seen_s + move_s
        x, y = self._place
        vx, vy = self._velocity
        tx, ty = x + vx * lead_s, y + vy * lead_s
        try:
            here = self.aim.centre_on_plane(joints)
        except VisionError:
            here = (x, y)
        step = math.hypot(tx - here[0], ty - here[1])
        most = self.settings.max_aim_mm_s * move_s
        if step > most:  # the velocity limit: toward the target, no faster
            tx = here[0] + (tx - here[0]) * most / step
            ty = here[1] + (ty - here[1]) * most / step
        try:
            target = self._solve((tx, ty), (x, y), joints)
        except UnreachableError as exc:
            self._unreachable += 1
            if self._unreachable >= REACH_FRAMES:
                raise _Stop("left the reach", f"left the reach: the {self.color} block at "
                            f"({x:.0f}, {y:.0f}) mm is where the camera cannot be held "
                            f"over it ({exc})") from None
            return
        self._unreachable = 0
        self.robot.arm.command_joints(target, self._duration(joints, target, move_s))
        self.report.latencies_s.append(self.clock.now() - frame_s)
        self.report.compute_s.append(time.perf_counter() - self._had_frame)

    def _solve(self, aim_xy: tuple[float, float], seen_xy: tuple[float, float],
               joints: Sequence[float]) -> tuple[float, ...]:
        """Joints aiming at ``aim_xy``, else (a prediction beyond the reach) at the block
        as seen; UnreachableError if that is beyond it too."""
        try:
            return self.aim.solve(*aim_xy, joints)
        except UnreachableError:
            return self.aim.solve(*seen_xy, joints)

    def _duration(self, joints: Sequence[float], target: Sequence[float], move_s: float
                  ) -> float:
        """``move_s``, or longer if a joint would turn faster than its limit allows."""
        need = max(abs(t - c) / j.max_speed_deg_s for t, c, j in
                   zip(target, joints, self.robot.config.joints, strict=True))
        return max(move_s, math.ceil(need * 1000.0) / 1000.0)
