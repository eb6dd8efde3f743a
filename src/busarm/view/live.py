"""The robot's channels for Foxglove: what it senses, read while it runs, and what a job
knows, handed in by the job's caller.

``RobotView(robot).start()`` reads the robot in threads of its own and logs each value on
its channels: a Foxglove WebSocket server (busarm.view.server) and an MCAP recording
(busarm.view.recording) attached to the view get every message. A
channel nobody watches costs nothing: the camera is not rendered, the blocks are not
located, and the Lidar is not read for it.

=============================== ============================ ===========================
topic                           schema                       when
=============================== ============================ ===========================
/tf                             foxglove.FrameTransforms     ``state_hz``: the URDF's
                                                             links for the joints read,
                                                             the camera on its link;
                                                             odom -> base_footprint and
                                                             the mounts on a mobile
                                                             robot; map -> odom once a
                                                             job has localised
/joint_states                   foxglove.JointStates         with /tf: each joint (rad),
                                                             ``gripper`` (its gap, m)
/robot_description              std_msgs/msg/String (JSON)   at start and to each new
                                                             subscriber: the URDF
/wrist_camera/compressed        foxglove.CompressedImage     ``camera_fps`` (JPEG)
/wrist_camera/calibration       foxglove.CameraCalibration   with each frame, when the
                                                             camera is calibrated
/blocks                         foxglove.SceneUpdate         ``BLOCKS_HZ``: the blocks
                                                             the wrist camera sees, as
                                                             cubes in ``base_link``
/scan                           foxglove.LaserScan           every revolution anyone
                                                             reads (a job's), or read
                                                             when no job reads
/map                            foxglove.Grid                when given (``show_map``),
                                                             and to each new subscriber
/path                           foxglove.SceneUpdate         when a job says
                                                             (``show_path``): the plan,
                                                             the path driven, its points
=============================== ============================ ===========================

Stamps are seconds since the epoch: the wall clock's on hardware and on a twin in real
time; on a twin in simulated time, the start's wall time plus the robot's clock since,
so that a recording replays at the robot's pace. A scan is stamped when its revolution
began (the Lidar's own stamp, on the robot's clock), not when the view got it.

Two contexts: servers attach to ``live_context``, recordings to ``record_context``; each
message goes to both, but what a new subscriber is sent again (the URDF, the map, the
path) goes to the live one only, so a recording holds each once however many watch.

The view only watches: an error of its own (a read that failed, a sink that refused a
message) is noted once in ``errors`` and skips that tick; it never reaches a job whose
hooks feed it. A loop that fails for ``GIVE_UP_S`` on end stops, and ``failure`` says why.
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import foxglove
from foxglove.channels import (
    CameraCalibrationChannel,
    CompressedImageChannel,
    FrameTransformsChannel,
    GridChannel,
    JointStatesChannel,
    LaserScanChannel,
    SceneUpdateChannel,
)

from busarm.arm.urdf import urdf_from_config
from busarm.base.odometry import Pose2D
from busarm.clock import SimClock
from busarm.errors import BusArmError
from busarm.lidar.scan import LaserScan
from busarm.lidar.tap import ScanTap
from busarm.nav.grid import OccupancyGrid
from busarm.nav.mapping import compose, inverse
from busarm.perception.locate import Sighting
from busarm.robot import Robot
from busarm.robot.frames import (
    CAMERA_FRAME,
    LASER_FRAME,
    ODOM_FRAME,
    Frame,
    arm_frames,
    base_frames,
    planar,
)
from busarm.robot.state import StateReader
from busarm.view import messages as fm

__all__ = [
    "BLOCKS_HZ",
    "GIVE_UP_S",
    "GRIPPER_JOINT",
    "MAP_FRAME",
    "MAX_ERRORS",
    "SCAN_IDLE_S",
    "TOPICS",
    "RobotView",
    "Topic",
    "ViewSettings",
]


log = logging.getLogger(__name__)

MAP_FRAME = "map"
GRIPPER_JOINT = "gripper"
BLOCKS_HZ = 3.0
SCAN_IDLE_S = 0.5
"""The view reads the Lidar itself only when no job has for this long."""
GIVE_UP_S = 5.0
"""A loop whose every tick failed for this long (the robot gone) stops."""
MAX_ERRORS = 20
"""Distinct errors kept (and logged); more are counted only."""
MAX_SCAN_AGE_S = 5.0
"""A scan stamped longer ago than this (or in the future) is stamped when it came."""
STRING_SCHEMA = foxglove.Schema(
    name="std_msgs/msg/String", encoding="jsonschema",
    data=json.dumps({"type": "object", "properties": {"data": {"type": "string"}}}).encode())
"""The URDF's message: ROS's String, which Foxglove's 3D panel loads a robot from."""

TOPICS = ("/tf", "/joint_states", "/robot_description", "/wrist_camera/compressed",
          "/wrist_camera/calibration", "/blocks", "/scan", "/map", "/path")
"""Every topic the view may have (a robot without a camera or a Lidar has fewer)."""


@dataclass(frozen=True)
class ViewSettings:
    state_hz: float = 30.0
    """/tf and /joint_states a second."""
    camera_fps: float = 10.0
    jpeg_quality: int = 80
    camera: bool = True
    """Publish the wrist camera (and the blocks it sees), if the robot has one."""
    blocks: bool = True
    """Locate the blocks in the wrist camera's pictures (needs its calibration)."""
    map_grid: OccupancyGrid | None = None
    """A saved map to show on /map from the start."""


class Topic:
    """One topic's channel on the live context (servers) and on the recording one."""

    def __init__(self, make: Callable[..., Any], topic: str, live: foxglove.Context,
                 record: foxglove.Context) -> None:
        self.name = topic
        self.live = make(topic, context=live)
        self.record = make(topic, context=record)

    def topic(self) -> str:
        return self.name

    def has_sinks(self) -> bool:
        """Whether anyone takes its messages (a client subscribed, a recording)."""
        return bool(self.live.has_sinks() or self.record.has_sinks())


class _Streak:
    """A loop's failed ticks in a row: each error noted (once), the last raised when
    nothing but failures came for GIVE_UP_S."""

    def __init__(self, view: RobotView, what: str) -> None:
        self.view, self.what = view, what
        self.since: float | None = None

    def ok(self) -> None:
        self.since = None

    def failed(self, exc: BusArmError) -> None:
        self.view.note(f"{self.what}: {exc}")
        now = time.monotonic()
        if self.since is None:
            self.since = now
        elif now - self.since > GIVE_UP_S:
            raise exc


class RobotView:
    """``robot``'s channels; ``start()``, ``close()``. The ``show_*`` calls are for a
    job's caller, from any thread."""

    def __init__(self, robot: Robot, settings: ViewSettings | None = None) -> None:
        self.robot = robot
        self.settings = settings or ViewSettings()
        self.live_context = foxglove.Context()
        """Where servers attach (busarm.view.server)."""
        self.record_context = foxglove.Context()
        """Where recordings attach (busarm.view.recording)."""
        self.camera = robot.has_camera and self.settings.camera
        self.errors: list[str] = []
        """Each distinct problem the view met, once (it went on)."""
        self.failure: str | None = None
        """Why a loop of the view stopped (None while they all run)."""
        self.counts: dict[str, int] = {}
        """Messages recorded on each topic (a recording's summary)."""
        self.started = False
        self._closed = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()
        self._more_errors = 0
        self._map: OccupancyGrid | None = self.settings.map_grid
        self._path: tuple[str, Sequence[fm.Point2], Sequence[fm.Point2],
                          dict[str, fm.Point2]] | None = None
        self._map_to_odom: Frame | None = None
        self._latest: tuple[Any, tuple[float, ...], float] | None = None
        self._joints_deg: tuple[float, ...] | None = None
        self._stop_listening: Callable[[], None] | None = None
        self._clock_origin = (time.time(), robot.clock.now())
        self.simulated = isinstance(robot.clock, SimClock)
        """A twin on simulated time: stamps follow its clock, and the view never reads
        the Lidar itself (a read would move the job's time)."""
        self.joint_names = [j.name for j in robot.config.joints]
        calibrated = self.camera and robot.camera_calibration is not None
        topic = partial(Topic, live=self.live_context, record=self.record_context)
        self.tf = topic(FrameTransformsChannel, "/tf")
        self.joints = topic(JointStatesChannel, "/joint_states")
        self.description = topic(partial(foxglove.Channel, schema=STRING_SCHEMA,
                                         message_encoding="json"), "/robot_description")
        self.image = (topic(CompressedImageChannel, "/wrist_camera/compressed")
                      if self.camera else None)
        self.calibration = (topic(CameraCalibrationChannel, "/wrist_camera/calibration")
                            if calibrated else None)
        self.blocks = (topic(SceneUpdateChannel, "/blocks")
                       if calibrated and self.settings.blocks else None)
        self.scan = topic(LaserScanChannel, "/scan") if robot.lidar is not None else None
        self.map = topic(GridChannel, "/map")
        self.path = topic(SceneUpdateChannel, "/path")
        self.urdf = urdf_from_config(robot.config)
        self._state = StateReader(robot.arm)

    # ------------------------------------------------------------------ lifecycle

    @property
    def topics(self) -> list[str]:
        """The topics this robot's view has."""
        channels = [self.tf, self.joints, self.description, self.image, self.calibration,
                    self.blocks, self.scan, self.map, self.path]
        return [c.topic() for c in channels if c is not None]

    def start(self) -> RobotView:
        loops: list[tuple[str, Callable[[], None]]] = [("state", self._state_loop)]
        if self.image is not None:
            loops.append(("camera", self._camera_loop))
        if self.blocks is not None:
            loops.append(("blocks", self._blocks_loop))
        lidar = self.robot.lidar
        if isinstance(lidar, ScanTap):
            self._stop_listening = lidar.listen(self._on_scan)
            if not self.simulated:
                loops.append(("scan", self._scan_loop))
        self.started = True
        self.publish_latched()
        for name, loop in loops:
            thread = threading.Thread(target=self._guard(loop), name=f"busarm-view-{name}",
                                      daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def close(self) -> None:
        """Stop reading the robot (what was logged stays logged); the robot is left as it
        is: the view never moves it."""
        self._closed.set()
        if self._stop_listening is not None:
            self._stop_listening()
        for thread in self._threads:
            thread.join(timeout=5.0)
        self._threads.clear()

    def __enter__(self) -> RobotView:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def note(self, error: str) -> None:
        """Keep ``error`` in ``errors`` and log it, the first time only."""
        with self._lock:
            if error in self.errors:
                return
            if len(self.errors) >= MAX_ERRORS:
                self._more_errors += 1
                return
            self.errors.append(error)
        log.info("the view: %s", error)  # the command says it (busarm.cli.job_view)

    def _guard(self, loop: Callable[[], None]) -> Callable[[], None]:
        def run() -> None:
            try:
                loop()
            except Exception as exc:  # a loop that dies says so: the view is incomplete
                self.failure = f"{type(exc).__name__}: {exc}"
                self.note(self.failure)
                if not isinstance(exc, BusArmError):  # a bug: its traceback helps
                    log.exception("the view stopped publishing")
        return run

    def _every(self, period_s: float) -> Callable[[], bool]:
        """A ticker: each call waits for the next period; False once the view closes."""
        next_at = [time.monotonic()]

        def tick() -> bool:
            next_at[0] += period_s
            delay = next_at[0] - time.monotonic()
            if delay < -3 * period_s:  # far behind (a busy CPU): on from now, no burst
                next_at[0] = time.monotonic()
            return not self._closed.wait(max(0.0, delay))
        return tick

    def now_s(self) -> float:
        """The stamp for a message now, in seconds since the epoch."""
        wall0, clock0 = self._clock_origin
        return wall0 + self.robot.clock.now() - clock0 if self.simulated else time.time()

    def stamp_at(self, clock_s: float) -> float:
        """The stamp of the moment ``clock_s`` of the robot's clock (a sensor's own
        time) on the view's timeline; now's if it is not a recent past one."""
        age_s = self.robot.clock.now() - clock_s
        now = self.now_s()
        return now - age_s if 0.0 <= age_s <= MAX_SCAN_AGE_S else now

    def _log(self, topic: Topic, message: Any, t_s: float, *, live: bool = True,
             record: bool = True) -> None:
        log_time = round(t_s * 1e9)
        if live and topic.live.has_sinks():
            topic.live.log(message, log_time=log_time)
        if record and topic.record.has_sinks():
            topic.record.log(message, log_time=log_time)
            with self._lock:
                self.counts[topic.name] = self.counts.get(topic.name, 0) + 1

    # ------------------------------------------------------------------ a job's values

    def show_map(self, grid: OccupancyGrid) -> None:
        """Show ``grid`` on /map (in the ``map`` frame), now and to every later subscriber."""
        self._map = grid
        t = self.now_s()
        self._log(self.map, fm.map_grid(t, grid, MAP_FRAME), t)

    def show_path(self, planned: Sequence[fm.Point2] = (), driven: Sequence[fm.Point2] = (),
                  marks: dict[str, fm.Point2] | None = None, frame_id: str = MAP_FRAME
                  ) -> None:
        """Draw a job's plan, the path it drove and its named marks (m, in ``frame_id``:
        ``map``, or ``odom`` for a job that has no map) on /path."""
        self._path = (frame_id, list(planned), list(driven), dict(marks or {}))
        t = self.now_s()
        self._log(self.path, fm.path_scene(t, *self._path), t)

    def show_blocks(self, sightings: Sequence[Sighting]) -> None:
        """Draw blocks a job found (in ``base_link``, the arm's frame) on /blocks."""
        if self.blocks is not None:
            t = self.now_s()
            self._log(self.blocks, fm.block_scene(t, sightings), t)

    def show_pose_on_map(self, on_map: Pose2D, odometry: Pose2D) -> None:
        """Where a job's localisation puts the base on the map (``on_map``) when the
        odometry said ``odometry``: /tf's map -> odom from then on."""
        offset = compose(on_map, inverse(odometry))
        self._map_to_odom = (MAP_FRAME, ODOM_FRAME, planar(offset.x_m, offset.y_m, 0.0,
                                                           offset.yaw_rad))

    def publish_latched(self, *, live: bool = True, record: bool = True) -> None:
        """The values a late subscriber needs at once: the URDF, and the map and the
        job's path when there are; to the servers (``live``), the recordings
        (``record``) or both."""
        t = self.now_s()
        self._log(self.description, {"data": self.urdf}, t, live=live, record=record)
        if self._map is not None:
            self._log(self.map, fm.map_grid(t, self._map, MAP_FRAME), t, live=live,
                      record=record)
        if self._path is not None:
            self._log(self.path, fm.path_scene(t, *self._path), t, live=live, record=record)

    # ------------------------------------------------------------------ loops

    def _state_loop(self) -> None:
        tick = self._every(1.0 / self.settings.state_hz)
        streak = _Streak(self, "joint states or odometry not read")
        while tick():
            try:  # one failed read skips this tick; the next may do
                self._publish_state()
            except BusArmError as exc:
                streak.failed(exc)
            else:
                streak.ok()

    def frames(self, joints_deg: Sequence[float]) -> list[Frame]:
        """The transforms of /tf for these joint angles (and the base's odometry now)."""
        robot = self.robot
        cal = robot.camera_calibration
        frames = arm_frames(robot.config, robot.arm.kin, joints_deg,
                            cal.hand_eye.cam2link if cal is not None else None)
        base = robot.base
        if base is not None:
            frames += base_frames(base.odometry().pose, base.config.arm, base.config.lidar)
            if self._map_to_odom is not None:
                frames.append(self._map_to_odom)
        return frames

    def _publish_state(self) -> None:
        reading = self._state.read()
        frames = self.frames(reading.joints_deg)
        t = self.now_s()
        gap_m = self.robot.config.gripper.gap_mm_at(reading.gripper_pulses) / 1000.0
        self._log(self.tf, fm.frame_transforms(t, frames), t)
        self._log(self.joints, fm.joint_states(
            t, [*self.joint_names, GRIPPER_JOINT],
            [*(math.radians(v) for v in reading.joints_deg), gap_m]), t)
        self._joints_deg = reading.joints_deg

    def _camera_loop(self) -> None:
        import cv2

        assert self.image is not None
        sim = self.robot.sim
        # A twin's camera for people is rendered as the dashboard's is (no shadows nor
        # antialiasing: several times cheaper); the job's pictures keep them.
        source = sim.live_camera("arm") if sim is not None else self.robot.camera
        cal = self.robot.camera_calibration
        tick = self._every(1.0 / self.settings.camera_fps)
        streak = _Streak(self, "no camera frame")
        try:
            while tick():
                if not (self.image.has_sinks() or (
                        self.blocks is not None and self.blocks.has_sinks())):
                    continue  # nobody watches: nothing rendered
                try:
                    frame = source.read()
                except BusArmError as exc:
                    streak.failed(exc)
                    continue
                streak.ok()
                t = self.now_s()
                joints = self._joints_deg
                if joints is not None:
                    self._latest = (frame.image, joints, t)
                ok, jpeg = cv2.imencode(".jpg", frame.image,
                                        [cv2.IMWRITE_JPEG_QUALITY, self.settings.jpeg_quality])
                if ok:
                    self._log(self.image, fm.compressed_jpeg(t, CAMERA_FRAME, jpeg.tobytes()), t)
                if self.calibration is not None and cal is not None:
                    self._log(self.calibration,
                              fm.camera_calibration(t, CAMERA_FRAME, cal.intrinsics), t)
        finally:
            if sim is not None:
                sim.release_renderers()  # this thread's, made for its pictures

    def _blocks_loop(self) -> None:
        """The blocks in the latest frame, BLOCKS_HZ times a second, while watched (in a
        thread of its own: locating them must not slow the camera down)."""
        assert self.blocks is not None
        locator = self.robot.locator()
        tick = self._every(1.0 / BLOCKS_HZ)
        seen: float | None = None
        streak = _Streak(self, "blocks not located")
        while tick():
            latest = self._latest
            if latest is None or latest[2] == seen or not self.blocks.has_sinks():
                continue
            image, joints, seen = latest
            try:
                sightings = locator.locate(image, joints)
            except BusArmError as exc:
                streak.failed(exc)
                continue
            streak.ok()
            self._log(self.blocks, fm.block_scene(seen, sightings), seen)

    def _on_scan(self, scan: LaserScan) -> None:
        """Each revolution anyone reads (in the reader's thread, a job's: kept short,
        and nothing of the view's raises into it)."""
        if self.scan is None or self._closed.is_set():
            return
        try:
            if not self.scan.has_sinks():
                return
            t = self.stamp_at(scan.stamp_s)
            self._log(self.scan, fm.laser_scan(t, scan, LASER_FRAME), t)
        except Exception as exc:  # the view only watches: never the job's error
            self.note(f"a scan not shown: {type(exc).__name__}: {exc}")

    def _scan_loop(self) -> None:
        """Reads a revolution only while no job does (its scans come through
        ``_on_scan``), and only while someone watches."""
        lidar = self.robot.lidar
        assert isinstance(lidar, ScanTap) and self.scan is not None
        while not self._closed.wait(0.05):
            if not self.scan.has_sinks():
                continue
            try:
                lidar.read_when_idle(SCAN_IDLE_S, timeout_s=1.0)
            except BusArmError as exc:
                self.note(f"no scan: {exc}")
                self._closed.wait(0.5)
