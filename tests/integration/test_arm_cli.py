"""``busarm arm`` and ``busarm actions`` end to end, in-process with click's CliRunner,
against ``sim://?timing=0`` or simulated servos of the test's own (``sim_arm``), which
the commands open from one run to the next as a served arm, both on their simulated
clock."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from busarm.bus.driver import ServoBus
from busarm.cli.main import cli
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.transport import SimTransport
from conftest import in_process_port

SIM = "sim://?timing=0"
VENDOR = Path(__file__).resolve().parents[1] / "data" / "vendor" / "arm_action_1.d6a"


def run(*args: str, port: str = SIM, input: str | None = None) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", port, *args], input=input)


def assert_one_error(result: Result, code: int) -> str:
    assert result.exit_code == code, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return lines[0]


@pytest.fixture
def sim_arm(monkeypatch: pytest.MonkeyPatch) -> tuple[str, SimBus]:
    """The arm's six simulated servos (no wire timing, on their simulated clock), and the
    port by which commands run in this process open them, kept from one command to the
    next as a served arm is."""
    sim = SimBus.with_ids(timing=WireTiming(enabled=False))
    url = in_process_port(monkeypatch, sim)
    return url, sim


def test_fk_and_ik_json() -> None:
    result = run("arm", "fk", "0", "-90", "0", "-90", "0", "--json")
    assert result.exit_code == 0, result.stderr
    pose = json.loads(result.stdout)["pose"]
    assert pose["x_mm"] == pytest.approx(0, abs=1e-6) and pose["z_mm"] == pytest.approx(629.4)
    result = run("arm", "ik", "150", "-100", "60", "--pitch", "-90", "--json")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    q = list(data["solutions"][0].values())
    back = json.loads(run("arm", "fk", *map(str, q), "--json").stdout)["pose"]
    assert (back["x_mm"], back["y_mm"], back["z_mm"]) == pytest.approx((150, -100, 60), abs=0.01)


def test_ik_batch_good_and_bad_lines() -> None:
    lines = ['{"x": 150, "y": 0, "z": 60, "pitch": -90}', "not json",
             '{"x": 1000, "y": 0, "z": 0, "pitch": -90}', "[150, 50, 60]", '{"y": 1}']
    result = run("arm", "ik-batch", input="\n".join(lines) + "\n")
    assert result.exit_code == 3
    out = [json.loads(x) for x in result.stdout.strip().splitlines()]
    assert len(out) == 5
    assert [("error" in o) for o in out] == [False, True, True, False, True]
    assert [o["line"] for o in out if "error" in o] == [2, 3, 5]
    assert result.stderr.strip() == "error: 3 line(s) failed"


def test_unreachable_ik_and_bad_numbers() -> None:
    line = assert_one_error(run("arm", "ik", "1000", "0", "0", "--pitch", "-90"), 1)
    assert "beyond reach" in line
    line = assert_one_error(run("arm", "fk", "0", "abc", "0", "0", "0"), 2)
    assert "'abc'" in line
    line = assert_one_error(run("arm", "move-to", "100", "x1", "0"), 2)
    assert "'x1'" in line


def test_pose_move_to_home(sim_arm: tuple[str, SimBus]) -> None:
    path, sim = sim_arm
    result = run("arm", "pose", "--json", port=path)
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["joints_deg"]["elbow_pitch"] == pytest.approx(0)
    result = run("arm", "move-to", "150", "-100", "60", "--pitch", "-90", "--speed", "180",
                 port=path)
    assert result.exit_code == 0, result.stderr
    pose = json.loads(run("arm", "pose", "--json", port=path).stdout)["pose"]
    assert (pose["x_mm"], pose["y_mm"], pose["z_mm"]) == pytest.approx((150, -100, 60), abs=2)
    assert pose["pitch_deg"] == pytest.approx(-90, abs=1)
    result = run("arm", "home", "--speed", "180", port=path)
    assert result.exit_code == 0, result.stderr
    joints = json.loads(run("arm", "pose", "--json", port=path).stdout)["joints_deg"]
    assert list(joints.values()) == pytest.approx([0, -150, 120, -60, 0], abs=1.5)


def test_gripper_close_on_a_block() -> None:
    result = run("arm", "gripper", "close", port=SIM + "&block=1")
    assert result.exit_code == 0, result.stderr
    assert "holding an object" in result.stdout
    result = run("arm", "gripper", "close")
    assert result.exit_code == 0 and "closed on nothing" in result.stdout


def test_calibrate_non_interactive(sim_arm: tuple[str, SimBus], tmp_path: Path) -> None:
    path, sim = sim_arm
    with ServoBus(SimTransport(sim)) as bus:
        bus.move_pulses(3, 512, 0)
        sim.clock.sleep(0.05)
        bus.set_torque(3, False)
    out = tmp_path / "cal.json"
    result = run("arm", "calibrate", "--yes", "--out", str(out), port=path)
    assert result.exit_code == 0, result.stderr
    saved = json.loads(out.read_text())
    assert [j["hardware_offset_pulses"] for j in saved["joints"]] == [0, 0, 12, 0, 0]
    result = run("arm", "--calibration", str(out), "pose", "--json", port=path)
    assert result.exit_code == 0, result.stderr
    assert json.loads(result.stdout)["joints_deg"]["elbow_pitch"] == pytest.approx(0, abs=0.25)
    # A file that does not match the servos: one clear error.
    saved["joints"][2]["hardware_offset_pulses"] = 5
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(saved))
    line = assert_one_error(run("arm", "--calibration", str(bad), "pose", port=path), 2)
    assert "servo 3" in line and "calibrate" in line


def test_actions_show_play_record(tmp_path: Path, sim_arm: tuple[str, SimBus]) -> None:
    result = run("actions", "show", str(VENDOR), "--json")
    assert result.exit_code == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["columns"] == [1, 2, 3, 4, 5, 10] and len(data["frames"]) == 2
    assert data["frames"][0]["pulses"]["2"] == 788
    result = run("actions", "play", str(VENDOR), "--speed-scale", "2")
    assert result.exit_code == 0, result.stderr
    assert "played 2 of 2 frames" in result.stdout
    path, sim = sim_arm
    sim.servo(1).move_by_hand(620, sim.clock.now())
    out = tmp_path / "taught.d6a"
    result = run("actions", "record", str(out), "--interval", "0.05", "--frames", "3", port=path)
    assert result.exit_code == 0, result.stderr
    result = run("actions", "show", str(out), "--json")
    assert result.exit_code == 0, result.stderr
    frames = json.loads(result.stdout)["frames"]
    assert len(frames) == 3
    assert all(f["pulses"]["1"] == 620 and f["duration_ms"] == 50 for f in frames)


def test_urdf_prints_xml() -> None:
    result = run("arm", "urdf")
    assert result.exit_code == 0, result.stderr
    assert result.stdout.lstrip().startswith("<?xml") or "<robot" in result.stdout
    assert "</robot>" in result.stdout
