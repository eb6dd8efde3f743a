"""The robot's channels for Foxglove: what it senses, read while it runs, and what a job
knows, handed in by the job's caller.

``RobotView(robot).start()`` reads the robot in threads of its own and logs each value on
a channel of its ``context``: a Foxglove WebSocket server (busarm.view.server) and an
MCAP recording (busarm.view.recording) attached to that context get every message. A
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
so that a recording replays at the robot's pace.
"""

from __future__ import annotations

import json
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
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
    "GRIPPER_JOINT",
    "MAP_FRAME",
    "SCAN_IDLE_S",
    "TOPICS",
    "RobotView",
    "ViewSettings",
]


log = logging.getLogger(__name__)

MAP_FRAME = "map"
GRIPPER_JOINT = "gripper"
BLOCKS_HZ = 3.0
SCAN_IDLE_S = 0.5
"""The view reads the Lidar itself only when no job has for this long."""
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


class RobotView:
    """``robot``'s channels on ``context`` (a new one by default); ``start()``,
    ``close()``. The ``show_*`` calls are for a job's caller, from any thread."""

    def __init__(self, robot: Robot, settings: ViewSettings | None = None,
                 context: foxglove.Context | None = None) -> None:
        self.robot = robot
        self.settings = settings or ViewSettings()
        self.context = context or foxglove.Context()
        self.camera = robot.has_camera and self.settings.camera
        self.errors: list[str] = []
        self.counts: dict[str, int] = {}
        """Messages logged on each topic (for a recording's summary)."""
        self.started = False
        self._closed = threading.Event()
        self._threads: list[threading.Thread] = []
        self._lock = threading.Lock()
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
        ctx = self.context
        self.tf = FrameTransformsChannel("/tf", context=ctx)
        self.joints = JointStatesChannel("/joint_states", context=ctx)
        self.description = foxglove.Channel("/robot_description", schema=STRING_SCHEMA,
                                            message_encoding="json", context=ctx)
        self.image = (CompressedImageChannel("/wrist_camera/compressed", context=ctx)
                      if self.camera else None)
        calibrated = self.camera and robot.camera_calibration is not None
        self.calibration = (CameraCalibrationChannel("/wrist_camera/calibration", context=ctx)
                            if calibrated else None)
        self.blocks = (SceneUpdateChannel("/blocks", context=ctx)
                       if calibrated and self.settings.blocks else None)
        self.scan = LaserScanChannel("/scan", context=ctx) if robot.lidar is not None else None
        self.map = GridChannel("/map", context=ctx)
        self.path = SceneUpdateChannel("/path", context=ctx)
        self.urdf = urdf_from_config(robot.config)
        self._state = StateReader(robot.arm)

    # ------------------------------------------------------------------ lifecycle

    @property
    def topics(self) -> list[str]:
        """The topics this robot's view has."""
        channels: list[Any] = [self.tf, self.joints, self.description, self.image,
                               self.calibration, self.blocks, self.scan, self.map, self.path]
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

    def _guard(self, loop: Callable[[], None]) -> Callable[[], None]:
        def run() -> None:
            try:
                loop()
            except Exception as exc:  # a loop that dies says so: the view is incomplete
                self.errors.append(f"{type(exc).__name__}: {exc}")
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

    def _log(self, channel: Any, message: Any, t_s: float) -> None:
        channel.log(message, log_time=round(t_s * 1e9))
        topic = channel.topic()
        with self._lock:
            self.counts[topic] = self.counts.get(topic, 0) + 1

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

    def publish_latched(self) -> None:
        """The values a late subscriber needs at once: the URDF, and the map and the
        job's path when there are."""
        t = self.now_s()
        self._log(self.description, {"data": self.urdf}, t)
        if self._map is not None:
            self._log(self.map, fm.map_grid(t, self._map, MAP_FRAME), t)
        if self._path is not None:
            self._log(self.path, fm.path_scene(t, *self._path), t)

    # ------------------------------------------------------------------ loops

    def _state_loop(self) -> None:
        tick = self._every(1.0 / self.settings.state_hz)
        while tick():
            self._publish_state()

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
        try:
            reading = self._state.read()
        except BusArmError as exc:
            log.warning("joint states not read: %s", exc)
            return
        t = self.now_s()
        gap_m = self.robot.config.gripper.gap_mm_at(reading.gripper_pulses) / 1000.0
        self._log(self.tf, fm.frame_transforms(t, self.frames(reading.joints_deg)), t)
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
        try:
            while tick():
                if not (self.image.has_sinks() or (
                        self.blocks is not None and self.blocks.has_sinks())):
                    continue  # nobody watches: nothing rendered
                frame = source.read()
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
        while tick():
            latest = self._latest
            if latest is None or latest[2] == seen or not self.blocks.has_sinks():
                continue
            image, joints, seen = latest
            self._log(self.blocks, fm.block_scene(seen, locator.locate(image, joints)), seen)

    def _on_scan(self, scan: LaserScan) -> None:
        """Each revolution anyone reads (in the reader's thread: kept short)."""
        if self.scan is not None and self.scan.has_sinks() and not self._closed.is_set():
            t = self.now_s()
            self._log(self.scan, fm.laser_scan(t, scan, LASER_FRAME), t)

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
                log.warning("no scan: %s", exc)
                self._closed.wait(0.5)
