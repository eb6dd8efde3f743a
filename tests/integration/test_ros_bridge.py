"""`busarm ros bridge` in its own process, seen and driven over a real loopback Zenoh
session as a ROS 2 node using rmw_zenoh would: the graph from liveliness tokens, CDR
payloads with the 33-byte attachment, commands checked before anything moves, bad
samples dropped and said on /rosout, the robot stopped when the sender's link drops."""

from __future__ import annotations

import itertools
import json
import math
import os
import queue
import secrets
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from busarm.arm.config import load_arm_config
from busarm.arm.urdf import urdf_from_config
from busarm.bench.ros import free_port
from busarm.bus.zenoh_session import open_session
from busarm.protocol.rmw_zenoh import (
    ROSOUT,
    Attachment,
    Entity,
    History,
    Qos,
    gid_of,
    topic_key,
)
from busarm.ros import messages as m
from busarm.ros.graph import read_graph
from busarm.ros.node import Received, RosNode
from conftest import keep_twin_calibration

pytestmark = [pytest.mark.slow, pytest.mark.wallclock(
    "a `busarm ros bridge` process on a real-time twin, over a loopback Zenoh session")]

BUSARM = str(Path(sys.executable).with_name("busarm"))
CONFIG = load_arm_config("jetauto_pro")
NAMES = [j.name for j in CONFIG.joints]


@pytest.fixture(scope="module")
def bridge(tmp_path_factory: pytest.TempPathFactory,
           twin_calibration: tuple[Path, Path]) -> Iterator[str]:
    """A bridge on the twin (real time, seed-3 table), listening on a free loopback port;
    yields its endpoint. It must exit cleanly (0) when stopped at the end."""
    root = tmp_path_factory.mktemp("ros-bridge")
    keep_twin_calibration(root / "config", twin_calibration)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    env = {**os.environ, "XDG_CONFIG_HOME": str(root / "config"),
           "BUSARM_RUNTIME_DIR": str(root / "run")}
    # Two camera frames a second: enough for the tests that read one, and each frame is a
    # full render and detection on the CPU the rest of the suite shares.
    proc = subprocess.Popen([BUSARM, "ros", "bridge", "--seed", "3", "--listen", endpoint,
                             "--fps", "2"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert "ROS 2 bridge of the JetAuto Pro arm on the twin" in line, proc.stderr.read()
    assert f"listening on {endpoint}" in line
    yield endpoint
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert "Traceback" not in err and "bridge stopped" in err


@pytest.fixture
def peer(bridge: str) -> Iterator[RosNode]:
    session = open_session(connect=[bridge])
    node = RosNode(session, "tester")
    yield node
    node.close()
    session.close()


class Inbox:
    """What came on a topic, in order."""

    def __init__(self, node: RosNode, topic: str, type_name: str) -> None:
        self.items: queue.Queue[tuple[Any, Received]] = queue.Queue()
        node.subscribe(topic, type_name, lambda msg, rec: self.items.put((msg, rec)))

    # Generous waits: a busy computer delivers late, and only a failing test waits them out.
    def next(self, timeout_s: float = 15.0) -> tuple[Any, Received]:
        """The oldest message not yet taken (waiting for one if none)."""
        return self.items.get(timeout=timeout_s)

    def latest(self, timeout_s: float = 15.0) -> tuple[Any, Received]:
        """The next message to come after every one taken or waiting now."""
        while not self.items.empty():
            self.items.get()
        return self.next(timeout_s)

    def until(self, check: Callable[[Any], bool], timeout_s: float = 20.0) -> Any:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            msg, _ = self.next(max(0.01, end - time.monotonic()))
            if check(msg):
                return msg
        raise AssertionError("not seen in time")


def joints_deg(msg: Any) -> dict[str, float]:
    return {n: math.degrees(p) for n, p in zip(msg.name, msg.position, strict=True)}


def trajectory(points: list[tuple[float, dict[str, float]]]) -> Any:
    """A JointTrajectory of (time s, {joint: deg})."""
    names = list(points[0][1])
    point = m.message_class("trajectory_msgs/msg/JointTrajectoryPoint")
    duration = m.message_class("builtin_interfaces/msg/Duration")
    empty = np.zeros(0)
    return m.message_class(m.JOINT_TRAJECTORY)(
        header=m.header(0.0, ""), joint_names=names, points=[point(
            positions=np.radians([q[n] for n in names]), velocities=empty,
            accelerations=empty, effort=empty,
            time_from_start=duration(sec=int(t), nanosec=round(t % 1 * 1e9)))
            for t, q in points])


def test_the_graph_shows_the_bridge_as_ros_2_would(peer: RosNode, bridge: str) -> None:
    graph = read_graph(peer.session, 0)
    assert "/busarm" in graph.nodes
    states = graph.topic("/joint_states")
    assert states is not None and states.publishers == 1
    assert states.type_hash == m.ros_type(m.JOINT_STATE).type_hash
    for name in ("/joint_trajectory", "/gripper/command", "/estop", "/rearm"):
        topic = graph.topic(name)
        assert topic is not None and topic.subscribers >= 1, name
    for name in ("/tf", "/robot_description", "/diagnostics", "/wrist_camera/image_raw",
                 "/wrist_camera/camera_info", "/blocks", "/rosout"):
        assert graph.topic(name) is not None, name
    assert graph.topic("/cmd_vel") is None  # an arm on a table has no base
    # The CLI sees the same, as `ros2 topic list -t` would.
    out = subprocess.run([BUSARM, "ros", "topics", "--connect", bridge], capture_output=True,
                         text=True, timeout=30)
    assert out.returncode == 0, out.stderr
    assert "/joint_states [sensor_msgs/msg/JointState] publishers 1" in out.stdout


def test_joint_states_carry_rmw_zenohs_attachment_and_the_urdf_names(peer: RosNode) -> None:
    inbox = Inbox(peer, "/joint_states", m.JOINT_STATE)
    (first, a), (_, b) = inbox.next(), inbox.next()
    assert first.name == [*NAMES, "gripper"] and len(first.position) == 6
    assert b.sequence_number == a.sequence_number + 1
    publisher = next(e for e in read_graph(peer.session, 0).entities
                     if e.kind == "MP" and e.topic == "/joint_states")
    assert a.gid == gid_of(publisher.token())  # the GID a ROS 2 graph gives it
    assert abs(a.source_timestamp_ns / 1e9 - time.time()) < 5.0


def test_the_description_is_the_urdf_and_the_camera_is_calibrated(peer: RosNode) -> None:
    description = Inbox(peer, "/robot_description", m.STRING).next(timeout_s=6.0)[0]
    assert description.data == urdf_from_config(CONFIG)
    image = Inbox(peer, "/wrist_camera/image_raw", m.IMAGE).next()[0]
    assert m.image_array(image).shape == (480, 640, 3)
    info = Inbox(peer, "/wrist_camera/camera_info", m.CAMERA_INFO).next()[0]
    assert (info.width, info.height) == (640, 480) and info.k[0] > 100  # focal length, px
    jpeg = Inbox(peer, "/wrist_camera/image_raw/compressed", m.COMPRESSED_IMAGE).next()[0]
    assert jpeg.format == "jpeg" and bytes(jpeg.data[:2]) == b"\xff\xd8"
    diagnostics = Inbox(peer, "/diagnostics", m.DIAGNOSTIC_ARRAY).next(timeout_s=3.0)[0]
    names = [s.name for s in diagnostics.status]
    assert "busarm/servo 1 (base_yaw)" in names and "busarm/bus" in names


def test_a_trajectory_moves_the_twin_and_a_bad_one_moves_nothing(peer: RosNode) -> None:
    states = Inbox(peer, "/joint_states", m.JOINT_STATE)
    rosout = Inbox(peer, "/rosout", m.ROSOUT_LOG)
    send = peer.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    time.sleep(0.3)  # the bridge hears of this publisher
    start = joints_deg(states.next()[0])
    target = start["base_yaw"] + 20.0
    send.publish(trajectory([(0.5, {"base_yaw": start["base_yaw"] + 10.0}),
                             (1.0, {"base_yaw": target})]))
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - target) < 1.0)
    # Beyond the joint's limit: refused whole, said on /rosout, nothing moves.
    lo, hi = CONFIG.joints[0].min_deg, CONFIG.joints[0].max_deg
    send.publish(trajectory([(1.0, {"base_yaw": target + 5.0}), (3.0, {"base_yaw": hi + 10})]))
    log = rosout.until(lambda msg: "joint_trajectory" in msg.msg)
    assert "refused" in log.msg or "point 1" in log.msg
    assert f"{hi:g}" in log.msg  # the allowed range is named
    # Too fast from where the arm is (120 deg in 0.1 s): refused too.
    send.publish(trajectory([(0.1, {"base_yaw": max(lo + 1, target - 120.0)})]))
    assert "deg/s" in rosout.until(lambda msg: "deg/s" in msg.msg).msg
    time.sleep(0.5)
    held = joints_deg(states.latest()[0])["base_yaw"]
    assert abs(held - target) < 1.0
    send.publish(trajectory([(1.0, {"base_yaw": start["base_yaw"]})]))
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start["base_yaw"]) < 1.0)


def _put_raw(peer: RosNode, topic: str, type_name: str, type_hash: str,
             payload: bytes, attachment: bytes | None) -> None:
    key = topic_key(0, topic, type_name, type_hash)
    peer.session.put(key, payload, attachment=attachment)


def test_malformed_and_mistyped_samples_are_dropped_and_the_bridge_stays_up(
        peer: RosNode) -> None:
    states = Inbox(peer, "/joint_states", m.JOINT_STATE)
    rosout = Inbox(peer, "/rosout", m.ROSOUT_LOG)
    time.sleep(0.3)
    good_hash = m.ros_type(m.JOINT_TRAJECTORY).type_hash
    attachment = Attachment(1, time.time_ns(), b"\x01" * 16).encode()
    _put_raw(peer, "/joint_trajectory", m.JOINT_TRAJECTORY, good_hash,
             b"\x00\x01\x00\x00" + b"\xff" * 64, attachment)
    assert "malformed" in rosout.until(lambda msg: "malformed" in msg.msg).msg
    _put_raw(peer, "/joint_trajectory", m.JOINT_TRAJECTORY, "RIHS01_" + "0" * 64,
             m.encode(trajectory([(1.0, {"base_yaw": 0.0})]), m.JOINT_TRAJECTORY),
             attachment)
    assert "expected" in rosout.until(lambda msg: "RIHS01_0000" in msg.msg).msg
    _put_raw(peer, "/joint_trajectory", m.JOINT_TRAJECTORY, good_hash,
             m.encode(trajectory([(1.0, {"base_yaw": 0.0})]), m.JOINT_TRAJECTORY), b"\x00")
    assert "attachment" in rosout.until(lambda msg: "attachment" in msg.msg).msg
    _put_raw(peer, "/joint_trajectory", m.STRING, m.ros_type(m.STRING).type_hash,
             m.encode(m.string("move!"), m.STRING), attachment)
    assert "std_msgs/msg/String" in rosout.until(lambda msg: "String" in msg.msg).msg
    before = states.latest()[1].sequence_number
    time.sleep(0.3)
    assert states.latest()[1].sequence_number > before + 5  # still publishing


def test_a_flood_of_trajectories_leaves_the_last_one_in_charge(peer: RosNode) -> None:
    states = Inbox(peer, "/joint_states", m.JOINT_STATE)
    # Reliable keep-all: every one of the flood arrives (a busy computer would otherwise
    # drop some, perhaps the last, as a keep-last publisher may).
    send = peer.publisher("/joint_trajectory", m.JOINT_TRAJECTORY,
                          Qos(history=History.KEEP_ALL))
    time.sleep(0.3)
    start = joints_deg(states.next()[0])["wrist_roll"]
    for k in range(300):
        send.publish(trajectory([(1.0, {"wrist_roll": start + 15.0 * (k % 3)})]))
    final = start + 15.0 * (299 % 3)
    states.until(lambda msg: abs(joints_deg(msg)["wrist_roll"] - final) < 1.0)
    time.sleep(1.2)
    assert abs(joints_deg(states.latest()[0])["wrist_roll"] - final) < 1.0
    send.publish(trajectory([(1.0, {"wrist_roll": start})]))
    states.until(lambda msg: abs(joints_deg(msg)["wrist_roll"] - start) < 1.0)


def test_estop_latches_until_rearm(peer: RosNode) -> None:
    states = Inbox(peer, "/joint_states", m.JOINT_STATE)
    rosout = Inbox(peer, "/rosout", m.ROSOUT_LOG)
    send = peer.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    estop = peer.publisher("/estop", m.EMPTY)
    rearm = peer.publisher("/rearm", m.EMPTY)
    time.sleep(0.3)
    start = joints_deg(states.next()[0])["base_yaw"]
    estop.publish(m.message_class(m.EMPTY)())
    rosout.until(lambda msg: "halted until /rearm" in msg.msg)
    send.publish(trajectory([(1.0, {"base_yaw": start + 10.0})]))
    assert "publish on /rearm first" in rosout.until(lambda msg: "rearm first" in msg.msg).msg
    time.sleep(1.2)
    assert abs(joints_deg(states.latest()[0])["base_yaw"] - start) < 0.5
    rearm.publish(m.message_class(m.EMPTY)())
    time.sleep(0.3)
    send.publish(trajectory([(1.0, {"base_yaw": start + 10.0})]))
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start - 10.0) < 1.0)
    send.publish(trajectory([(1.0, {"base_yaw": start})]))
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start) < 1.0)


def test_the_arm_stops_and_holds_when_the_senders_link_drops(
        peer: RosNode, bridge: str) -> None:
    states = Inbox(peer, "/joint_states", m.JOINT_STATE)
    start = joints_deg(states.next()[0])["base_yaw"]
    target = start + 60.0 if start < 0 else start - 60.0
    # A ROS 2 node of its own, sending the arm 60 deg in 4 s, then killed 1 s in.
    sender = subprocess.Popen([sys.executable, "-m", "busarm.bench.ros_sender", bridge,
                               "base_yaw", str(target), "4"],
                              stdout=subprocess.PIPE, text=True)
    assert sender.stdout is not None and sender.stdout.readline().strip() == "sent"
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start) > 10.0)
    sender.kill()  # mid-trajectory: 4 s to go 60 deg, about 1 s in
    sender.wait()
    time.sleep(1.0)
    stopped = joints_deg(states.latest()[0])["base_yaw"]
    time.sleep(1.0)
    later = joints_deg(states.latest()[0])["base_yaw"]
    assert abs(later - stopped) < 0.5  # it holds ...
    assert abs(stopped - start) < 40.0  # ... well short of where it was sent (60 deg)
    send = peer.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    time.sleep(0.3)
    send.publish(trajectory([(2.0, {"base_yaw": start})]))
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start) < 1.0)


# ------------------------------------------------------------------ busarm on two computers


def truth(peer: RosNode) -> dict[str, Any]:
    """The served twin's ground truth (for tests and benchmarks only)."""
    for reply in peer.session.get("busarm/busarm/truth", timeout=3.0):
        assert reply.ok is not None
        return json.loads(reply.ok.payload.to_bytes())  # type: ignore[no-any-return]
    raise AssertionError("no truth")


def remote(bridge: str) -> str:
    return "zenoh://" + bridge.removeprefix("tcp/")


def test_a_command_on_another_process_moves_the_served_twin(peer: RosNode,
                                                            bridge: str) -> None:
    start = truth(peer)["joints_deg"]
    out = subprocess.run([BUSARM, "--port", remote(bridge), "arm", "move-joints", "30",
                          f"{start[1]:.2f}", f"{start[2]:.2f}", f"{start[3]:.2f}", "0",
                          "--time", "1"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert abs(truth(peer)["joints_deg"][0] - 30.0) < 1.0
    pose = subprocess.run([BUSARM, "--port", remote(bridge), "arm", "pose", "--json"],
                          capture_output=True, text=True, timeout=60)
    assert abs(json.loads(pose.stdout)["joints_deg"]["base_yaw"] - 30.0) < 1.0
    back = subprocess.run([BUSARM, "--port", remote(bridge), "arm", "move-joints",
                           *(f"{v:.2f}" for v in start), "--time", "1"],
                          capture_output=True, text=True, timeout=60)
    assert back.returncode == 0, back.stderr


def test_the_robots_side_refuses_a_position_past_a_limit_and_writes_while_halted(
        peer: RosNode, bridge: str) -> None:
    from busarm.bus.zenoh_link import ZenohTransport
    from busarm.errors import TransportError
    from busarm.protocol import Command
    from busarm.protocol.frames import encode_request

    link = ZenohTransport(peer.session, "busarm", remote(bridge), owns_session=False)
    try:
        before = truth(peer)["joints_deg"][0]
        # The shoulder's servo (2) may go 125..875 pulses: its joint's -180..0 deg.
        with pytest.raises(TransportError, match=r"servo 2 position 1000 refused: allowed "
                                                 r"125\.\.875 pulses"):
            link.write(encode_request(2, Command.MOVE_TIME_WRITE, 1000, 500))
        with pytest.raises(TransportError, match="not whole LX request frames"):
            link.write(b"\x55\x55\x01\x07\x01\xff")
        estop = peer.publisher("/estop", m.EMPTY)
        rearm = peer.publisher("/rearm", m.EMPTY)
        time.sleep(0.3)
        estop.publish(m.message_class(m.EMPTY)())
        time.sleep(0.3)
        with pytest.raises(TransportError, match="halted"):
            link.write(encode_request(1, Command.MOVE_TIME_WRITE, 560, 500))
        link.write(encode_request(254, Command.MOVE_STOP))  # a stop always goes through
        rearm.publish(m.message_class(m.EMPTY)())
        time.sleep(0.6)
        assert abs(truth(peer)["joints_deg"][0] - before) < 0.5  # nothing moved
    finally:
        link.close()


def test_a_remote_client_whose_process_dies_leaves_the_arm_holding(peer: RosNode,
                                                                   bridge: str) -> None:
    start = truth(peer)["joints_deg"]
    mover = subprocess.Popen([BUSARM, "--port", remote(bridge), "arm", "move-joints", "-60",
                              *(f"{v:.2f}" for v in start[1:]), "--time", "4"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    end = time.monotonic() + 20
    while abs(truth(peer)["joints_deg"][0] - start[0]) < 5.0 and time.monotonic() < end:
        time.sleep(0.05)
    mover.kill()  # mid-move: its one command would take the servo on to -60 deg
    mover.wait()
    time.sleep(0.8)
    stopped = truth(peer)["joints_deg"][0]
    time.sleep(1.0)
    assert abs(truth(peer)["joints_deg"][0] - stopped) < 0.3
    assert abs(stopped - start[0]) < 40.0
    back = subprocess.run([BUSARM, "--port", remote(bridge), "arm", "move-joints",
                           *(f"{v:.2f}" for v in start), "--time", "2"],
                          capture_output=True, text=True, timeout=60)
    assert back.returncode == 0, back.stderr


def test_a_recording_is_an_mcap_file_ros_2_tools_read(bridge: str, tmp_path: Path) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out = subprocess.run([BUSARM, "ros", "record", str(tmp_path / "run.mcap"), "--connect",
                          bridge, "--topic", "/joint_states", "--topic", "/tf", "--time",
                          "1.5"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert not list(tmp_path.glob(".*partial"))  # written whole, then renamed
    seen: dict[str, list[Any]] = {}
    with open(tmp_path / "run.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            seen.setdefault(channel.topic, []).append((schema, channel, message, decoded))
    assert set(seen) == {"/joint_states", "/tf"}
    states = seen["/joint_states"]
    schema, channel, _, first = states[0]
    assert len(states) > 20 and list(first.name) == [*NAMES, "gripper"]
    assert schema.name == m.JOINT_STATE and schema.encoding == "ros2msg"
    assert channel.message_encoding == "cdr"
    assert all(a[2].log_time <= b[2].log_time for a, b in itertools.pairwise(states))
    assert f"/joint_states: {len(states)} messages" in out.stdout


# ------------------------------------------------------------------ issue 31: ROS 2 fidelity


def test_rosout_keeps_its_log_for_late_joiners_as_rcl_does(peer: RosNode, bridge: str) -> None:
    rosout = next(e for e in read_graph(peer.session, 0).entities
                  if e.kind == "MP" and e.topic == "/rosout")
    assert rosout.qos == ROSOUT  # rcl's logging QoS, as the token says it
    assert rosout.token().endswith("/:1:,1000:,:10,:,,")  # transient local, 1000, 10 s
    # A line logged now (a refused sample naming a made-up type hash) ...
    live = Inbox(peer, "/rosout", m.ROSOUT_LOG)
    time.sleep(0.3)
    marker = secrets.token_hex(32)
    _put_raw(peer, "/joint_trajectory", m.JOINT_TRAJECTORY, "RIHS01_" + marker,
             m.encode(trajectory([(1.0, {"base_yaw": 0.0})]), m.JOINT_TRAJECTORY),
             Attachment(1, time.time_ns(), b"\x01" * 16).encode())
    live.until(lambda msg: marker[:13] in msg.msg)
    # ... reaches a node that joins after it, subscribing as rmw_zenoh's transient-local
    # subscriptions do (querying the publisher's cache); a volatile one gets none of it.
    session = open_session(connect=[bridge])
    late = RosNode(session, "late_joiner")
    try:
        kept, volatile = queue.Queue[str](), queue.Queue[str]()
        late.subscribe("/rosout", m.ROSOUT_LOG, lambda msg, _: kept.put(msg.msg), ROSOUT)
        late.subscribe("/rosout", m.ROSOUT_LOG, lambda msg, _: volatile.put(msg.msg))
        end = time.monotonic() + 15.0
        while marker[:13] not in kept.get(timeout=max(0.01, end - time.monotonic())):
            pass
        time.sleep(0.5)
        assert all(marker[:13] not in line for line in volatile.queue)
    finally:
        late.close()
        session.close()


def test_a_third_party_senders_trajectory_stops_when_its_token_goes(peer: RosNode) -> None:
    states = Inbox(peer, "/joint_states", m.JOINT_STATE)
    rosout = Inbox(peer, "/rosout", m.ROSOUT_LOG)
    # Another Zenoh SDK's publisher: an rmw_zenoh token, but GIDs of its own making.
    entity = Entity(0, "0123456789abcdef0123456789abcdef", 0, 7, "MP", "third_party",
                    topic="/joint_trajectory", ros_type=m.JOINT_TRAJECTORY,
                    type_hash=m.ros_type(m.JOINT_TRAJECTORY).type_hash, qos=Qos())
    gid = b"\x5a" * 16
    assert gid != gid_of(entity.token())
    token = peer.session.liveliness().declare_token(entity.token())
    publisher = peer.session.declare_publisher(topic_key(
        0, "/joint_trajectory", m.JOINT_TRAJECTORY, m.ros_type(m.JOINT_TRAJECTORY).type_hash))
    try:
        time.sleep(0.5)  # the bridge hears of the token before the trajectory
        start = joints_deg(states.next()[0])["base_yaw"]
        target = start + 60.0 if start < 0 else start - 60.0
        publisher.put(m.encode(trajectory([(4.0, {"base_yaw": target})]), m.JOINT_TRAJECTORY),
                      attachment=Attachment(1, time.time_ns(), gid).encode())
        states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start) > 10.0)
        token.undeclare()  # it leaves about 1 s into 4
        rosout.until(lambda msg: "its sender left" in msg.msg)
        time.sleep(0.5)
        stopped = joints_deg(states.latest()[0])["base_yaw"]
        time.sleep(1.0)
        later = joints_deg(states.latest()[0])["base_yaw"]
        assert abs(later - stopped) < 0.5  # held (MOVE_STOP) ...
        assert abs(stopped - start) < 40.0  # ... well short of the 60 deg it was sent
    finally:
        publisher.undeclare()
    send = peer.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    time.sleep(0.3)
    send.publish(trajectory([(2.0, {"base_yaw": start})]))
    states.until(lambda msg: abs(joints_deg(msg)["base_yaw"] - start) < 1.0)
