"""One robot, two computers: the robot's side serves it on a Zenoh session, another
computer opens ``--port zenoh://HOST`` and every busarm command works there as it does
on the robot (the servo bus stays where the serial port is).

Served under ``busarm/<robot>/``:

- ``bus``: the servo bus's transport (busarm.bus.zenoh_link), each request checked here
  first (``bus_guard``): a position outside the joints' limits, or any write but a stop
  while the robot is halted, never reaches the line;
- ``info``: what the other side needs to be this robot: its arm config, its camera's
  calibration (the files, as the calibration store keeps them), its bins;
- ``camera/wrist``: the wrist camera's frames, raw BGR (a small header, then the pixels);
  rendered and sent only while someone listens;
- ``truth`` (a twin only): where the twin's joints and blocks really are, for benchmarks
  and tests that check a remote job; the job itself never asks for it.

When a remote client's link goes, every servo is stopped where it is (MOVE_STOP).
"""

from __future__ import annotations

import json
import logging
import struct
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from busarm.arm.arm import Arm
from busarm.arm.config import ArmConfig, arm_config_from_toml, load_arm_config
from busarm.bus.driver import ServoBus
from busarm.bus.zenoh_link import BusServer, Check, ZenohTransport
from busarm.errors import CameraError, ConfigError, LimitError, ProtocolError
from busarm.protocol import BROADCAST_ID, Command, FrameParser
from busarm.protocol.frames import decode_request
from busarm.vision.calibration import load_hand_eye, load_intrinsics, save_hand_eye, save_intrinsics
from busarm.vision.camera import CameraFrame

if TYPE_CHECKING:
    import zenoh

    from busarm.robot.robot import Bins, CameraCalibration, Robot

__all__ = [
    "INFO_TIMEOUT_S",
    "POSITION_COMMANDS",
    "RemoteCamera",
    "RemoteParts",
    "RobotServer",
    "ask",
    "bus_guard",
    "fetch_info",
    "remote_parts",
    "robot_info",
    "robot_key",
    "served_bus",
    "twin_truth",
]


log = logging.getLogger(__name__)

POSITION_COMMANDS = (Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE)
_FRAME = struct.Struct("<dIHH")
"""A camera frame's header: capture time (s since the epoch), sequence, height, width."""
INFO_TIMEOUT_S = 5.0


def robot_key(robot: str, what: str) -> str:
    return f"busarm/{robot}/{what}"


def served_bus(arm: Arm) -> ServoBus:
    """The arm's LX line, whose bytes a served robot relays; ConfigError for another
    servo port (behind a controller board, another family: its frames are not relayed)."""
    if not isinstance(arm.bus, ServoBus):
        raise ConfigError(f"only servos on an LX line can be served over Zenoh; this arm's "
                          f"are on {arm.bus.name}")
    return arm.bus


def bus_guard(arm: Arm) -> Check:
    """The check each request from a remote client passes before it reaches the line."""
    limits = arm.pulse_limits
    bus = served_bus(arm)

    def check(request: bytes) -> None:
        parser = FrameParser()
        frames = parser.feed(request)
        if not frames or parser.pending or parser.skipped_bytes:
            raise ProtocolError(f"not whole LX request frames: {request.hex(' ')}")
        for frame in frames:
            req = decode_request(frame)
            bus.check_not_halted(req.command, req.args)
            if req.command not in POSITION_COMMANDS:
                continue
            if req.servo_id == BROADCAST_ID or req.servo_id not in limits:
                raise LimitError(f"a position for servo {req.servo_id} refused: allowed "
                                 f"only to the arm's servos {sorted(limits)}, one at a time")
            lo, hi = limits[req.servo_id]
            position = req.args[0]
            if not lo <= position <= hi:
                raise LimitError(f"servo {req.servo_id} position {position} refused: "
                                 f"allowed {lo}..{hi} pulses (its joint's limits)")
    return check


def robot_info(robot: Robot, camera: bool) -> dict[str, Any]:
    """What a remote client needs to be this robot (JSON values); ``camera``: whether
    its frames are served."""
    config = robot.config
    shipped = config.source.endswith(" (shipped)")
    if not shipped and not Path(config.source).is_file():
        raise ConfigError(f"the arm config ({config.source}) is not a file a remote client "
                          "can be given: load it from a TOML file")
    info: dict[str, Any] = {
        "config": ({"shipped": config.source.removesuffix(" (shipped)")} if shipped
                   else {"toml": Path(config.source).read_text(), "source": config.source}),
        "bins": {color: list(xy) for color, xy in robot.bins.items()},
        "camera": camera and robot.has_camera, "twin": robot.is_twin,
        "calibration": None,
    }
    cal = robot.camera_calibration
    if cal is not None:
        with tempfile.TemporaryDirectory(prefix="busarm-serve-") as tmp:
            save_intrinsics(Path(tmp) / "camera.json", cal.intrinsics)
            save_hand_eye(Path(tmp) / "hand_eye.json", cal.hand_eye)
            info["calibration"] = {"intrinsics": (Path(tmp) / "camera.json").read_text(),
                                   "hand_eye": (Path(tmp) / "hand_eye.json").read_text(),
                                   "source": cal.source}
    return info


def twin_truth(robot: Robot) -> dict[str, Any]:
    twin = robot.twin
    assert twin is not None
    with twin.lock:
        return {"t": time.time(), "joints_deg": list(twin.joints_deg()),
                "gap_mm": twin.finger_gap_mm(),
                "blocks": [{"color": b.color, "x_mm": b.x_mm, "y_mm": b.y_mm,
                            "z_mm": b.z_mm, "upright": b.is_upright} for b in twin.blocks()]}


class RobotServer:
    """Serves ``robot`` as ``name`` on ``session`` (see the module docstring); ``camera``:
    its frames are served (``publish_frame``)."""

    def __init__(self, session: zenoh.Session, robot: Robot, name: str, *,
                 camera: bool = True) -> None:
        bus = served_bus(robot.arm)
        self.robot = robot
        self.name = name
        self.lost: list[str] = []
        self._info = json.dumps(robot_info(robot, camera)).encode()
        self._bus = BusServer(session, name, bus.transport, bus.lock, bus_guard(robot.arm),
                              self._client_lost)
        self._queryables = [session.declare_queryable(robot_key(name, "info"), self._on_info)]
        if robot.is_twin:
            self._queryables.append(session.declare_queryable(robot_key(name, "truth"),
                                                              self._on_truth))
        self._camera = session.declare_publisher(robot_key(name, "camera/wrist"))

    @property
    def camera_wanted(self) -> bool:
        """Whether anyone listens to the camera (else no frame need be made for it)."""
        return bool(self._camera.matching_status)

    def publish_frame(self, frame: CameraFrame, t_s: float) -> None:
        image = np.ascontiguousarray(frame.image)
        h, w = image.shape[:2]
        self._camera.put(_FRAME.pack(t_s, frame.sequence & 0xFFFFFFFF, h, w) + image.tobytes())

    def _on_info(self, query: zenoh.Query) -> None:
        query.reply(query.key_expr, self._info)

    def _on_truth(self, query: zenoh.Query) -> None:
        query.reply(query.key_expr, json.dumps(twin_truth(self.robot)).encode())

    def _client_lost(self, client: str) -> None:
        """A remote busarm's link went: whatever it was doing, the arm holds."""
        self.lost.append(client)
        log.warning("remote client %s left: every servo stopped where it is", client)
        self.robot.arm.bus.emergency_stop()

    def close(self) -> None:
        for q in self._queryables:
            q.undeclare()
        self._camera.undeclare()
        self._bus.close()


# ------------------------------------------------------------------ the client's side


class RemoteCamera:
    """The wrist camera of a robot served on Zenoh: ``read()`` gives the second frame to
    arrive after it is called (the first may have been taken before it was), as a USB
    camera's next frame is one taken after the call."""

    def __init__(self, session: zenoh.Session, robot: str, timeout_s: float = 3.0) -> None:
        self.name = f"zenoh camera of robot {robot!r}"
        self.timeout_s = timeout_s
        self._cond = threading.Condition()
        self._frames: list[CameraFrame] = []
        self._count = 0
        self.width_px, self.height_px = 0, 0
        self._sub = session.declare_subscriber(robot_key(robot, "camera/wrist"), self._on_frame)
        first = self._next(1, self.timeout_s * 2)
        self.height_px, self.width_px = first.image.shape[:2]

    def _on_frame(self, sample: zenoh.Sample) -> None:
        data = bytes(sample.payload.to_bytes())
        try:
            _t, seq, h, w = _FRAME.unpack_from(data)
            image = np.frombuffer(data, dtype=np.uint8, offset=_FRAME.size).reshape(h, w, 3)
        except (struct.error, ValueError):
            log.warning("%s: a malformed frame of %d bytes dropped", self.name, len(data))
            return
        image.flags.writeable = False
        with self._cond:
            self._count += 1
            self._frames = [CameraFrame(image, time.monotonic(), seq, self.name)]
            self._cond.notify_all()

    def _next(self, after: int, timeout_s: float) -> CameraFrame:
        with self._cond:
            target = self._count + after
            if not self._cond.wait_for(lambda: self._count >= target, timeout=timeout_s):
                raise CameraError(f"{self.name}: no frame in {timeout_s:g} s (is the robot's "
                                  "bridge running with its camera?)")
            return self._frames[-1]

    def read(self) -> CameraFrame:
        return self._next(2, self.timeout_s)

    def close(self) -> None:
        self._sub.undeclare()

    def __enter__(self) -> RemoteCamera:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class RemoteParts:
    """A served robot as the client sees it: its config, camera, calibration and bins."""

    config: ArmConfig
    camera: RemoteCamera | None
    calibration: CameraCalibration | None
    bins: Bins
    twin: bool


def ask(session: zenoh.Session, robot: str, what: str,
        timeout_s: float = INFO_TIMEOUT_S) -> dict[str, Any]:
    """A served robot's JSON answer on ``busarm/<robot>/<what>`` (``info``, ``truth``);
    ConfigError when none comes within ``timeout_s``."""
    for reply in session.get(robot_key(robot, what), timeout=timeout_s):
        if reply.ok is not None:
            data: dict[str, Any] = json.loads(reply.ok.payload.to_bytes())
            return data
    raise ConfigError(f"robot {robot!r} gave no {what} within {timeout_s:g} s (is "
                      "`busarm ros bridge` serving it?)")


def fetch_info(transport: ZenohTransport) -> dict[str, Any]:
    """What the robot behind ``transport`` is (its ``info``)."""
    return ask(transport.session, transport.robot, "info")


def remote_parts(transport: ZenohTransport, info: dict[str, Any],
                 camera: bool) -> RemoteParts:
    """The served robot's parts from its ``info`` (``camera``: open its wrist camera)."""
    from busarm.robot.robot import CameraCalibration

    spec = info["config"]
    config = (load_arm_config(spec["shipped"]) if "shipped" in spec
              else arm_config_from_toml(spec["toml"], source=spec["source"]))
    calibration = None
    if info.get("calibration"):
        cal = info["calibration"]
        with tempfile.TemporaryDirectory(prefix="busarm-remote-") as tmp:
            (Path(tmp) / "camera.json").write_text(cal["intrinsics"])
            (Path(tmp) / "hand_eye.json").write_text(cal["hand_eye"])
            intr = load_intrinsics(Path(tmp) / "camera.json")
            hand_eye = load_hand_eye(Path(tmp) / "hand_eye.json", intrinsics=intr)
        calibration = CameraCalibration(intr, hand_eye, f"{cal['source']} (on {transport.name})")
    source = (RemoteCamera(transport.session, transport.robot)
              if camera and info.get("camera") else None)
    bins = {str(c): (float(xy[0]), float(xy[1])) for c, xy in info.get("bins", {}).items()}
    return RemoteParts(config, source, calibration, bins, bool(info.get("twin")))
