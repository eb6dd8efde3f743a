"""``busarm bench teleop``: a leader arm on a second simulated bus (behind a pseudo-
terminal, as a USB adapter would be) drives the twin's arm in real time, one frame at a
time (busarm.learn.leader, busarm.learn.frames), as ``lerobot-record`` and ``busarm
record --leader`` do.

A hand turns the leader's base joint along a sine (30 deg either way, one turn in 4 s)
and its elbow along another (7.5 deg either way), in wall time; the leader is read in the
background (``LeaderArm(background=True)``). Measured: the rate the loop keeps, each
frame's time (the follower read, its move sent), and against the twin's truth how far
behind the hand the follower's joints are (the lag that best lines the two up) and by how
much they miss it then.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from busarm.bench.common import latency_percentiles_ms, short_machine_info
from busarm.learn.frames import FrameRobot
from busarm.learn.leader import LeaderArm
from busarm.progress import Progress, quiet
from busarm.robot import CameraSpec, RobotConfig, ServoLine
from busarm.sim.pty import PtyServer
from busarm.sim.spec import SimSpec
from busarm.twin.spec import TwinSpec
from busarm.units import check_int_range, check_range

__all__ = [
    "TARGET_HZ",
    "TeleopBenchReport",
    "run_teleop_bench",
]

TARGET_HZ = 30.0
AMPLITUDE_DEG = 30.0
PERIOD_S = 4.0
HAND_STEP_S = 0.005
JOINTS = (0, 2)
"""The joints the hand turns: the base and the elbow."""


@dataclass
class TeleopBenchReport:
    """The loop's rate and frame times, and the follower against the hand (the truth)."""

    machine: dict[str, str]
    fps: int
    seconds: float
    frames: int = 0
    rate_hz: float = 0.0
    frame_ms: dict[str, float] = field(default_factory=dict)
    lag_ms: float = 0.0
    error_deg: float = 0.0
    """RMS of the follower's joints from the hand's, once the lag is taken out."""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def text(self, verdict: Any) -> str:
        # the rate as shown: a loop paced at 30 frames a second is at 30.0 Hz
        return (f"leader -> twin at {self.rate_hz:.1f} Hz "
                f"({verdict(round(self.rate_hz, 1) >= TARGET_HZ)}"
                f" >= {TARGET_HZ:g}), {self.frames} frames in {self.seconds:g} s; a frame "
                f"(follower read, move sent) p50 {self.frame_ms['p50']:.1f} ms, p99 "
                f"{self.frame_ms['p99']:.1f} ms; the follower {self.lag_ms:.0f} ms behind the "
                f"hand, then within {self.error_deg:.2f} deg RMS")


def _hand_deg(t: float, base: tuple[float, ...]) -> list[float]:
    out = list(base)
    out[JOINTS[0]] = base[JOINTS[0]] + AMPLITUDE_DEG * math.sin(2 * math.pi * t / PERIOD_S)
    out[JOINTS[1]] = base[JOINTS[1]] - 0.25 * AMPLITUDE_DEG * math.sin(
        2 * math.pi * t / PERIOD_S + 1.0)
    return out


def run_teleop_bench(*, seconds: float = 10.0, fps: int = 50,
                     progress: Progress = quiet) -> TeleopBenchReport:
    """The leader on a pty drives the real-time twin for ``seconds`` at ``fps``."""
    check_range("seconds", seconds, 1.0, 600.0, "s")
    check_int_range("fps", fps, 1, 100)
    report = TeleopBenchReport(short_machine_info(), fps, seconds)
    lines = SimSpec(realtime=True).build()
    frames = FrameRobot(RobotConfig(TwinSpec(realtime=True, blocks=0),
                                    camera=CameraSpec(calibrate=False)), fps=fps, cameras=())
    with PtyServer(lines) as server:
        path = server.path
        # The simulated leader's pty is served by a thread of this process, which shares
        # the interpreter with the twin's physics and the loop: its replies get a margin
        # a USB adapter's would not need (20 ms: the leader is read in the background).
        with LeaderArm(path, config=frames.config, background=True,
                       line=ServoLine(timeout_margin_s=0.02)) as leader:
            frames.open()
            try:
                hand, follower = _drive(leader, frames, lines, seconds, fps, report)
            finally:
                frames.close()
    report.lag_ms, report.error_deg = _lag(hand, follower)
    progress(f"{report.frames} frames, follower {report.lag_ms:.0f} ms behind")
    return report


def _drive(leader: LeaderArm, frames: FrameRobot, lines: Any, seconds: float, fps: int,
           report: TeleopBenchReport) -> tuple[list[tuple[float, list[float]]],
                                                list[tuple[float, tuple[float, ...]]]]:
    """The hand moves the leader in a thread; the loop follows at ``fps``."""
    config = frames.config
    base = config.pose("look")
    hand: list[tuple[float, list[float]]] = []
    stop = threading.Event()

    def move_hand() -> None:
        t0 = time.monotonic()
        while not stop.is_set():
            t = time.monotonic() - t0
            angles = _hand_deg(t, base)
            for j, a in zip(config.joints, angles, strict=True):
                lines.servo(j.servo_id).move_by_hand(j.pulses_from_angle_deg(a),
                                                     lines.clock.now())
            hand.append((time.monotonic(), angles))
            stop.wait(HAND_STEP_S)

    twin = frames.robot.twin if frames.robot is not None else None
    assert twin is not None
    follower: list[tuple[float, tuple[float, ...]]] = []
    times, starts = [], []
    thread = threading.Thread(target=move_hand, name="busarm-bench-hand", daemon=True)
    thread.start()
    try:
        start = t_next = time.monotonic()
        while time.monotonic() - start < seconds:
            t = time.monotonic()
            starts.append(t)
            frames.observe()  # as lerobot-record does, before each action
            frames.act(leader.read())
            times.append(time.monotonic() - t)
            follower.append((time.monotonic(), twin.joints_deg()))
            t_next += 1.0 / fps
            time.sleep(max(0.0, t_next - time.monotonic()))
        # frames a second, from the first frame's start to the last's
        report.rate_hz = (len(starts) - 1) / max(starts[-1] - starts[0], 1e-9)
    finally:
        stop.set()
        thread.join()
    report.frames = len(times)
    report.frame_ms = latency_percentiles_ms(times)
    return hand, follower


def _lag(hand: list[tuple[float, list[float]]],
         follower: list[tuple[float, tuple[float, ...]]]) -> tuple[float, float]:
    """The delay (ms) that best lines the follower's joints up with the hand's, and the
    RMS error (deg) then; the first second (the arm catching up) left out."""
    th = np.array([t for t, _ in hand])
    tf = np.array([t for t, _ in follower])
    keep = tf > tf[0] + 1.0
    best = (math.inf, 0.0)
    for lag_ms in range(0, 501, 5):
        errors = []
        for k in JOINTS:
            want = np.interp(tf[keep] - lag_ms / 1000, th, [a[k] for _, a in hand])
            errors.append(np.array([a[k] for _, a in follower])[keep] - want)
        rms = float(np.sqrt(np.mean(np.square(errors))))
        best = min(best, (rms, float(lag_ms)))
    return best[1], best[0]
