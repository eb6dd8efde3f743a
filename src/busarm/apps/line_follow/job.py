"""Following the taped floor loop with the wrist camera; stopping for obstacles; clearing
coloured blocks off the line.

``LineFollowJob(robot).run()`` poses the arm to look ahead and down (``look_ahead``) and
goes round, paced by the Lidar: each scan (about 10 a second, busarm.apps.navigation.sensing),
then a camera frame of the same moment, in which it

- finds the tape on the floor (``FloorCamera.find_line``) and remembers its points in the
  odometry's frame (``LineTracker``); the base is steered by the line under its centre
  (``LineController``: slides onto it, turns with it), or toward the nearest point seen
  before the line has been driven up to;
- applies the vendor's stop rule to the scan (``obstacle_ahead``) over the corridor the
  base will sweep (the chassis's width and a margin, along the remembered line ahead):
  the wheels stop, and the job waits for the way to clear (each stop is reported:
  where, what, how long), giving up after ``obstacle_wait_s`` with a NavigationError;
- locates coloured blocks on the floor (the block locator on the floor's plane, below the
  Lidar's) and, when one is on the base's path (within ``near_line_m`` of the tracked
  line: the chassis's half width, the block's and a margin) and ``CLEAR_AHEAD_M`` ahead,
  stops, turns to face it, picks it (busarm.apps.transport.mobile_pick, the base lined up to it)
  and puts it down beside the base on the side where it ends farther from the line,
  looks that it is there and off the line, looks ahead again and goes on (the
  odometry, and so the remembered line, runs on through it all).

The tape's colour is given (``tape``: black, white or a colour of the default
thresholds) or measured on the first look (busarm.vision.tape_colour: the robot starts on
the tape facing along it). The line is looked for in that colour only. But for black
tape, the flat tape is painted out of the picture the blocks are looked for in (a block
of its colour standing on it stays: ``without_tape``), and out of the pictures the pick
looks at the block in (``tape_camera``).

A line not seen for ``LOST_AFTER_S`` is searched for by turning in place (up to
``SEARCH_DEG`` each way), before anything in the way is waited for (a lost line is a
lost line, not an obstacle); not found, or no room to turn, the job stops with a
NavigationError saying the line is lost.

Laps: the start pose is remembered (odometry frame); a lap is done when the base comes
back to it (within ``LAP_RADIUS_M``, facing its way, level with it or just past it)
having driven more than ``LAP_MIN_TRAVEL_M`` since. The first lap measures the loop's
length (the base's forward travel, odometry); later shares of a lap are the distance
driven over that length.
Before the first lap is done the length is not known: the share of the first lap is
then the share of a full turn (360 deg, as a closed loop turns once) the base has turned
(``laps=0.25``: a quarter turn round the loop).

Every stop of the job, done or not, leaves the wheels stopped; ``report`` (a
``LineFollowReport``) says what happened, also when ``run`` raised.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Literal

import numpy as np
import numpy.typing as npt

from busarm.apps.line_follow.floor_look import floor_camera, look_ahead
from busarm.apps.line_follow.report import BlockCleared, LineFollowReport, ObstacleStop
from busarm.apps.line_follow.tape_camera import tape_hidden
from busarm.apps.navigation.sensing import ScanReader, SensedScan
from busarm.apps.transport.mobile_pick import FLOOR, BlockSeen, pick_block, put_aside
from busarm.apps.transport.workspace import Workspace, half_size_m, m_text
from busarm.base.kinematics import Twist
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.errors import NavigationError, UnreachableError, why_stopped
from busarm.lidar.scan import at_returns, to_points
from busarm.nav.line_track import (
    MIN_POINTS,
    LineController,
    LineTracker,
    in_stop_range,
    obstacle_ahead,
)
from busarm.nav.mapping import compose
from busarm.perception.floor_view import FloorCamera
from busarm.progress import Progress, quiet
from busarm.robot import Robot
from busarm.units import check_range
from busarm.vision.color_thresholds import ColorRange
from busarm.vision.floor_line import FloorLineSighting
from busarm.vision.tape_colour import check_tape, measure_tape, without_tape

FloatArray = npt.NDArray[np.float64]

DEFAULT_SPEED_M_S = 0.2
OBSTACLE_WAIT_S = 30.0
LOST_AFTER_S = 1.0
SEARCH_DEG = 90.0
SEARCH_RATE_RAD_S = 0.5
"""The search turns this fast (the camera's picture smears little)."""
LAP_RADIUS_M = 0.1
LAP_MIN_TRAVEL_M = 1.0
LAP_HEADING_DEG = 45.0
"""Back at the start facing its way within this (not crossing it on another leg)."""
CLEAR_AHEAD_M = 0.32
"""A block on the path is cleared once it is this close ahead of the base's centre (its
fine alignment then moves the base less than ``mobile_pick.MAX_ALIGN_M``)."""
PATH_MARGIN_M = 0.02
"""Beyond the chassis's half width and a block's half side: a block nearer the line than
that would touch the chassis as it follows the line."""
CORRIDOR_MARGIN_M = 0.03
"""Beyond the chassis's half width: what the Lidar stops the base for (a table along the
line, farther to the side, does not)."""
ASIDE_PROBE_M = (0.05, 0.22)
"""Where a block put aside lands, about (ahead, to the side) of the base: which side is
farther from the line is judged there."""
MAX_CLEARS_HERE = 3
"""Blocks cleared within ``SAME_PLACE_M`` of one place at most (then the job stops)."""
SAME_PLACE_M = 0.3
FACE_MIN_DEG = 3.0
"""A block farther than this off the base's heading is turned to before it is picked."""
TURN_CLEAR_M = 0.03
"""Turning in place, the chassis's corners keep this far from what the Lidar sees."""
ON_LINE_M = 0.02
"""The base this close to the line follows it: the Lidar checks the way along the line."""
REJOINED_M = 0.005
"""After a clearing, the base is back on the line when this close to it."""
NOT_THERE_M = 0.1
"""A block a closer look did not find is not looked for again this close to where it
seemed to be (a block on a table seen from afar on the floor's plane)."""

Side = Literal["left", "right"]


StepHook = Callable[["LineFollowJob"], None]


class LineFollowJob:
    """Follow the floor loop ``laps`` times (see the module docstring)."""

    def __init__(self, robot: Robot, *, laps: float = 1.0,
                 speed_m_s: float = DEFAULT_SPEED_M_S, colors: Sequence[str] | None = None,
                 on_step: StepHook | None = None, obstacle_wait_s: float = OBSTACLE_WAIT_S,
                 progress: Progress = quiet, tape: str | None = None) -> None:
        self.laps = check_range("laps", laps, 0.05, 100.0, "laps")
        self.tape: str | ColorRange | None = None if tape is None else check_tape(tape)
        """What the line is looked for by (None until the first look measures it)."""
        check_range("obstacle_wait_s", obstacle_wait_s, 0.0, 3600.0, "s")
        self.robot = robot
        self.reader = ScanReader(robot)
        self.base = self.reader.base
        self.clock = robot.clock
        self.controller = LineController(speed_m_s=speed_m_s)
        self.on_step = on_step
        self.obstacle_wait_s = obstacle_wait_s
        self.progress = progress
        self.tracker = LineTracker()
        self.report = LineFollowReport(self.laps, tape=tape or "")
        self.sighting: FloorLineSighting | None = None
        """The line in the last frame (None if it was not seen)."""
        half_width = half_size_m(self.base.config)[1]
        self.corridor_half_m = half_width + CORRIDOR_MARGIN_M
        # Blocks are looked for when there are colours to clear (the locator checks them).
        self.workspace = Workspace(robot, FLOOR, colors) if colors is None or colors else None
        block_half = 0.0 if self.workspace is None else self.workspace.block_mm / 2000.0
        self.near_line_m = half_width + block_half + PATH_MARGIN_M
        """A block this close to the line is in the base's way."""
        self.camera: FloorCamera | None = None
        self.odometry = Pose2D()
        """The odometry's pose at the last camera frame."""
        self.sensed: SensedScan | None = None
        self.rejoining = False
        """True from a block's clearing (the base lined up with the block, off the line)
        until the base is back on the line: its offsets meanwhile are not following's."""
        self._start = Pose2D()
        self._last: Pose2D | None = None
        self._turned_rad = 0.0
        self._lap_mark_m = 0.0
        self._laps_marked = 0
        self._seen_at_s = -math.inf
        self._not_there: list[tuple[float, float]] = []
        self._said_share = 0.0
        self._tape_said = ""

    # ------------------------------------------------------------------ the run

    def run(self) -> LineFollowReport:
        """Go round until ``laps`` are done; NavigationError (the wheels stopped, the
        report kept in ``report``) if the job cannot go on."""
        began = self.clock.now()
        try:
            self._prepare()
            self.progress("the arm looks ahead: following the line")
            if self._tape_said:
                self.progress(f"the tape: {self._tape_said}")
            while not self._done():
                self._step()
            self.report.finished = True
            self.report.why = f"{_laps_text(self.laps)} done"
        except NavigationError as exc:
            self.report.why = str(exc)
            raise
        except BaseException as exc:
            self.report.why = why_stopped(exc)  # a person's stop is a stop, not an error
            raise
        finally:
            self.base.stop()
            self.report.seconds = self.clock.now() - began
        return self.report

    def _prepare(self) -> None:
        look_ahead(self.robot)
        self.camera = floor_camera(self.robot)
        if self.tape is None:
            self._measure_tape(self.camera)
        self._start = self.base.odometry().pose
        self._seen_at_s = self.clock.now()

    def _measure_tape(self, camera: FloorCamera) -> None:
        """The tape's colour from the first look (the robot stands on it)."""
        look = measure_tape(self.robot.camera.read().image, camera.intrinsics,
                            camera.cam_to_floor, mask=camera.mask)
        if look is None:
            raise NavigationError(
                "no tape seen on the first look: the robot starts on the tape facing along "
                "it (a strip of the tape's width, at least 0.2 m of it in view); or give "
                "the tape's colour (--tape)")
        self.tape = look.colour
        self.report.tape, self.report.tape_measured = look.name, True
        self._tape_said = look.text()

    def _step(self) -> None:
        """One scan: see, check the way, steer."""
        sensed, image = self._sense()
        returns = to_points(sensed.scan, self.base.config.lidar)
        if self.on_step is not None:
            self.on_step(self)
        if self.clock.now() - self._seen_at_s > LOST_AFTER_S:
            self._search(returns)
            return
        blocked = self._in_the_way(returns)
        if blocked is not None:
            self._wait_for_way(blocked)
            return
        block = self._block_in_the_way(image)
        if block is not None:
            with tape_hidden(self.robot, self.tape):  # a block of its colour on it
                self._clear(block)
            return
        self._steer()

    def _sense(self, *, anew: bool = False) -> tuple[SensedScan, npt.NDArray[np.uint8]]:
        """The next scan, then a camera frame, the line in it remembered (``anew``: only
        line not seen before counts, as when turning at the tape's end brings the part
        already followed into view)."""
        self.sensed = self.reader.read()
        frame = self.robot.camera.read()
        image = frame.image
        self.odometry = self.base.pose_at(frame.timestamp_s)  # where the picture was taken
        self._note_motion(self.odometry)
        assert self.camera is not None and self.tape is not None
        sighting = self.sighting = self.camera.find_line(image, self.tape)
        if sighting is not None and (
                # Mostly at or behind what the Lidar sees: a wall's foot, not tape.
                np.mean(at_returns(sighting.points_m, self.sensed.scan,
                                       self.base.config.lidar)) > 0.5
                or (anew and self.tracker.unseen(sighting.points_m, self.odometry) < MIN_POINTS)):
            sighting = self.sighting = None
        if sighting is not None:
            self.tracker.add(sighting.points_m, self.odometry)
            self._seen_at_s = self.clock.now()
        return self.sensed, image

    def _steer(self) -> None:
        line = self.tracker.under(self.odometry)
        if line is not None:
            if self.rejoining and abs(line.lateral_m) < REJOINED_M:
                self.rejoining = False
            if not self.rejoining:
                self.report.lateral.append((self.report.travelled_m, line.lateral_m))
            twist = self.controller.command(line)
        else:
            nearest = self.tracker.nearest(self.odometry)
            twist = Twist() if nearest is None else self.controller.toward(nearest)
        self.base.drive(twist.vx_m_s, twist.vy_m_s, twist.wz_rad_s)

    # ------------------------------------------------------------------ laps

    def _note_motion(self, pose: Pose2D) -> None:
        r = self.report
        r.path.append(pose)
        if self._last is not None:
            # Along the line: the base's own forward travel (not the sideways slides of
            # lining up with a block and back).
            step = pose.relative_to(self._last)
            r.travelled_m += step.x_m
            self._turned_rad += step.yaw_rad
        self._last = pose
        back = pose.relative_to(self._start)
        if (r.travelled_m - self._lap_mark_m > LAP_MIN_TRAVEL_M
                and math.hypot(back.x_m, back.y_m) <= LAP_RADIUS_M and back.x_m >= 0.0
                and abs(back.yaw_deg) <= LAP_HEADING_DEG):
            if r.loop_length_m is None:
                r.loop_length_m = r.travelled_m
            self._laps_marked += 1
            self._lap_mark_m = r.travelled_m
            self.progress(f"lap {self._laps_marked} done ({r.travelled_m:.2f} m driven; the "
                          f"loop is {r.loop_length_m:.2f} m)")
        r.laps_done = self._share()
        if r.laps_done >= self._said_share + 0.25 and r.laps_done < self.laps:
            self._said_share = math.floor(r.laps_done * 4) / 4
            self.progress(f"{r.laps_done:.2f} of {_laps_text(self.laps)} "
                          f"({r.travelled_m:.2f} m driven)")

    def _share(self) -> float:
        """Laps done so far (see the module docstring)."""
        r = self.report
        if r.loop_length_m is None:  # the first lap: by the turn (never a whole one)
            return min(abs(self._turned_rad) / (2 * math.pi), 0.99)
        return self._laps_marked + (r.travelled_m - self._lap_mark_m) / r.loop_length_m

    def _done(self) -> bool:
        return self.report.laps_done >= self.laps - 1e-9

    # ------------------------------------------------------------------ obstacles

    def _wait_for_way(self, blocked: tuple[float, float]) -> None:
        """Stop, and wait until the Lidar sees the way clear; NavigationError after
        ``obstacle_wait_s``."""
        self.base.stop()
        at, began = self.odometry, self.clock.now()
        self.progress(f"stopped: something {_ahead_text(blocked)} in the way")
        while True:
            sensed = self.reader.read()
            if self.on_step is not None:
                self.on_step(self)
            waited = self.clock.now() - began
            still = self._in_the_way(to_points(sensed.scan, self.base.config.lidar))
            if still is None:
                self.report.stops.append(ObstacleStop(at, blocked, began, waited, True))
                self.progress(f"the way is clear after {waited:.1f} s: going on")
                self._seen_at_s = self.clock.now()  # (not lost for having waited)
                return
            if waited > self.obstacle_wait_s:
                self.report.stops.append(ObstacleStop(at, blocked, began, waited, False))
                raise NavigationError(
                    f"something {_ahead_text(still)} stayed in the base's way for "
                    f"{self.obstacle_wait_s:g} s (at {m_text((at.x_m, at.y_m))} of the "
                    "odometry): the base is stopped")

    def _in_the_way(self, returns: FloatArray) -> tuple[float, float] | None:
        """The vendor's stop rule (``obstacle_ahead``) over the corridor the base will
        sweep: along the line ahead when the base is on it (a box beside the outside of
        a bend is not in the way), else straight ahead."""
        line = self.tracker.under(self.odometry)
        points = self.tracker.points(self.odometry)
        ahead = points[points[:, 0] > 0.0]
        if line is None or abs(line.lateral_m) > ON_LINE_M or not len(ahead) \
                or not len(returns):
            return obstacle_ahead(returns, corridor_half_m=self.corridor_half_m)
        returns = returns[in_stop_range(returns)]  # the only ones the rule may stop for
        gaps = np.hypot(returns[:, None, 0] - ahead[None, :, 0],
                        returns[:, None, 1] - ahead[None, :, 1]).min(axis=1)
        return obstacle_ahead(returns[gaps <= self.corridor_half_m],
                              corridor_half_m=math.inf)

    # ------------------------------------------------------------------ blocks

    def _block_in_the_way(self, image: npt.NDArray[np.uint8]) -> BlockSeen | None:
        """The nearest block of the colours seen in ``image`` on the base's path and
        ahead within ``CLEAR_AHEAD_M``, or None."""
        ws = self.workspace
        if ws is None:
            return None
        assert self.camera is not None
        line = self.tracker.points(self.odometry)
        if not len(line):
            return None
        if self.tape != "black" and self.sighting is not None:  # (see tape_camera)
            cam = self.camera
            image = without_tape(image, self.sighting, cam.intrinsics, cam.cam_to_floor,
                                 cam.mask)
        found = []
        for sighting in ws.locator.locate(image, self.camera.joints_deg):
            block = ws.seen(sighting, image)
            # Near enough to line up with (a block far off to the side of a bend is
            # cleared once the line has brought the base near it).
            if block.x_m <= 0.0 or math.hypot(block.x_m, block.y_m) > CLEAR_AHEAD_M:
                continue
            if _distance_m(line, (block.x_m, block.y_m)) > self.near_line_m:
                continue
            here = self._to_odometry((block.x_m, block.y_m))
            if any(math.dist(here, p) < NOT_THERE_M for p in self._not_there):
                continue
            found.append(block)
        return min(found, key=lambda b: b.x_m) if found else None

    def _clear(self, block: BlockSeen) -> None:
        """Pick ``block`` off the path, put it aside, look ahead again."""
        self.base.stop()
        began = self.clock.now()
        found = self._to_odometry((block.x_m, block.y_m))
        if sum(math.dist(found, b.found_m) < SAME_PLACE_M for b in self.report.blocks) \
                >= MAX_CLEARS_HERE:
            raise NavigationError(
                f"a {block.color} block is on the line at {m_text((block.x_m, block.y_m))} "
                f"again after {MAX_CLEARS_HERE} clearings here: the base is stopped")
        self.progress(f"a {block.color} block on the line {_ahead_text((block.x_m, block.y_m))}"
                      ": clearing it")
        # Seen from where the base stopped, not where the picture was taken: on the wall
        # clock it drove on while the picture was looked at (a busy computer's tenths of
        # a second: centimetres the pick's closer look then misses the block by).
        self.base.wait_stopped()
        block = _seen_after(block, self.base.odometry().pose.relative_to(self.odometry))
        try:
            picked = pick_block(self.robot, FLOOR, self._face(block))
        except UnreachableError as exc:
            raise NavigationError(
                f"a {block.color} block lies on the line {_ahead_text((block.x_m, block.y_m))}"
                f" and the arm cannot clear it: {exc}; the base is stopped") from exc
        if not picked.ok:
            self._not_picked(block, found, picked.why, picked.attempts, began)
            return
        side = self._aside_side()
        placed = put_aside(self.robot, FLOOR, side)
        self.odometry = self.base.odometry().pose
        put = None if placed.where_m is None else self._to_odometry(placed.where_m)
        why = placed.why
        line = self.tracker.points(self.odometry)
        if placed.ok and placed.where_m is not None and len(line):
            off = _distance_m(line, placed.where_m)
            if off <= self.near_line_m:
                why = (f"put down {off:.2f} m from the line, within the base's path "
                       f"({self.near_line_m:.2f} m)")
        cleared = BlockCleared(block.color, found, put,
                               "cleared" if placed.ok and not why else "failed", why, side,
                               picked.attempts, self.clock.now() - began)
        self.report.blocks.append(cleared)
        self.progress(f"{block.color} block " + (f"cleared: put {side} of the line"
                                                 if cleared.ok else f"not cleared: {why}"))
        self._look_ahead_again()

    def _face(self, block: BlockSeen) -> BlockSeen:
        """Turn the base in place to face ``block`` (then the pick's alignment slides it
        straight ahead, the way it was going, not sideways toward what stands beside the
        line); not if the Lidar sees something within the chassis's turning circle.
        The block as seen from the turned base."""
        bearing = math.atan2(block.y_m, block.x_m)
        if abs(bearing) < math.radians(FACE_MIN_DEG):
            return block
        returns = to_points(self.reader.read().scan, self.base.config.lidar)
        turning_m = math.hypot(*half_size_m(self.base.config)) + TURN_CLEAR_M
        if len(returns) and float(np.min(np.hypot(returns[:, 0], returns[:, 1]))) < turning_m:
            return block
        return _seen_after(block, self.base.move_by(0.0, 0.0, bearing))

    def _not_picked(self, block: BlockSeen, found: tuple[float, float], why: str,
                    attempts: int, began: float) -> None:
        not_there = attempts == 0 and "no longer near" in why
        self.report.blocks.append(BlockCleared(block.color, found, None,
                                               "not there" if not_there else "failed", why,
                                               attempts=attempts,
                                               seconds=self.clock.now() - began))
        if not_there:
            # Not on the floor where the look ahead put it (on a table seen from afar):
            # not looked for there again.
            self._not_there.append(found)
            self.progress(f"the {block.color} block is not on the floor there: going on")
            self._look_ahead_again()
            return
        raise NavigationError(f"a {block.color} block on the line "
                              f"{_ahead_text((block.x_m, block.y_m))} could not be picked: "
                              f"{why}; the base is stopped")

    def _aside_side(self) -> Side:
        """The side of the base where a block put down is farther from the line (on a
        tie, the outside of the line's bend)."""
        pose = self.base.odometry().pose
        line = self.tracker.points(pose)
        if not len(line):
            return "right"
        x, y = ASIDE_PROBE_M
        left, right = _distance_m(line, (x, y)), _distance_m(line, (x, -y))
        if abs(left - right) > 0.02:
            return "left" if left > right else "right"
        under = self.tracker.under(pose)
        bend = 0.0 if under is None else under.curvature_1_m
        return "right" if bend > 0 else "left"

    def _look_ahead_again(self) -> None:
        look_ahead(self.robot)
        self.camera = floor_camera(self.robot)
        self.odometry = self.base.odometry().pose
        self.rejoining = True
        self._seen_at_s = self.clock.now()

    # ------------------------------------------------------------------ lost

    def _search(self, returns: FloatArray) -> None:
        """Turn in place up to ``SEARCH_DEG`` each way until the line is seen;
        NavigationError if it is not, or if the Lidar sees something within the chassis's
        turning circle (``returns``: this scan's, base frame)."""
        self.base.stop()
        self.report.searches += 1
        lost_s = self.clock.now() - self._seen_at_s
        start = self.odometry
        turning_m = math.hypot(*half_size_m(self.base.config)) + TURN_CLEAR_M
        near = returns[np.hypot(returns[:, 0], returns[:, 1]) < turning_m] if len(returns) \
            else returns
        if len(near):
            nearest = near[int(np.argmin(np.hypot(near[:, 0], near[:, 1])))]
            raise NavigationError(
                f"the line is lost: not seen for {lost_s:.1f} s at "
                f"{m_text((start.x_m, start.y_m))} of the odometry, and something "
                f"{_ahead_text((float(nearest[0]), float(nearest[1])))} leaves no room to "
                "turn and look for it; the base is stopped")
        self.progress(f"the line is lost (not seen for {lost_s:.1f} s): looking for it")
        limit = math.radians(SEARCH_DEG)
        for direction in (1.0, -1.0):
            while True:
                seen_before = self._seen_at_s
                self._sense(anew=True)
                if self._seen_at_s > seen_before:
                    self.base.stop()
                    self.progress("the line is found again: going on")
                    return
                turned = wrap_rad(self.odometry.yaw_rad - start.yaw_rad)
                if direction * turned >= limit:
                    break
                self.base.drive(0.0, 0.0, direction * SEARCH_RATE_RAD_S)
        self.base.stop()
        raise NavigationError(
            f"the line is lost: not seen for {lost_s:.1f} s, nor turning {SEARCH_DEG:g} deg "
            f"each way at {m_text((start.x_m, start.y_m))} of the odometry; the base is "
            "stopped")

    # ------------------------------------------------------------------ frames

    def _to_odometry(self, xy_base_m: tuple[float, float]) -> tuple[float, float]:
        p = compose(self.odometry, Pose2D(xy_base_m[0], xy_base_m[1], 0.0))
        return p.x_m, p.y_m


def _seen_after(block: BlockSeen, moved: Pose2D) -> BlockSeen:
    """``block`` as seen from the base after it ``moved`` (in the frame it had)."""
    seen = Pose2D(block.x_m, block.y_m, math.radians(block.yaw_deg)).relative_to(moved)
    return replace(block, x_m=seen.x_m, y_m=seen.y_m,
                   yaw_deg=(seen.yaw_deg + 45.0) % 90.0 - 45.0)


def _distance_m(points: FloatArray, xy: tuple[float, float]) -> float:
    """From ``xy`` to the nearest of ``points`` (the line's, a centimetre apart)."""
    return float(np.min(np.hypot(points[:, 0] - xy[0], points[:, 1] - xy[1])))


def _ahead_text(xy: tuple[float, float]) -> str:
    return f"{xy[0]:.2f} m ahead, {abs(xy[1]):.2f} m {'left' if xy[1] >= 0 else 'right'}"


def _laps_text(laps: float) -> str:
    return f"{laps:g} lap" + ("" if laps == 1 else "s")


__all__ = ["BlockCleared", "LineFollowJob", "LineFollowReport", "ObstacleStop"]
