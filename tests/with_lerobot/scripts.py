"""Running LeRobot's and busarm's scripts for the tests: each a process of its own (the
process is the subject), a twin served on a pseudo-terminal to replay onto, and reading
where that twin's arm ended through the same pty."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from busarm.robot import ArmSpec, CameraSpec, Robot, RobotConfig, ServoLine
from with_lerobot.conftest import BIN, lerobot_env

TIMEOUT_S = 300.0


def run_script(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    """``BIN/name args``, to its end; its output kept for the assertion's message."""
    return subprocess.run([str(BIN / name), *args], capture_output=True, text=True,
                          env=lerobot_env(), timeout=TIMEOUT_S, check=False)


@contextmanager
def served_twin() -> Iterator[str]:
    """``busarm twin serve`` (no blocks): its pty's path, stopped after."""
    proc = subprocess.Popen([sys.executable, "-m", "busarm", "twin", "serve", "--blocks", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=lerobot_env())
    try:
        assert proc.stdout is not None
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), proc.stderr.read() if proc.stderr else path
        yield path
    finally:
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=30)


BUSY_MARGIN_S = 0.3
"""A simulated line's reply margin here: its pty is served by another process or thread
while the main suite runs beside on the same two cores (50 ms was seen to fall short:
three POS_READs unanswered in 155 ms). It costs time only where a reply never comes."""


def arm_on(path: str) -> dict[str, float]:
    """The served twin's joints (rad) and gripper gap (mm), read through its pty."""
    with Robot.open(RobotConfig.from_port(path, camera=CameraSpec(calibrate=False), arm=ArmSpec(
            line=ServoLine(timeout_margin_s=BUSY_MARGIN_S)))) as robot:
        return robot.get_observation(cameras=False, scan=False).as_dict()  # type: ignore[return-value]


def close_deg(a: float, b: float, tolerance_deg: float) -> bool:
    return abs(math.degrees(a - b)) <= tolerance_deg


def replay_args(root: Path, repo_id: str, port: str, fps: int) -> list[str]:
    # the twin's pty is served by another process, on a busy computer: a reply's margin
    return ["--robot.type=busarm", f"--robot.port={port}", "--robot.camera_roles=[]",
            f"--robot.timeout_margin_s={BUSY_MARGIN_S}",
            f"--robot.fps={fps}", f"--dataset.repo_id={repo_id}", f"--dataset.root={root}",
            "--dataset.episode=0", f"--dataset.fps={fps}", "--play_sounds=false"]
