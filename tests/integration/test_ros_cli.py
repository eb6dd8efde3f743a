"""`busarm ros ...` refuses what it must before anything opens, and the mobile robot's
bridge: /cmd_vel drives the base until the twists stop, /odom and /scan come out.

Each `busarm ros bridge` serving a twin runs as its own process, on the twin in real time,
and is reached over a loopback Zenoh session, as another computer would reach it. The
commands that only look at or use such a session (refusals, `ros topics`, `ros echo`, a
remote `pick-sort`) run in this process through click's runner: they talk to the bridge
over Zenoh all the same, and open and close their own sessions.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner, Result
from test_ros_bridge import Inbox

from busarm.bench.ros import free_port
from busarm.bus.zenoh_session import open_session
from busarm.cli.main import cli
from busarm.ros import messages as m
from busarm.ros.node import RosNode
from conftest import keep_twin_calibration

pytestmark = [pytest.mark.slow, pytest.mark.wallclock(
    "`busarm ros bridge` processes on a real-time twin, and `busarm ros` clients in this "
    "process, over a loopback Zenoh session")]

BUSARM = str(Path(sys.executable).with_name("busarm"))


def run(*args: str, env: dict[str, str | None] | None = None) -> Result:
    """``busarm ARGS`` in this process, its output captured (``env`` set for the call)."""
    return CliRunner(mix_stderr=False).invoke(cli, list(args), env=env)


def clean(result: Result) -> bool:
    """Whether the command ended as a command does (an exit code), not in a crash."""
    return result.exception is None or isinstance(result.exception, SystemExit)


def test_listening_off_this_computer_needs_a_token() -> None:
    out = run("ros", "bridge", "--listen", "tcp/0.0.0.0:7447", env={"BUSARM_TOKEN": None})
    assert out.exit_code != 0 and clean(out), out.exception
    assert "needs a token: --token SECRET or BUSARM_TOKEN" in out.stderr


def test_a_taken_port_says_what_holds_it() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        out = run("ros", "bridge", "--listen", f"tcp/127.0.0.1:{port}")
    assert out.exit_code != 0 and clean(out), out.exception
    assert f"cannot listen on tcp/127.0.0.1:{port}: that port is taken" in out.stderr


@pytest.mark.parametrize(("args", "says"), [
    (["--listen", "udp/127.0.0.1"], "give tcp/HOST:PORT"),
    (["--listen", "tcp/127.0.0.1:70000"], "allowed: 1..65535"),
    (["--domain", "233"], "0<=x<=232"),
    (["--rate", "500"], "500"),
])
def test_bad_options_are_refused_naming_the_value(args: list[str], says: str) -> None:
    out = run("ros", "bridge", *args)
    assert out.exit_code != 0 and clean(out), out.exception
    assert says in out.stderr


def test_echo_of_a_topic_nobody_publishes_says_so() -> None:
    port = free_port()
    # A lone listener to connect to: nobody publishes anything there.
    lone = open_session(listen=[f"tcp/127.0.0.1:{port}"])
    try:
        out = run("ros", "echo", "/joint_states", "--connect", f"tcp/127.0.0.1:{port}")
    finally:
        lone.close()
    assert out.exit_code != 0 and clean(out), out.exception
    assert "nobody publishes /joint_states on domain 0" in out.stderr


def test_a_token_keeps_out_a_peer_without_it(tmp_path: Path) -> None:
    port = free_port()
    guarded = open_session(listen=[f"tcp/127.0.0.1:{port}"], token="s3cret")
    node = RosNode(guarded, "guarded")
    node.publisher("/chatter", m.STRING)
    try:
        stranger = run("ros", "topics", "--connect", f"tcp/127.0.0.1:{port}",
                       env={"BUSARM_TOKEN": None})
        friend = run("ros", "topics", "--connect", f"tcp/127.0.0.1:{port}",
                     env={"BUSARM_TOKEN": "s3cret"})
    finally:
        node.close()
        guarded.close()
    assert clean(stranger) and clean(friend), (stranger.exception, friend.exception)
    assert "/chatter" not in stranger.stdout and "no ROS 2 topics" in stranger.stdout
    assert "/chatter [std_msgs/msg/String] publishers 1" in friend.stdout


@pytest.fixture(scope="module")
def mobile_bridge(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The mobile robot's twin in an arena, with a saved map (a 2 x 1 m room) to publish.
    Stopped at the end by SIGTERM (what systemd and container runtimes send): as every
    command, one line (the arm held, read back; the wheels stopped) and 143 (issue 30)."""
    import numpy as np

    from busarm.nav.grid import GridSpec, OccupancyGrid
    from busarm.nav.map_files import save_map

    root = tmp_path_factory.mktemp("ros-mobile")
    log_odds = np.full((20, 40), -3.0)
    log_odds[[0, -1], :] = log_odds[:, [0, -1]] = 3.0  # walls round free floor
    save_map(root / "room.yaml", OccupancyGrid(GridSpec(-1.0, -0.5, 0.05, 40, 20), log_odds))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    env = {**os.environ, "XDG_CONFIG_HOME": str(root / "config"),
           "BUSARM_RUNTIME_DIR": str(root / "run")}
    proc = subprocess.Popen([BUSARM, "--port", "board://twin?family=arena&seed=3", "ros",
                             "bridge", "--listen", endpoint, "--no-camera", "--map",
                             str(root / "room.yaml")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stdout is not None
    line = proc.stdout.readline()
    assert "ROS 2 bridge" in line, proc.stderr.read()
    yield endpoint
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 143 and "Traceback" not in err, err
    assert err.splitlines()[-1] == (
        "stopped by SIGTERM: all servos stopped (MOVE_STOP); servos 1-5, 10 holding position "
        "(torque on); the wheels stopped"), err


def test_cmd_vel_drives_the_base_until_the_twists_stop(mobile_bridge: str) -> None:
    session = open_session(connect=[mobile_bridge])
    peer = RosNode(session, "teleop")
    try:
        odom = Inbox(peer, "/odom", m.ODOMETRY)
        scan = Inbox(peer, "/scan", m.LASER_SCAN)
        room = Inbox(peer, "/map", m.OCCUPANCY_GRID).next(timeout_s=15.0)[0]
        assert (room.info.width, room.info.height) == (40, 20) and room.data[0] == 100
        assert room.data[41] == 0  # inside the walls: free
        twist = peer.publisher("/cmd_vel", m.TWIST)
        time.sleep(0.3)
        beams = scan.latest()[0]
        assert len(beams.ranges) == 360 and (beams.ranges < 10).sum() > 30  # walls seen
        x0 = odom.next()[0].pose.pose.position.x
        vec = m.message_class("geometry_msgs/msg/Vector3")
        forward = m.message_class(m.TWIST)(linear=vec(x=0.1, y=0.0, z=0.0),
                                           angular=vec(x=0.0, y=0.0, z=0.0))
        for _ in range(15):  # 1.5 s at 10 Hz, as a teleop node sends
            twist.publish(forward)
            time.sleep(0.1)
        odom.until(lambda msg: msg.pose.pose.position.x - x0 > 0.05)
        time.sleep(1.5)  # no twist for longer than the watchdog's 0.5 s: stopped
        a = odom.latest()[0]
        time.sleep(0.5)
        b = odom.latest()[0]
        assert math.isclose(a.pose.pose.position.x, b.pose.pose.position.x, abs_tol=0.003)
        assert abs(b.twist.twist.linear.x) < 0.01
    finally:
        peer.close()
        session.close()


@pytest.mark.slow
def test_pick_sort_on_another_process_sorts_the_served_table(
        tmp_path: Path, twin_calibration: tuple[Path, Path]) -> None:
    """`busarm --port zenoh://... pick-sort`: the servo bus, the camera, its calibration and
    the bins are the bridge's; the block ends in its bin, as the twin's truth says. The
    bridge is a process of its own; pick-sort runs in this process, reaching it over
    Zenoh."""
    keep_twin_calibration(tmp_path / "config", twin_calibration)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    env = {**os.environ, "XDG_CONFIG_HOME": str(tmp_path / "config")}
    bridge = subprocess.Popen([BUSARM, "ros", "bridge", "--listen", endpoint, "--seed", "3",
                               "--blocks", "1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True, env=env)
    try:
        assert bridge.stdout is not None and "ROS 2 bridge" in bridge.stdout.readline()
        out = run("--port", "zenoh://" + endpoint[4:], "pick-sort",
                  "--report", str(tmp_path / "report"))
        assert out.exit_code == 0, (out.stderr, out.exception)
        assert "sorted 1, failed 0" in out.stdout
        session = open_session(connect=[endpoint])
        try:
            replies = list(session.get("busarm/busarm/truth", timeout=10.0))
            info = list(session.get("busarm/busarm/info", timeout=10.0))
        finally:
            session.close()
        truth = json.loads(replies[0].ok.payload.to_bytes())
        bins = json.loads(info[0].ok.payload.to_bytes())["bins"]
        block = truth["blocks"][0]
        assert math.dist((block["x_mm"], block["y_mm"]), bins[block["color"]]) < 45.0
    finally:
        bridge.send_signal(signal.SIGINT)
        _, err = bridge.communicate(timeout=20)
    assert bridge.returncode == 0 and "Traceback" not in err, err
