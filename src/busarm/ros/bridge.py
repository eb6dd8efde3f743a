"""The robot as ROS 2 sees it: rmw_zenoh topics out, commands in, on one Zenoh session.

Published (``ros2 topic list`` shows them; stamps are the wall clock's, as ROS has them):

=========================== ================================= ============================
topic                       type                              when
=========================== ================================= ============================
/joint_states               sensor_msgs/JointState            ``state_hz`` (60): the five
                                                              URDF joints (rad) and
                                                              ``gripper`` (its gap, m)
/tf                         tf2_msgs/TFMessage                with each joint state
/robot_description          std_msgs/String (latched)         every ``DESCRIBE_EVERY_S``
/diagnostics                diagnostic_msgs/DiagnosticArray   1 Hz: each servo's
                                                              temperature, voltage, alarms
/wrist_camera/image_raw     sensor_msgs/Image (bgr8)          ``camera_fps`` (15)
/wrist_camera/image_raw/    sensor_msgs/CompressedImage       with each frame
compressed
/wrist_camera/camera_info   sensor_msgs/CameraInfo            with each frame, when the
                                                              camera is calibrated
/blocks                     visualization_msgs/MarkerArray    ``BLOCKS_HZ`` (3), when the
                                                              camera is calibrated
/odom                       nav_msgs/Odometry                 with each joint state, on a
                                                              mobile robot
/scan                       sensor_msgs/LaserScan             each revolution, with a Lidar
/map                        nav_msgs/OccupancyGrid (latched)  a saved map, when given
=========================== ================================= ============================

Taken in (busarm.ros.commands says how each is checked and stopped): /joint_trajectory,
/cmd_vel, /gripper/command, /estop, /rearm. Closing the bridge stops the robot.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from busarm.arm.urdf import urdf_from_config
from busarm.bus.driver import ServoBus
from busarm.errors import BusArmError, ConfigError, HaltedError
from busarm.nav.grid import OccupancyGrid
from busarm.protocol.rmw_zenoh import LATCHED, SENSOR_DATA
from busarm.robot import Robot
from busarm.robot.frames import (
    CAMERA_FRAME,
    FOOTPRINT_FRAME,
    LASER_FRAME,
    ODOM_FRAME,
    arm_frames,
    base_frames,
)
from busarm.robot.remote import RobotServer
from busarm.robot.state import StateReader
from busarm.ros import messages as m
from busarm.ros.commands import (
    CLOSED_GAP_M,
    CmdVel,
    Publishers,
    TrajectoryRunner,
    plan_trajectory,
)
from busarm.ros.node import Received, RosNode
from busarm.ros.rosout import RosoutHandler
from busarm.ros.sensors import (
    block_markers,
    diagnostics,
    laser_scan,
    occupancy_grid,
    odometry,
)

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "BLOCKS_HZ",
    "DESCRIBE_EVERY_S",
    "GRIPPER_JOINT",
    "SENDER_LEFT",
    "BridgeSettings",
    "RosBridge",
]


log = logging.getLogger(__name__)

DESCRIBE_EVERY_S = 2.0
"""/robot_description (and /map) again this often: a transient-local subscriber gets them
from the publisher's cache, a volatile one (a plain Zenoh subscriber, a tool that does
not query) from the next repeat; every two seconds is cheap."""
BLOCKS_HZ = 3.0
GRIPPER_JOINT = "gripper"
SENDER_LEFT = "its sender left (the link dropped or the node ended)"


@dataclass(frozen=True)
class BridgeSettings:
    state_hz: float = 60.0
    camera_fps: float = 15.0
    jpeg_quality: int = 80
    camera: bool = True
    """Publish the wrist camera (and the blocks it sees), if the robot has one."""
    map_grid: OccupancyGrid | None = None
    """A saved map to publish on /map (latched, as map_server does)."""


class RosBridge:
    """Publishes ``robot`` on ``node`` and takes commands for it; ``start()``, ``close()``."""

    def __init__(self, robot: Robot, node: RosNode,
                 settings: BridgeSettings | None = None, *, serve_as: str | None = None
                 ) -> None:
        self.robot = robot
        self.node = node
        self.settings = settings or BridgeSettings()
        self.camera = robot.has_camera and self.settings.camera
        self.joint_names = [j.name for j in robot.config.joints]
        # A slow value (a temperature, a voltage...) every 5th period: each servo's
        # about every 2 s at 50 Hz, while the joints get the bus's time.
        self.state = StateReader(robot.arm, slow_every=5)
        self.runner = TrajectoryRunner(robot.arm)
        self.cmd_vel = CmdVel(robot.base) if robot.base is not None else None
        self.errors: list[str] = []
        self._closed = threading.Event()
        self._threads: list[threading.Thread] = []
        self._latest_deg: tuple[float, ...] | None = None
        self._latest_frame: tuple[Any, tuple[float, ...] | None, float] | None = None
        pub = node.publisher
        self.pub_joints = pub("/joint_states", m.JOINT_STATE)
        self.pub_tf = pub("/tf", m.TF_MESSAGE)
        self.pub_description = pub("/robot_description", m.STRING, LATCHED)
        self.pub_diagnostics = pub("/diagnostics", m.DIAGNOSTIC_ARRAY)
        self.pub_odom = pub("/odom", m.ODOMETRY) if robot.base is not None else None
        self.pub_scan = (pub("/scan", m.LASER_SCAN, SENSOR_DATA)
                         if robot.lidar is not None else None)
        self.pub_map = (pub("/map", m.OCCUPANCY_GRID, LATCHED)
                        if self.settings.map_grid is not None else None)
        if self.camera:
            self.pub_image = pub("/wrist_camera/image_raw", m.IMAGE, SENSOR_DATA)
            self.pub_jpeg = pub("/wrist_camera/image_raw/compressed", m.COMPRESSED_IMAGE,
                                SENSOR_DATA)
        if self.camera and robot.camera_calibration is not None:
            self.pub_info = pub("/wrist_camera/camera_info", m.CAMERA_INFO, SENSOR_DATA)
            self.pub_blocks = pub("/blocks", m.MARKER_ARRAY)
        self.server = (RobotServer(node.session, robot, serve_as, camera=self.camera)
                       if serve_as is not None and isinstance(robot.arm.bus, ServoBus)
                       else None)
        """The robot served to other busarm processes (``--port zenoh://HOST``); not one
        on a controller board (its frames are not tunnelled yet)."""
        self._rosout = RosoutHandler(node)
        logging.getLogger("busarm.ros").addHandler(self._rosout)
        self.trajectory_senders = Publishers("/joint_trajectory")
        # history: the tokens already there are told too, so a sender that came first counts.
        self._watch_senders = node.session.liveliness().declare_subscriber(
            f"@ros2_lv/{node.domain_id}/**", self._on_token, history=True)
        self._subscribe()

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> RosBridge:
        loops: list[tuple[str, Callable[[], None]]] = [("ros-state", self._state_loop)]
        if self.camera:
            loops.append(("ros-camera", self._camera_loop))
        if self.camera and self.robot.camera_calibration is not None:
            loops.append(("ros-blocks", self._blocks_loop))
        if self.robot.lidar is not None:
            loops.append(("ros-scan", self._scan_loop))
        for name, loop in loops:
            thread = threading.Thread(target=self._guard(loop), name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def close(self) -> None:
        """Stop publishing and taking commands; the arm holds, the wheels stop."""
        self._closed.set()
        self._watch_senders.undeclare()
        self.runner.close()
        if self.cmd_vel is not None:
            self.cmd_vel.stop()
        for thread in self._threads:
            thread.join(timeout=2.0)
        logging.getLogger("busarm.ros").removeHandler(self._rosout)
        if self.server is not None:
            self.server.close()
        self.node.close()

    def _guard(self, loop: Callable[[], None]) -> Callable[[], None]:
        def run() -> None:
            try:
                loop()
            except Exception as exc:  # a loop that dies says so, and the robot stops
                self.errors.append(f"{type(exc).__name__}: {exc}")
                log.exception("the bridge stopped publishing")
                self.runner.cancel(f"a bridge loop failed: {exc}")
                if self.cmd_vel is not None:
                    self.cmd_vel.stop()
        return run

    def _every(self, period_s: float) -> Callable[[], bool]:
        """A ticker: each call waits for the next period; False once the bridge closes."""
        next_at = [time.monotonic()]

        def tick() -> bool:
            next_at[0] += period_s
            delay = next_at[0] - time.monotonic()
            if delay < -3 * period_s:  # far behind: start again from now, not in a burst
                next_at[0] = time.monotonic()
            return not self._closed.wait(max(0.0, delay))
        return tick

    # ------------------------------------------------------------------ publishing

    def _describe(self) -> None:
        """The latched topics: /robot_description, and /map when there is one."""
        self.pub_description.publish(m.string(urdf_from_config(self.robot.config)))
        grid = self.settings.map_grid
        if self.pub_map is not None and grid is not None:
            self.pub_map.publish(occupancy_grid(time.time(), grid))

    def _state_loop(self) -> None:
        self._describe()
        described_at = time.monotonic()
        diagnosed_at = 0.0
        tick = self._every(1.0 / self.settings.state_hz)
        while tick():
            self._publish_state()
            now = time.monotonic()
            if now - diagnosed_at >= 1.0:
                self.pub_diagnostics.publish(diagnostics(
                    time.time(), self.state, self.joint_names, self.robot.arm.bus.halted))
                diagnosed_at = now
            if now - described_at >= DESCRIBE_EVERY_S:
                self._describe()
                described_at = now
            if self.cmd_vel is not None:
                self.cmd_vel.tick()

    def _publish_state(self) -> None:
        try:
            reading = self.state.read()
        except BusArmError as exc:
            log.warning("joint states not read: %s", exc)
            return
        t = time.time()
        self._latest_deg = reading.joints_deg
        gap_m = self.robot.config.gripper.gap_mm_at(reading.gripper_pulses) / 1000.0
        positions = [*(math.radians(v) for v in reading.joints_deg), gap_m]
        self.pub_joints.publish(m.joint_state(t, [*self.joint_names, GRIPPER_JOINT],
                                              positions))
        cal = self.robot.camera_calibration
        frames = arm_frames(self.robot.config, self.robot.arm.kin, reading.joints_deg,
                            cal.hand_eye.cam2link if cal is not None else None)
        base = self.robot.base
        if base is not None:
            odom = base.odometry()
            frames += base_frames(odom.pose, base.config.arm, base.config.lidar)
            assert self.pub_odom is not None
            self.pub_odom.publish(odometry(t, odom, ODOM_FRAME, FOOTPRINT_FRAME))
        self.pub_tf.publish(m.tf_message([m.transform(t, p, c, x) for p, c, x in frames]))

    def _camera_loop(self) -> None:
        import cv2

        camera, cal = self.robot.camera, self.robot.camera_calibration
        # A twin's camera for people to watch (RViz, Foxglove) is rendered as the
        # dashboard's is, without shadows or antialiasing: 15 ms a frame, not 40, and
        # the renderer holds the GIL (every other loop here waits on it). A busarm on
        # zenoh:// gets the pictures the twin's vision works on, while it listens.
        sim = self.robot.sim
        watched = sim.live_camera("arm") if sim is not None else camera
        tick = self._every(1.0 / self.settings.camera_fps)
        while tick():
            served = self.server is not None and self.server.camera_wanted
            frame = camera.read() if served else watched.read()
            joints = self._latest_deg
            t = time.time()
            self._latest_frame = (frame.image, joints, t)
            if served and self.server is not None:
                self.server.publish_frame(frame, t)
            if self.pub_image.matched:  # a raw frame is 0.9 MB of CDR, a JPEG 1 ms to make
                self.pub_image.publish(m.image_bgr(t, CAMERA_FRAME, frame.image))
            ok, jpeg = (cv2.imencode(".jpg", frame.image,
                                     [cv2.IMWRITE_JPEG_QUALITY, self.settings.jpeg_quality])
                        if self.pub_jpeg.matched else (False, None))
            if ok and jpeg is not None:
                self.pub_jpeg.publish(m.compressed_jpeg(t, CAMERA_FRAME, jpeg.tobytes()))
            if cal is not None:
                i = cal.intrinsics
                self.pub_info.publish(m.camera_info(t, CAMERA_FRAME, i.width_px, i.height_px,
                                                    i.camera_matrix, list(i.distortion),
                                                    i.model))
        if sim is not None:
            sim.release_renderers()  # this thread's, made for its pictures

    def _blocks_loop(self) -> None:
        """The blocks in the latest frame, BLOCKS_HZ times a second (in a thread of its
        own: locating them must not slow the camera down)."""
        locator = self.robot.locator()
        tick = self._every(1.0 / BLOCKS_HZ)
        seen: float | None = None
        while tick():
            latest = self._latest_frame
            if latest is None or latest[1] is None or latest[2] == seen:
                continue
            image, joints, seen = latest
            assert joints is not None
            self.pub_blocks.publish(block_markers(seen, locator.locate(image, joints)))

    def _scan_loop(self) -> None:
        lidar = self.robot.lidar
        assert lidar is not None and self.pub_scan is not None
        while not self._closed.is_set():
            try:
                scan = lidar.read_scan(timeout_s=1.0)
            except BusArmError as exc:
                log.warning("no scan: %s", exc)
                continue
            self.pub_scan.publish(laser_scan(time.time(), scan, LASER_FRAME))

    # ------------------------------------------------------------------ commands

    def _subscribe(self) -> None:
        sub = self.node.subscribe
        sub("/joint_trajectory", m.JOINT_TRAJECTORY, self._on_trajectory)
        sub("/gripper/command", m.FLOAT64, self._on_gripper)
        sub("/estop", m.EMPTY, self._on_estop)
        sub("/rearm", m.EMPTY, self._on_rearm)
        if self.cmd_vel is not None:
            sub("/cmd_vel", m.TWIST, self._on_cmd_vel)

    def _on_trajectory(self, msg: Any, received: Received) -> None:
        trajectory = m.parse_trajectory(msg, self.joint_names)
        self._check_armed()
        current = self._latest_deg or self.robot.arm.read_joints_deg()
        tokens = self.trajectory_senders.of(received.gid)
        if not tokens:
            log.warning("a trajectory from a publisher with no liveliness token: it runs to "
                        "its end even if its sender goes")
        plan = plan_trajectory(self.robot.arm, trajectory, current, received.gid, tokens)
        self.runner.start(plan)
        if not self.trajectory_senders.present(tokens):  # one left while it was planned
            self.runner.cancel(SENDER_LEFT)

    def _on_gripper(self, msg: Any, received: Received) -> None:
        gap_mm = float(msg.data) * 1000.0
        g = self.robot.config.gripper
        widest_mm = g.gap_mm_at(g.open_pulses)
        if not 0.0 <= gap_mm <= widest_mm + 0.5:  # NaN fails too
            raise ConfigError(f"/gripper/command {msg.data!r} m; allowed: 0 (close and "
                              f"grip) .. {widest_mm / 1000.0:.4f} m (open)")
        self._check_armed()
        arm = self.robot.arm

        def action() -> object:
            if gap_mm <= CLOSED_GAP_M * 1000.0:
                return arm.grip()
            return arm.open_gripper(gap_mm=min(gap_mm, widest_mm))
        threading.Thread(target=self._quietly(action), name="ros-gripper", daemon=True).start()

    def _quietly(self, action: Callable[[], object]) -> Callable[[], None]:
        def run() -> None:
            try:
                action()
            except BusArmError as exc:
                log.error("gripper command failed: %s", exc)
        return run

    def _on_cmd_vel(self, msg: Any, received: Received) -> None:
        twist = m.parse_twist(msg)
        self._check_armed()
        assert self.cmd_vel is not None
        self.cmd_vel.take(twist)

    def _on_estop(self, msg: Any, received: Received) -> None:
        self.estop("e-stop from ROS (/estop)")

    def _on_rearm(self, msg: Any, received: Received) -> None:
        self.robot.arm.bus.rearm()
        log.warning("re-armed from ROS (/rearm)")

    def estop(self, why: str) -> None:
        """Halt the bus (the arm holds; every later write refused) and stop the wheels."""
        self.robot.arm.bus.halt(why)
        self.runner.cancel(why, hold=False)
        if self.cmd_vel is not None:
            self.cmd_vel.stop()
        log.warning("%s: halted until /rearm", why)

    def _check_armed(self) -> None:
        why = self.robot.arm.bus.halted
        if why is not None:
            raise HaltedError(f"the robot is halted ({why}): publish on /rearm first")

    def _on_token(self, sample: zenoh.Sample) -> None:
        import zenoh

        key, alive = str(sample.key_expr), sample.kind != zenoh.SampleKind.DELETE
        self.trajectory_senders.update(key, alive)
        if not alive:
            self.runner.sender_left(key, SENDER_LEFT)
