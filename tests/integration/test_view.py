"""`busarm view`'s server seen by a WebSocket client speaking Foxglove's protocol
(foxglove.sdk.v1: serverInfo, advertise, subscribe, binary message data), each message
decoded with the protobuf schema its channel advertises and checked against the twin's
truth; the same run recorded into MCAP and read back by `mcap`'s reader with its
protobuf decoder (the latched topics once, however many clients subscribe); the token
relay refusing a client without the token; `busarm record` writing a file only when it is
complete, and finishing it on SIGTERM (exit 143); a port in use refused before the robot
is opened; and the view's failures never ending the job it watches."""

from __future__ import annotations

import asyncio
import base64
import json
import math
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import websockets
from click.testing import CliRunner
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.decoder import DecoderFactory as McapDecoderFactory
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoder
from websockets.exceptions import InvalidStatus

from busarm.apps.navigation.explore import Explorer
from busarm.arm.urdf import urdf_from_config
from busarm.cli.main import cli
from busarm.errors import TransportError
from busarm.lidar.beams import SCAN_BEAMS
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.map_files import trinary_cells
from busarm.robot import Robot
from busarm.robot.frames import arm_frames
from busarm.rotations import quaternion_wxyz
from busarm.view.jobs import explore_hook
from busarm.view.live import TOPICS, RobotView, ViewSettings
from busarm.view.recording import McapRecording
from busarm.view.server import SUBPROTOCOL, URDF_ASSET, is_loopback, serve_view
from conftest import not_crashed

pytestmark = pytest.mark.wallclock(
    "a real-time twin watched through a real WebSocket server on 127.0.0.1")

ARENA = "board://twin?family=arena&seed=3&realtime=1"
POSE_DEG = (20.0, -60.0, 90.0, -30.0, 15.0)
"""Where the arm is sent before it is watched: every joint away from zero."""
TIMEOUT_S = 20.0  # generous: a busy computer is late, and only a failing test waits it out


def message_classes(channels: list[dict[str, Any]]) -> dict[int, Any]:
    """Each protobuf channel's message class, made from the schema it advertises (a
    base64 FileDescriptorSet), as a client that knows no Foxglove types would."""
    out = {}
    for c in channels:
        if c["encoding"] != "protobuf":
            continue
        assert c["schemaEncoding"] == "protobuf"
        files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(c["schema"]))
        pool = descriptor_pool.DescriptorPool()
        for f in files.file:
            pool.Add(f)
        out[c["id"]] = message_factory.GetMessageClass(
            pool.FindMessageTypeByName(c["schemaName"]))
    return out


def watch(url: str, want: set[str]) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """``_watch`` within a minute in all (a test fails, it does not hang)."""
    return asyncio.run(asyncio.wait_for(_watch(url, want), 60.0))


async def _watch(url: str, want: set[str]) -> tuple[dict[str, Any], dict[str, Any], Any]:
    """Connect, read the channels advertised, subscribe to all, and take the first
    message of each of ``want`` (decoded); also ask for the URDF as a parameter and as an
    asset.
    Returns (advertised channels by topic, first message by topic, extras)."""
    async with websockets.connect(url, subprotocols=[SUBPROTOCOL], max_size=None,
                                  open_timeout=TIMEOUT_S) as ws:
        info = json.loads(await asyncio.wait_for(ws.recv(), TIMEOUT_S))
        assert info["op"] == "serverInfo" and "parameters" in info["capabilities"]
        channels: dict[int, dict[str, Any]] = {}
        while not want <= {c["topic"] for c in channels.values()}:
            msg = json.loads(await asyncio.wait_for(ws.recv(), TIMEOUT_S))
            if msg["op"] == "advertise":
                channels |= {c["id"]: c for c in msg["channels"]}
        classes = message_classes(list(channels.values()))
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": 100 + cid, "channelId": cid} for cid in channels]}))
        await ws.send(json.dumps({"op": "getParameters", "id": "urdf",
                                  "parameterNames": ["/robot_description"]}))
        await ws.send(json.dumps({"op": "fetchAsset", "uri": URDF_ASSET, "requestId": 7}))
        first: dict[str, Any] = {}
        extras: dict[str, Any] = {}
        while not want <= set(first) or len(extras) < 2:
            data = await asyncio.wait_for(ws.recv(), TIMEOUT_S)
            if isinstance(data, str):
                msg = json.loads(data)
                if msg["op"] == "parameterValues":
                    extras["parameter"] = msg["parameters"]
                continue
            if data[0] == 0x04:  # fetchAsset response: id, status, error length, ...
                request, status, error_len = struct.unpack_from("<IBI", data, 1)
                extras["asset"] = (request, status, data[10 + error_len:])
                continue
            assert data[0] == 0x01  # message data: subscription id, log time ns, payload
            sub, _ = struct.unpack_from("<IQ", data, 1)
            channel = channels[sub - 100]
            payload = data[13:]
            first.setdefault(channel["topic"], json.loads(payload)
                             if channel["encoding"] == "json"
                             else classes[channel["id"]].FromString(payload))
        return {c["topic"]: c for c in channels.values()}, first, extras


@pytest.fixture(scope="module")
def arena_robot(tmp_path_factory: pytest.TempPathFactory,
                twin_calibration: tuple[Path, Path]) -> Iterator[Robot]:
    """The mobile robot's twin in real time, its arm at POSE_DEG (calibrated camera)."""
    from busarm.robot import CameraSpec, RobotConfig
    from busarm.robot.port_url import parse_port

    folder = tmp_path_factory.mktemp("calibration")
    for f in twin_calibration:
        (folder / f.name).write_bytes(f.read_bytes())
    with Robot.open(RobotConfig(parse_port(ARENA), camera=CameraSpec(folder=folder))) as robot:
        robot.arm.move_joints(POSE_DEG, duration_s=1.0)
        yield robot


def test_every_channel_over_foxglove_websocket_and_mcap(arena_robot: Robot,
                                                       tmp_path: Path) -> None:
    robot = arena_robot
    log_odds = np.zeros((30, 40))
    log_odds[5:10, 3:8] = 3.0  # occupied
    log_odds[12:20, :] = -3.0  # free
    grid = OccupancyGrid(GridSpec(-1.0, -2.0, 0.05, 40, 30), log_odds)
    view = RobotView(robot, ViewSettings(state_hz=20.0, camera_fps=4.0))
    recording = McapRecording(view, tmp_path / "run.mcap")
    server = serve_view(view.start(), "127.0.0.1", 0)
    try:
        view.show_map(grid)
        view.show_path([(0.0, 0.0), (1.0, 0.5)], [(0.0, 0.0), (0.2, 0.1)],
                       {"pick": (1.0, 0.5)})
        assert server.token is None and server.url.startswith("ws://127.0.0.1:")
        channels, first, extras = watch(server.url, set(TOPICS))
        # A second client gets the latched topics too (sent again to the live clients
        # only: the recording keeps each once).
        _, again, _ = watch(server.url, {"/robot_description", "/map", "/path"})
    finally:
        server.stop()
        view.close()
        path = recording.close()
    # A real-time twin on a loaded computer may miss a reply now and then: the view says
    # so and goes on (its channels below all came); nothing else may have gone wrong.
    assert all("no answer in 3 attempts" in e for e in view.errors), view.errors
    assert {t: c["schemaName"] for t, c in channels.items()} == {
        "/tf": "foxglove.FrameTransforms", "/joint_states": "foxglove.JointStates",
        "/robot_description": "std_msgs/msg/String",
        "/wrist_camera/compressed": "foxglove.CompressedImage",
        "/wrist_camera/calibration": "foxglove.CameraCalibration",
        "/blocks": "foxglove.SceneUpdate", "/scan": "foxglove.LaserScan",
        "/map": "foxglove.Grid", "/path": "foxglove.SceneUpdate"}
    check_messages(robot, grid, first)
    check_grid(again["/map"], grid)
    assert again["/robot_description"] == first["/robot_description"]
    urdf = urdf_from_config(robot.config)
    assert extras["parameter"] == [{"name": "/robot_description", "value": urdf}]
    assert extras["asset"] == (7, 0, urdf.encode())
    check_mcap(path, grid)


def check_messages(robot: Robot, grid: OccupancyGrid, first: dict[str, Any]) -> None:
    """Each topic's first message against the twin's truth."""
    truth_deg = robot.arm.read_joints_deg()
    assert np.allclose(truth_deg, POSE_DEG, atol=1.5)
    joints = {j.name: j.position for j in first["/joint_states"].joints}
    for j, deg in zip(robot.config.joints, truth_deg, strict=True):
        assert math.degrees(joints[j.name]) == pytest.approx(deg, abs=1.0)
    assert 0.0 < joints["gripper"] < 0.2  # the fingers' gap, m
    tf = {(t.parent_frame_id, t.child_frame_id): t for t in first["/tf"].transforms}
    cal = robot.camera_calibration
    assert cal is not None
    for parent, child, matrix in arm_frames(robot.config, robot.arm.kin, truth_deg,
                                            cal.hand_eye.cam2link):
        got = tf[(parent, child)]
        assert [got.translation.x, got.translation.y, got.translation.z] == pytest.approx(
            matrix[:3, 3], abs=0.003)
        w, x, y, z = quaternion_wxyz(matrix[:3, :3])  # the joint's angle is in the rotation
        r = got.rotation
        assert abs(w * r.w + x * r.x + y * r.y + z * r.z) == pytest.approx(1.0, abs=1e-4)
    assert robot.base is not None
    odom = tf[("odom", "base_footprint")]
    pose = robot.base.odometry().pose  # the base stands still: the odometry's pose now
    assert (odom.translation.x, odom.translation.y) == pytest.approx((pose.x_m, pose.y_m),
                                                                     abs=0.01)
    assert 2 * math.atan2(odom.rotation.z, odom.rotation.w) == pytest.approx(pose.yaw_rad,
                                                                             abs=0.01)
    scan = first["/scan"]
    assert len(scan.ranges) == SCAN_BEAMS and scan.frame_id == "laser"
    assert scan.start_angle == pytest.approx(-math.pi)
    seen = [r for r in scan.ranges if math.isfinite(r)]
    assert len(seen) > SCAN_BEAMS / 2 and all(0.05 < r < 13.0 for r in seen)  # a room
    image = cv2.imdecode(np.frombuffer(first["/wrist_camera/compressed"].data, np.uint8),
                         cv2.IMREAD_COLOR)
    assert first["/wrist_camera/compressed"].format == "jpeg" and image.shape == (480, 640, 3)
    info = first["/wrist_camera/calibration"]
    assert (info.width, info.height) == (640, 480)
    assert list(info.K) == pytest.approx(np.ravel(cal.intrinsics.camera_matrix))
    assert first["/blocks"].deletions[0].type == 1  # ALL: the blocks drawn before go
    check_grid(first["/map"], grid)
    lines = first["/path"].entities[0].lines
    assert [(p.x, p.y) for p in lines[0].points] == [(0.0, 0.0), (1.0, 0.5)]
    assert first["/path"].entities[0].texts[0].text == "pick"
    assert first["/robot_description"] == {"data": urdf_from_config(robot.config)}


def check_grid(got: Any, grid: OccupancyGrid) -> None:
    s = grid.spec
    assert (got.column_count, got.row_stride, got.cell_stride) == (s.width, s.width, 1)
    assert (got.pose.position.x, got.pose.position.y) == (s.origin_x_m, s.origin_y_m)
    assert got.cell_size.x == pytest.approx(s.resolution_m)
    cells = np.frombuffer(got.data, np.int8).reshape(s.height, s.width)
    assert np.array_equal(cells, trinary_cells(grid))
    assert cells[6, 4] == 100 and cells[15, 0] == 0 and cells[0, 0] == -1


class JsonDecoder(McapDecoderFactory):
    """mcap's decoder for JSON messages (the URDF's channel)."""

    def decoder_for(self, message_encoding: str, schema: Any) -> Callable[[bytes], Any] | None:
        return json.loads if message_encoding == "json" else None


def decoders() -> list[McapDecoderFactory]:
    """New for each file: the protobuf factory keeps its decoders by the file's schema id."""
    return [ProtobufDecoder(), JsonDecoder()]


def check_mcap(path: Path, grid: OccupancyGrid) -> None:
    """Every channel of the run in the file, each message decoded by the decoder of its
    encoding: protobuf by mcap-protobuf-support's, the URDF's JSON by json's."""
    assert not list(path.parent.glob(".*"))  # no temporary file left
    counts: dict[str, int] = {}
    last: dict[str, Any] = {}
    with open(path, "rb") as f:
        for schema, channel, _, decoded in make_reader(
                f, decoder_factories=decoders()).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            last[channel.topic] = decoded
            assert schema is not None and schema.encoding in ("protobuf", "jsonschema")
    assert set(counts) == set(TOPICS)
    assert counts["/tf"] >= 5
    # Given once, at the file's start or when shown, however many clients subscribed.
    assert [counts[t] for t in ("/robot_description", "/map", "/path")] == [1, 1, 1]
    check_grid(last["/map"], grid)
    assert len(last["/scan"].ranges) == SCAN_BEAMS
    assert last["/robot_description"]["data"].startswith("<?xml")
    assert last["/path"].entities[0].texts[0].text == "pick"


def test_token_relay_refuses_a_client_without_the_token(arena_robot: Robot) -> None:
    view = RobotView(arena_robot, ViewSettings(camera=False, state_hz=5.0))
    token = "t" * 8 + "0123456789abcdef"
    server = serve_view(view.start(), "127.0.0.1", 0, token)
    try:
        assert server.relay is not None and server.url.endswith(f"/?token={token}")
        bare = server.url.split("/?")[0]
        for url, why in ((bare, "a token is required"), (f"{bare}/?token=wrong", "wrong")):
            with pytest.raises(InvalidStatus) as refused:
                watch(url, {"/tf"})
            assert refused.value.response.status_code == 401
            assert why in refused.value.response.body.decode()
        assert server.relay.refused == 2
        channels, first, _ = watch(server.url, {"/tf", "/scan", "/robot_description"})
        assert set(channels) == set(view.topics)
        assert len(first["/tf"].transforms) >= 9  # through the relay, decoded
        assert len(first["/scan"].ranges) == SCAN_BEAMS
    finally:
        server.stop()
        view.close()
    assert not is_loopback("0.0.0.0") and is_loopback("::1") and is_loopback("localhost")


def test_view_refuses_a_short_token_and_record_writes_when_complete(tmp_path: Path) -> None:
    runner = CliRunner(mix_stderr=False)
    short = runner.invoke(cli, ["view", "--bind", "0.0.0.0", "--token", "short"])
    assert short.exit_code == 2 and "--token of 5 characters" in short.stderr
    out = tmp_path / "table.mcap"
    done = runner.invoke(cli, ["record", str(out), "--seconds", "1.5", "--no-camera",
                               "--rate", "10"])
    not_crashed(done)
    assert done.exit_code == 0, done.output
    assert out.exists() and not list(tmp_path.glob(".*"))
    assert "/tf: " in done.stdout and "recorded " in done.stderr
    with open(out, "rb") as f:
        topics = {c.topic for _, c, _, _ in make_reader(
            f, decoder_factories=decoders()).iter_decoded_messages()}
    assert topics == {"/tf", "/joint_states", "/robot_description"}  # no camera, no base


def test_a_map_build_recorded_for_foxglove(tmp_path: Path) -> None:
    """`busarm map build --mcap`: the map as it grew and the path driven are in the file,
    in the map's frame."""
    runner = CliRunner(mix_stderr=False)
    out = tmp_path / "build.mcap"
    done = runner.invoke(cli, ["map", "build", "--arena", "1", "--time", "12", "--out",
                               str(tmp_path / "map.yaml"), "--mcap", str(out)])
    not_crashed(done)
    assert done.exit_code == 0, done.output
    counts: dict[str, int] = {}
    last: dict[str, Any] = {}
    with open(out, "rb") as f:
        for _, channel, _, decoded in make_reader(
                f, decoder_factories=decoders()).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            last[channel.topic] = decoded
    assert {"/map", "/path", "/scan", "/tf"} <= set(counts), counts
    assert counts["/map"] >= 2 and counts["/path"] >= 2  # as the map grew
    assert last["/map"].frame_id == "map" and last["/path"].entities[0].frame_id == "map"


def test_the_views_failures_never_end_the_job_it_watches(arena_robot: Robot,
                                                         tmp_path: Path) -> None:
    """A map build whose view fails at every map it is given (a sink that refuses it)
    explores on to its time limit, the error noted once; and the view's own /tf goes on
    past odometry reads that fail (each skips one tick)."""
    with Robot.open("board://twin?family=arena&seed=1") as robot:  # simulated time
        view = RobotView(robot, ViewSettings(camera=False))
        refused: list[OccupancyGrid] = []

        def refusing_sink(grid: OccupancyGrid) -> None:
            refused.append(grid)
            raise RuntimeError("FoxgloveError: the sink is gone")

        view.show_map = refusing_sink  # type: ignore[method-assign]
        run = Explorer(robot, time_limit_s=5.0, on_scan=explore_hook(view)).run()
    assert run.finished == "the time limit (5 s)" and run.scans >= 20
    assert len(refused) >= 2  # tried each time it was due, refused each time
    assert view.errors == ["a job's view: RuntimeError: FoxgloveError: the sink is gone"]

    base = arena_robot.base
    assert base is not None
    read_odometry, failures = base.odometry, [3]

    def odometry_failing_thrice() -> Any:
        if failures[0] > 0:
            failures[0] -= 1
            raise TransportError("the board did not answer")
        return read_odometry()

    base.odometry = odometry_failing_thrice  # type: ignore[method-assign]
    watched = RobotView(arena_robot, ViewSettings(camera=False, state_hz=20.0))
    recording = McapRecording(watched, tmp_path / "tf.mcap")  # counts what is logged
    try:
        with watched:
            deadline = time.monotonic() + TIMEOUT_S
            while time.monotonic() < deadline and watched.counts.get("/tf", 0) < 3:
                time.sleep(0.05)
            # A scan's stamp: when its revolution began (the robot's clock), on the view's
            # timeline; one from long ago (a clock gone wrong) is stamped now.
            began_s = arena_robot.clock.now() - 0.1
            assert watched.stamp_at(began_s) == pytest.approx(watched.now_s() - 0.1, abs=0.05)
            assert watched.stamp_at(began_s - 60.0) == pytest.approx(watched.now_s(), abs=0.05)
    finally:
        del base.odometry  # the Base's own again
        recording.close()
    assert failures[0] == 0 and watched.counts["/tf"] >= 3 and watched.failure is None
    assert watched.errors == [
        "joint states or odometry not read: the board did not answer"]


def test_a_port_in_use_is_refused_before_the_robot_is_opened(tmp_path: Path) -> None:
    """`transport --foxglove PORT --mcap FILE` on a port another program listens on: one
    error naming --foxglove, exit 2, at once (no twin opened: that takes seconds), and
    no file; `view --ws-port` the same."""
    runner = CliRunner(mix_stderr=False)
    with socket.socket() as held:
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        out = tmp_path / "t.mcap"
        started = time.monotonic()
        job = runner.invoke(cli, ["transport", "--foxglove", str(port), "--mcap", str(out)])
        took_s = time.monotonic() - started
        served = runner.invoke(cli, ["view", "--ws-port", str(port)])
    for result, option in ((job, "--foxglove"), (served, "--ws-port")):
        not_crashed(result)
        assert result.exit_code == 2 and result.stdout == "", result.output
        assert result.stderr == (f"error: 127.0.0.1:{port} is in use (give another {option}, "
                                 "or 0 for any free port)\n")
    assert took_s < 10.0  # generous: opening the arena's twin alone takes longer
    assert list(tmp_path.iterdir()) == []


def test_record_finishes_its_file_on_sigterm(tmp_path: Path) -> None:
    """`busarm record` is a job: SIGTERM finishes the file, says what it holds in the one
    line that reports the stop, and exits 143."""
    out = tmp_path / "table.mcap"
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "record", str(out), "--seconds", "30",
         "--no-camera", "--rate", "10"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert proc.stderr is not None
        assert proc.stderr.readline().startswith("recording /tf, /joint_states, ")
        time.sleep(0.5)  # a few messages in
        proc.send_signal(signal.SIGTERM)
        printed, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert re.fullmatch(r"stopped by SIGTERM: nothing was written to the servos; recorded "
                        rf"\d+ messages on 3 channels into {re.escape(str(out))}\n", err), err
    assert "/robot_description: 1 message\n" in printed
    counts: dict[str, int] = {}
    with open(out, "rb") as f:
        for _, channel, _, _ in make_reader(
                f, decoder_factories=decoders()).iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert set(counts) == {"/tf", "/joint_states", "/robot_description"}
    assert printed == "".join(f"{t}: {n} message{'s' if n > 1 else ''}\n"
                              for t, n in sorted(counts.items()))
    assert list(tmp_path.iterdir()) == [out]  # no temporary file left
