"""``busarm bench ros``: the ROS 2 bridge between two busarm processes on loopback.

A bridge (``busarm ros bridge``, the twin in real time) runs in a process of its own;
this process joins its Zenoh session as a ROS 2 node would, and measures against the
twin's ground truth (served to benchmarks only, ``busarm/<robot>/truth``):

- /joint_states' rate and latency (its header stamp, taken when the servos were read, to
  its arrival here), the camera's frames a second, /tf's rate;
- a trajectory sent here moving the twin there, its joints never past their limits;
- the link of a sender (a process of its own) dropped mid-trajectory, by killing it and
  by freezing a TCP proxy it talks through (a cable pulled: no FIN, no RST): the time
  from the drop until the twin's joints stand still;
- malformed CDR, a wrong type hash, a flood of trajectories: dropped or handled, nothing
  past the limits, the bridge still publishing;
- ``busarm --port zenoh://... pick-sort`` on the bridge's twin, recorded into an MCAP file
  that mcap-ros2-support reads back, against the same table sorted in one process.
"""

from __future__ import annotations

import json
import math
import os
import queue
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from busarm.bench.common import latency_percentiles_ms, machine_info
from busarm.bench.ros_sender import one_point_trajectory
from busarm.bus.zenoh_link import ZenohPort
from busarm.bus.zenoh_session import open_session
from busarm.errors import BusArmError
from busarm.progress import Progress, quiet
from busarm.protocol.rmw_zenoh import Attachment, topic_key
from busarm.robot.port_url import port_text
from busarm.robot.remote import ask
from busarm.ros import messages as m
from busarm.ros.node import Received, RosNode
from busarm.ros.recorder import McapRecorder

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "BUSARM",
    "JOINT",
    "STILL_DEG",
    "FrozenLink",
    "RosBenchReport",
    "Truth",
    "dropped_client",
    "dropped_sender",
    "faults",
    "free_port",
    "in_bins",
    "move",
    "pick_sort",
    "read_mcap",
    "run_ros_bench",
    "running_bridge",
    "stop_time_ms",
    "stream_rates",
]


BUSARM = str(Path(sys.executable).with_name("busarm"))
JOINT = "base_yaw"
STILL_DEG = 0.1
"""A joint whose true angle moves less than this from here on stands still."""


@dataclass
class RosBenchReport:
    machine: dict[str, str] = field(default_factory=machine_info)
    seconds: float = 0.0
    joint_states_hz: float = 0.0
    joint_states_latency_ms: dict[str, float] = field(default_factory=dict)
    tf_hz: float = 0.0
    camera_fps: float = 0.0
    trajectory_error_deg: float = math.nan
    beyond_limits_deg: float = 0.0
    """The most any true joint angle went past its limit during the whole run (0: never)."""
    stop_after_kill_ms: list[float] = field(default_factory=list)
    stop_after_freeze_ms: list[float] = field(default_factory=list)
    client_stop_after_freeze_ms: list[float] = field(default_factory=list)
    """A remote busarm (``--port zenoh://``) whose link froze mid-move."""
    travel_at_drop_deg: list[float] = field(default_factory=list)
    """How far the joint had gone when each link dropped (of 60 deg in 4 s)."""
    faults: dict[str, Any] = field(default_factory=dict)
    pick_remote: dict[str, Any] = field(default_factory=dict)
    pick_local: dict[str, Any] = field(default_factory=dict)
    mcap: dict[str, Any] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def faults_handled(self) -> bool:
        """Every bad sample dropped and said, none moving anything; the flood's last
        trajectory carried out."""
        f = self.faults
        return bool(f) and (f["malformed_said"] == f["malformed_sent"]
                            and f["wrong_hash_said"] == f["wrong_hash_sent"]
                            and f["moved_by_bad_deg"] < 0.5
                            and f["last_of_flood_error_deg"] <= 1.0)

    @property
    def pick_same(self) -> bool:
        """Over zenoh:// as in one process: every block sorted, and truly in its bin."""
        r, local = self.pick_remote, self.pick_local
        return bool(r) and (r.get("sorted") == local.get("sorted") == local.get("blocks")
                            and r.get("in_bins_truth") == r.get("sorted"))

    def text(self, ok: Callable[[bool], str]) -> str:
        """The report for a person, each target judged by ``ok`` (ok or FAIL)."""
        lat, f = self.joint_states_latency_ms, self.faults
        p50, p99, worst = (lat.get(k, math.nan) for k in ("p50", "p99", "max"))
        kill = max(self.stop_after_kill_ms, default=math.nan)
        frozen = max(self.stop_after_freeze_ms, default=math.nan)
        client = max(self.client_stop_after_freeze_ms, default=math.nan)
        travel = min(self.travel_at_drop_deg, default=0.0)
        decoded = self.mcap.get("decoded", {})
        return "\n".join([
            f"two busarm processes on loopback ({self.machine['cpu']}, "
            f"{self.machine['cores']} cores): the bridge on the twin in real time",
            f"/joint_states {self.joint_states_hz:.1f} Hz ({ok(self.joint_states_hz >= 50)} "
            f">= 50); latency from the servos' reading p50 {p50:.1f} ms, p99 {p99:.1f} ms "
            f"({ok(p99 <= 10)} <= 10), max {worst:.1f} ms; /tf {self.tf_hz:.1f} Hz",
            f"camera {self.camera_fps:.1f} frames/s ({ok(self.camera_fps >= 15)} >= 15)",
            f"a trajectory sent here, the twin there: {self.trajectory_error_deg:.2f} deg "
            f"from its goal ({ok(self.trajectory_error_deg <= 1.0)} <= 1); no joint past "
            f"its limit by more than {self.beyond_limits_deg:.3f} deg in the whole run "
            f"({ok(self.beyond_limits_deg <= 0.24)} <= one pulse, 0.24)",
            f"a link dropped mid-move ({travel:.0f}+ deg of 60 done), the joint still within: "
            f"a ROS sender killed {kill:.0f} ms, its cable 'pulled' (a frozen proxy) "
            f"{frozen:.0f} ms; a busarm on zenoh://, its cable pulled {client:.0f} ms "
            f"({ok(max(kill, frozen, client) <= 300)} <= 300)",
            f"faults: {f.get('malformed_said')}/{f.get('malformed_sent')} malformed and "
            f"{f.get('wrong_hash_said')}/{f.get('wrong_hash_sent')} wrong-hash samples "
            f"dropped and said on /rosout, moving {f.get('moved_by_bad_deg')} deg; a flood "
            f"of {f.get('flood')} trajectories ({f.get('flood_sent_per_s')}/s): the last in "
            f"charge ({f.get('last_of_flood_error_deg')} deg off), /joint_states after it "
            f"{f.get('joint_states_hz_after')} Hz ({ok(self.faults_handled)})",
            f"pick-sort over zenoh://: {self.pick_remote.get('summary', '?')}; "
            f"{self.pick_remote.get('in_bins_truth')} truly in their bins; in one process: "
            f"{self.pick_local.get('summary', '?')} ({ok(self.pick_same)} the same)",
            f"MCAP of the remote run: {sum(decoded.values())} messages on {len(decoded)} "
            f"topics, each decoded by mcap-ros2-support "
            f"({ok(decoded.get('/joint_states', 0) > 0)}): {self.mcap.get('file', '?')}",
        ])


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def running_bridge(endpoint: str, seed: int, blocks: int,
                   progress: Progress) -> Iterator[subprocess.Popen[str]]:
    """``busarm ros bridge`` on the twin in a process of its own, until the block ends."""
    proc = subprocess.Popen([BUSARM, "ros", "bridge", "--listen", endpoint, "--seed",
                             str(seed), "--blocks", str(blocks)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        if "ROS 2 bridge" not in line:
            raise BusArmError(f"the bridge did not start: {proc.communicate()[1][-2000:]}")
        progress(line.strip())
        yield proc
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()


class Truth:
    """The twin's ground truth, asked of the bridge's process; every answer is kept."""

    def __init__(self, session: zenoh.Session, limits: list[tuple[float, float]]) -> None:
        self.session = session
        self.limits = limits
        self.beyond_deg = 0.0

    def now(self) -> dict[str, Any]:
        truth = ask(self.session, "busarm", "truth", timeout_s=2.0)
        for (lo, hi), q in zip(self.limits, truth["joints_deg"], strict=False):
            self.beyond_deg = max(self.beyond_deg, lo - q, q - hi)
        return truth

    def joint(self) -> float:
        return float(self.now()["joints_deg"][0])

    def samples(self, seconds: float, period_s: float = 0.01) -> list[tuple[float, float]]:
        """(monotonic time, true base_yaw) every ``period_s`` for ``seconds``."""
        out = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            out.append((time.monotonic(), self.joint()))
            time.sleep(period_s)
        return out

    def settle(self, target_deg: float, timeout_s: float = 8.0) -> float:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if abs(self.joint() - target_deg) < 0.5:
                break
            time.sleep(0.05)
        return abs(self.joint() - target_deg)


def _rate(arrivals: list[float]) -> float:
    """Messages a second, from the first arrival to the last (not the window's edges)."""
    if len(arrivals) < 2 or arrivals[-1] <= arrivals[0]:
        return 0.0
    return (len(arrivals) - 1) / (arrivals[-1] - arrivals[0])


def stream_rates(node: RosNode, seconds: float) -> tuple[float, dict[str, float], float, float]:
    """(/joint_states Hz, its latency percentiles in ms, /tf Hz, camera frames/s)."""
    latencies: list[float] = []
    arrivals: dict[str, list[float]] = {"states": [], "tf": [], "image": []}

    def on_state(msg: Any, rec: Received) -> None:
        latencies.append(rec.received_ns / 1e9 - m.stamp_s(msg.header.stamp))
        arrivals["states"].append(rec.received_ns / 1e9)

    def counter(name: str) -> Callable[[Any, Received], None]:
        return lambda msg, rec: arrivals[name].append(rec.received_ns / 1e9)

    subs = [node.subscribe("/joint_states", m.JOINT_STATE, on_state),
            node.subscribe("/tf", m.TF_MESSAGE, counter("tf"), decoded=False),
            node.subscribe("/wrist_camera/image_raw", m.IMAGE, counter("image"),
                           decoded=False)]
    time.sleep(seconds)
    for sub in subs:
        sub.close()
    return (_rate(arrivals["states"]), latency_percentiles_ms(latencies or [math.nan]),
            _rate(arrivals["tf"]), _rate(arrivals["image"]))


def stop_time_ms(samples: list[tuple[float, float]], dropped_at: float) -> float:
    """When the joint stood still after the drop: the first sample from which on it stays
    within STILL_DEG of where it ends (an upper bound, to the sampling period)."""
    final = samples[-1][1]
    still_from = samples[0][0]
    for t, q in samples:
        if abs(q - final) > STILL_DEG:
            still_from = t  # moving here: still only after a later sample
    later = [t for t, _ in samples if t > still_from]
    first_still = later[0] if later and any(abs(q - final) > STILL_DEG for _, q in samples) \
        else samples[0][0]
    return max(0.0, (first_still - dropped_at) * 1e3)


class FrozenLink:
    """A TCP proxy to ``target``: ``freeze()`` stops every byte both ways and keeps the
    sockets open, as a pulled cable does (no FIN, no RST: only a lease notices)."""

    def __init__(self, target_port: int) -> None:
        self.port = free_port()
        self.frozen = threading.Event()
        self._server = socket.create_server(("127.0.0.1", self.port))
        self._target = target_port
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._server.accept()
            except OSError:
                return
            upstream = socket.create_connection(("127.0.0.1", self._target))
            for a, b in ((client, upstream), (upstream, client)):
                threading.Thread(target=self._pump, args=(a, b), daemon=True).start()

    def _pump(self, src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(65536):
                while self.frozen.is_set():
                    time.sleep(0.05)
                dst.sendall(data)
        except OSError:
            pass

    def freeze(self) -> None:
        self.frozen.set()

    def close(self) -> None:
        self._server.close()


def dropped_sender(endpoint: str, truth: Truth, *, freeze: bool) -> tuple[float, float]:
    """Send base_yaw 60 deg in 4 s from a process of its own, drop its link 1 s in (kill
    it, or freeze its proxy): how long the twin's joint kept moving (ms), and how far it
    had gone when the link dropped (deg: it was mid-way, moving)."""
    start = truth.joint()
    target = start + 60.0 if start < 0 else start - 60.0
    proxy = FrozenLink(int(endpoint.rsplit(":", 1)[1])) if freeze else None
    via = f"tcp/127.0.0.1:{proxy.port}" if proxy is not None else endpoint
    sender = subprocess.Popen([sys.executable, "-m", "busarm.bench.ros_sender", via, JOINT,
                               str(target), "4"], stdout=subprocess.PIPE, text=True)
    try:
        assert sender.stdout is not None
        sender.stdout.readline()
        time.sleep(1.0)
        travelled = abs(truth.joint() - start)
        dropped_at = time.monotonic()
        if proxy is not None:
            proxy.freeze()
        else:
            sender.kill()
        samples = truth.samples(1.5)
    finally:
        sender.kill()
        sender.wait()
        if proxy is not None:
            proxy.close()
    return stop_time_ms(samples, dropped_at), travelled


def dropped_client(endpoint: str, truth: Truth) -> tuple[float, float]:
    """``busarm --port zenoh://...`` moving base_yaw 60 deg in 4 s (one timed move: the
    servo would go on alone), its link frozen 1 s in: how long the joint kept moving
    (ms), and how far it had gone (deg)."""
    joints = truth.now()["joints_deg"]
    target = joints[0] + 60.0 if joints[0] < 0 else joints[0] - 60.0
    proxy = FrozenLink(int(endpoint.rsplit(":", 1)[1]))
    mover = subprocess.Popen([BUSARM, "--port", port_text(ZenohPort("127.0.0.1", proxy.port)),
                              "arm",
                              "move-joints", f"{target:.2f}",
                              *(f"{q:.2f}" for q in joints[1:]), "--time", "4"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        end = time.monotonic() + 20.0
        while abs(truth.joint() - joints[0]) < 10.0 and time.monotonic() < end:
            time.sleep(0.01)
        travelled = abs(truth.joint() - joints[0])
        dropped_at = time.monotonic()
        proxy.freeze()
        samples = truth.samples(1.5)
    finally:
        mover.kill()
        mover.wait()
        proxy.close()
    return stop_time_ms(samples, dropped_at), travelled


def move(node: RosNode, truth: Truth, target_deg: float, seconds: float) -> float:
    """Send base_yaw to ``target_deg`` and wait for it; the error left (deg)."""
    pub = node.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    time.sleep(0.3)
    pub.publish(one_point_trajectory(JOINT, target_deg, seconds))
    error = truth.settle(target_deg, timeout_s=seconds + 5.0)
    pub.close()
    return error


def faults(node: RosNode, truth: Truth, flood: int) -> dict[str, Any]:
    """Malformed CDR, a wrong type hash, a flood of trajectories: what became of them."""
    rosout: queue.Queue[str] = queue.Queue()
    log = node.subscribe("/rosout", m.ROSOUT_LOG, lambda msg, rec: rosout.put(msg.msg))
    session, good = node.session, m.ros_type(m.JOINT_TRAJECTORY).type_hash
    attachment = Attachment(1, time.time_ns(), b"\x07" * 16).encode()
    time.sleep(1.0)  # the bridge learns of this /rosout subscriber before it is needed
    start = truth.joint()
    for k in range(10):
        session.put(topic_key(0, "/joint_trajectory", m.JOINT_TRAJECTORY, good),
                    b"\x00\x01\x00\x00" + bytes([k]) * 40, attachment=attachment)
        session.put(topic_key(0, "/joint_trajectory", m.JOINT_TRAJECTORY, "RIHS01_" + "0" * 64),
                    m.encode(one_point_trajectory(JOINT, start + 30, 1.0), m.JOINT_TRAJECTORY),
                    attachment=attachment)
    time.sleep(1.0)
    moved_by_bad = abs(truth.joint() - start)
    said = []
    while not rosout.empty():
        said.append(rosout.get())
    pub = node.publisher("/joint_trajectory", m.JOINT_TRAJECTORY)
    time.sleep(0.3)
    t0 = time.monotonic()
    for k in range(flood):
        pub.publish(one_point_trajectory(JOINT, start + (10.0 if k % 2 else -10.0), 1.0))
    flood_s = time.monotonic() - t0
    final = start + (10.0 if (flood - 1) % 2 else -10.0)
    error = truth.settle(final)
    alive, _, _, _ = stream_rates(node, 1.0)
    pub.close()
    log.close()
    back = move(node, truth, start, 1.0)
    return {"malformed_sent": 10, "wrong_hash_sent": 10,
            "malformed_said": sum("malformed" in s for s in said),
            "wrong_hash_said": sum("RIHS01_0000" in s for s in said),
            "moved_by_bad_deg": round(moved_by_bad, 2), "flood": flood,
            "flood_sent_per_s": round(flood / flood_s), "last_of_flood_error_deg":
            round(error, 2), "joint_states_hz_after": round(alive, 1),
            "back_error_deg": round(back, 2)}


def pick_sort(port_args: list[str], seed: int, blocks: int, folder: Path) -> dict[str, Any]:
    """``busarm [--port P] pick-sort``: what its report says."""
    table = [] if port_args else ["--seed", str(seed), "--blocks", str(blocks)]
    t0 = time.monotonic()
    out = subprocess.run([BUSARM, *port_args, "pick-sort", *table, "--report", str(folder)],
                         capture_output=True, text=True, timeout=900)
    summary = [line for line in out.stdout.splitlines() if line.startswith("sorted ")]
    report = json.loads((folder / "report.json").read_text()) if (
        folder / "report.json").is_file() else {}
    blocks_out = report.get("blocks", [])
    return {"exit": out.returncode, "seconds": round(time.monotonic() - t0, 1),
            "summary": summary[-1] if summary else out.stderr.strip()[-300:],
            "sorted": sum(1 for b in blocks_out if b.get("outcome") == "sorted"),
            "blocks": len(blocks_out)}


def in_bins(truth: dict[str, Any], bins: dict[str, Any], radius_mm: float = 45.0) -> int:
    """How many blocks truly stand in their colour's bin."""
    return sum(1 for b in truth["blocks"] if b["color"] in bins and math.dist(
        (b["x_mm"], b["y_mm"]), bins[b["color"]]) <= radius_mm)


def read_mcap(path: Path) -> dict[str, Any]:
    """Every message of the file decoded by mcap-ros2-support, counted by topic."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    counts: dict[str, int] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _schema, channel, _message, _decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return {"file": str(path), "bytes": path.stat().st_size, "decoded": counts}


def run_ros_bench(*, seconds: float = 10.0, drops: int = 3, flood: int = 1000, seed: int = 3,
                  blocks: int = 5, out_dir: Path | None = None,
                  progress: Progress = quiet) -> RosBenchReport:
    """Run it all (see the module docstring)."""
    from busarm.arm.config import load_arm_config

    report = RosBenchReport(seconds=seconds)
    limits = [(j.min_deg, j.max_deg) for j in load_arm_config().joints]
    folder = out_dir or Path(tempfile.mkdtemp(prefix="busarm-bench-ros-"))
    folder.mkdir(parents=True, exist_ok=True)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with running_bridge(endpoint, seed, blocks, progress):
        session = open_session(connect=[endpoint])
        node = RosNode(session, "bench")
        truth = Truth(session, limits)
        try:
            time.sleep(0.5)
            progress(f"streams for {seconds:g} s...")
            (report.joint_states_hz, report.joint_states_latency_ms, report.tf_hz,
             report.camera_fps) = stream_rates(node, seconds)
            start = truth.joint()
            progress("a trajectory, then links dropped mid-trajectory...")
            report.trajectory_error_deg = round(move(node, truth, start + 30.0, 1.5), 2)
            move(node, truth, start, 1.5)
            for k in range(drops):
                for freeze, kept in ((False, report.stop_after_kill_ms),
                                     (True, report.stop_after_freeze_ms)):
                    stop_ms, travelled = dropped_sender(endpoint, truth, freeze=freeze)
                    kept.append(round(stop_ms, 1))
                    report.travel_at_drop_deg.append(round(travelled, 1))
                    move(node, truth, start, 2.0)
                stop_ms, travelled = dropped_client(endpoint, truth)
                report.client_stop_after_freeze_ms.append(round(stop_ms, 1))
                report.travel_at_drop_deg.append(round(travelled, 1))
                move(node, truth, start, 2.0)
                progress(f"drops {k + 1}/{drops}")
            progress("faults...")
            report.faults = faults(node, truth, flood)
            progress("pick-sort over zenoh:// while recording an MCAP file...")
            recorder = McapRecorder(session, folder / "pick-sort.mcap")
            bins = ask(session, "busarm", "info")["bins"]
            host, tcp_port = endpoint[4:].rsplit(":", 1)
            report.pick_remote = pick_sort(["--port", port_text(ZenohPort(host, int(tcp_port)))],
                                           seed,
                                           blocks, folder / "remote")
            report.pick_remote["in_bins_truth"] = in_bins(truth.now(), bins)
            recorder.close()
            report.beyond_limits_deg = round(truth.beyond_deg, 3)
        finally:
            node.close()
            session.close()
    report.mcap = read_mcap(folder / "pick-sort.mcap")
    progress("the same table in one process...")
    report.pick_local = pick_sort([], seed, blocks, folder / "local")
    return report


if __name__ == "__main__":  # pragma: no cover - for a quick look without the CLI
    print(json.dumps(run_ros_bench(progress=print).as_dict(), indent=2))
    os._exit(0)
