"""LeRobot's own scripts with busarm's robot, teleoperator and environment, each in its own
process: ``lerobot-record`` from a leader arm (simulated servos behind a real pty, turned
by hand) into a dataset with the wrist camera's video, ``lerobot-replay`` of it onto a twin
served on another pty (where its arm is read back after), ``lerobot-train`` and
``lerobot-eval`` on the twin environment, ``busarm rollout`` of the trained policy, and a
person's dashboard episode recorded by ``busarm record --teleop dashboard`` and replayed."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from lerobot.datasets.lerobot_dataset import LeRobotDataset
from websockets.sync.client import connect

from busarm.arm.config import load_arm_config
from busarm.cli.main import cli
from busarm.learn.record import record_expert
from busarm.sim.pty import PtyServer
from busarm.sim.spec import SimSpec
from with_lerobot.conftest import lerobot_env
from with_lerobot.scripts import (
    BUSY_MARGIN_S,
    arm_on,
    close_deg,
    replay_args,
    run_script,
    served_twin,
)

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]  # LeRobot's scripts start slowly
ARM = load_arm_config()
FPS = 20


@pytest.mark.wallclock("lerobot-record paces its loop on the wall clock (a real-time twin)")
def test_lerobot_record_from_a_leader_then_replay(tmp_path: Path) -> None:
    lines = SimSpec(realtime=True).build()
    pose = {"base_yaw": 25.0, "elbow_pitch": 80.0}
    for j in ARM.joints:
        if j.name in pose:
            lines.servo(j.servo_id).move_by_hand(j.pulses_from_angle_deg(pose[j.name]),
                                                 lines.clock.now())
    root = tmp_path / "led"
    with PtyServer(lines) as server:
        done = run_script(
            "lerobot-record", "--robot.type=busarm", "--robot.port=twin",
            "--robot.camera_roles=[wrist]", "--teleop.type=busarm_leader",
            # the leader's pty is served by this test's process, on a busy computer
            f"--teleop.port={server.path}", f"--teleop.timeout_margin_s={BUSY_MARGIN_S}",
            "--dataset.repo_id=local/led",
            f"--dataset.root={root}", "--dataset.num_episodes=1",
            "--dataset.episode_time_s=3", "--dataset.reset_time_s=0",
            "--dataset.single_task=follow the leader", "--dataset.push_to_hub=false",
            f"--dataset.fps={FPS}", "--display_data=false", "--play_sounds=false")
    assert done.returncode == 0, done.stderr[-3000:]
    ds = LeRobotDataset("local/led", root=root)
    assert ds.num_episodes == 1 and ds.num_frames >= 20
    last = ds[ds.num_frames - 1]
    assert tuple(last["observation.images.wrist"].shape) == (3, 480, 640)
    names = ds.meta.features["action"]["names"]
    state, action = last["observation.state"].numpy(), last["action"].numpy()
    for name, deg in pose.items():
        k = names.index(f"{name}.pos")
        assert close_deg(action[k], math.radians(deg), 0.5), (name, action)
        assert close_deg(state[k], math.radians(deg), 2.0), (name, state)  # it followed
    with served_twin() as port:
        replayed = run_script("lerobot-replay", *replay_args(root, "local/led", port, FPS))
        assert replayed.returncode == 0, replayed.stderr[-3000:]
        there = arm_on(port)
    for name, deg in pose.items():
        assert close_deg(there[f"{name}.pos"], math.radians(deg), 2.0), there


def test_train_eval_and_rollout_on_the_twin(tmp_path: Path) -> None:
    record_expert(tmp_path / "ds", episodes=3, seed=30)
    out = tmp_path / "train"
    trained = run_script(
        "lerobot-train", "--dataset.repo_id=local/busarm", f"--dataset.root={tmp_path / 'ds'}",
        "--policy.type=act", "--policy.device=cpu", "--policy.push_to_hub=false",
        "--policy.chunk_size=10", "--policy.n_action_steps=10", "--policy.dim_model=64",
        "--policy.n_heads=2", "--policy.dim_feedforward=128", "--policy.n_encoder_layers=1",
        "--policy.n_vae_encoder_layers=1", "--wandb.enable=false", f"--output_dir={out}",
        "--steps=4", "--batch_size=4", "--save_freq=4", "--eval_freq=0", "--num_workers=0")
    assert trained.returncode == 0, trained.stderr[-3000:]
    policy = out / "checkpoints" / "last" / "pretrained_model"
    evaluated = run_script(
        "lerobot-eval", f"--policy.path={policy}", "--env.type=busarm",
        "--env.episode_length=30", "--eval.n_episodes=2", "--eval.batch_size=1",
        "--seed=1000000", f"--output_dir={tmp_path / 'eval'}", "--policy.device=cpu")
    assert evaluated.returncode == 0, evaluated.stderr[-3000:]
    info = json.loads((tmp_path / "eval" / "eval_info.json").read_text())
    overall = info["overall"]
    assert overall["n_episodes"] == 2 and 0.0 <= overall["pc_success"] <= 100.0
    assert all(Path(p).is_file() for p in overall["video_paths"])

    result = CliRunner(mix_stderr=False).invoke(
        cli, ["rollout", "--policy", str(policy), "--seconds", "2", "--json"])
    assert result.exit_code == 0, result.stderr
    report = json.loads(result.stdout)
    assert 30 <= report["frames"] <= 41 and report["ended"] == "2 s were up"
    assert report["success"] is False  # four steps of training do not sort a block
    assert "looked: " in result.stderr


@pytest.mark.wallclock("a rollout served with the dashboard (real time), stopped from it")
def test_the_dashboard_stops_a_rollout(tmp_path: Path) -> None:
    record_expert(tmp_path / "ds", episodes=2, seed=40)
    out = tmp_path / "train"
    assert run_script(
        "lerobot-train", "--dataset.repo_id=local/busarm", f"--dataset.root={tmp_path / 'ds'}",
        "--policy.type=act", "--policy.device=cpu", "--policy.push_to_hub=false",
        "--policy.dim_model=64", "--policy.n_heads=2", "--policy.dim_feedforward=128",
        "--policy.n_encoder_layers=1", "--policy.n_vae_encoder_layers=1",
        "--wandb.enable=false", f"--output_dir={out}", "--steps=2", "--batch_size=4",
        "--save_freq=2", "--eval_freq=0", "--num_workers=0").returncode == 0
    policy = out / "checkpoints" / "last" / "pretrained_model"
    proc = subprocess.Popen([sys.executable, "-m", "busarm", "rollout", "--policy", str(policy),
                             "--seconds", "60", "--dashboard", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=lerobot_env())
    try:
        url = _dashboard_url(proc)
        with connect(url.replace("http", "ws") + "ws", open_timeout=10) as ws:
            _said(proc, "looked: ")  # the policy acts from here on
            ws.send('{"type": "estop"}')
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr[-3000:]
    report = json.loads(stdout)
    assert report["ended"].startswith("stopped: ") and report["seconds"] < 30


def _said(proc: subprocess.Popen[str], text: str) -> str:
    """The first line of ``proc``'s stderr that says ``text``."""
    assert proc.stderr is not None
    for line in proc.stderr:
        if text in line:
            return line
    raise AssertionError(f"never said {text!r}: {proc.communicate(timeout=10)}")


def _dashboard_url(proc: subprocess.Popen[str]) -> str:
    return _said(proc, "dashboard: open ").split("dashboard: open ", 1)[1].split()[0]


@pytest.mark.wallclock("a person's jog through the dashboard of a real-time twin")
def test_a_dashboard_episode_is_recorded_and_replayed(tmp_path: Path) -> None:
    root = tmp_path / "jogged"
    proc = subprocess.Popen([sys.executable, "-m", "busarm", "record", str(root), "--teleop",
                             "dashboard", "--episodes", "1", "--episode-s", "4",
                             "--cameras", "", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=lerobot_env())
    try:
        url = _dashboard_url(proc)
        with connect(url.replace("http", "ws") + "ws", open_timeout=10) as ws:
            _said(proc, "episode 1/1: recording")
            ws.send(json.dumps({"type": "jog", "joint": "base_yaw", "direction": 1}))
            for _ in range(10):  # held for a second, heartbeats every 100 ms
                time.sleep(0.1)
                ws.send('{"type": "heartbeat"}')
            ws.send('{"type": "jog_stop"}')
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr[-3000:]
    assert json.loads(stdout)["episodes"] == 1
    ds = LeRobotDataset("local/busarm", root=root)
    actions = np.stack([ds[i]["action"].numpy() for i in range(ds.num_frames)])
    turned = math.degrees(actions[-1, 0] - actions[0, 0])
    assert 10.0 < turned < 60.0, turned  # the jog turned the base (30 deg/s for a second)
    with served_twin() as port:
        replayed = run_script("lerobot-replay", *replay_args(root, "local/busarm", port, FPS))
        assert replayed.returncode == 0, replayed.stderr[-3000:]
        there = arm_on(port)
    assert close_deg(there["base_yaw.pos"], float(actions[-1, 0]), 2.0), there
