"""What the arm commands print reads as a person reads it: every number with its unit, no
``-0.0``, no Python repr, the gripper in millimetres (its pulses beside them)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from busarm.cli.main import cli

RAW_FLOAT = re.compile(r"\d\.\d{5,}")
"""A float printed as Python prints it (171.8238837475933)."""


def run(*args: str) -> Result:
    return CliRunner(mix_stderr=False).invoke(cli, ["--port", "sim", *args])


def _readable(out: str) -> None:
    assert "-0.0" not in out and "nan" not in out.lower(), out
    assert not RAW_FLOAT.search(out), out
    assert not re.search(r"\b[A-Z][A-Za-z]+\(", out), out  # SomeClass(...) reprs


def test_pose_says_joints_pose_and_gripper_with_units() -> None:
    result = run("arm", "pose")
    assert result.exit_code == 0, result.stderr
    _readable(result.stdout)
    joints = " ".join(result.stdout.split()).split(" x ", 1)[0]
    assert joints.endswith(" deg"), result.stdout
    assert re.search(r"x 0\.0  y 0\.0  z [\d.]+ mm  pitch [-\d.]+  roll 0\.0 deg", result.stdout)
    # A fresh simulated servo is limp (the manual's power-on state): said so.
    assert re.search(r"gripper open [\d.]+ mm \(\d+ pulses, torque off\)", result.stdout), \
        result.stdout
    data = json.loads(run("arm", "pose", "--json").stdout)
    assert data["gripper_gap_mm"] == pytest.approx(37.5, abs=0.1)


@pytest.mark.parametrize("args", [["arm", "ik", "200", "0", "40"],
                                  ["arm", "ik", "200", "0", "40", "--json"],
                                  ["arm", "fk", "0", "0", "0", "0", "0", "--json"]])
def test_ik_and_fk_never_print_minus_zero(args: list[str]) -> None:
    result = run(*args)
    assert result.exit_code == 0, result.stderr
    _readable(result.stdout)
    if "--json" not in args:
        assert "pitch -90.0 deg" in result.stdout


def test_ik_batch_json_has_no_minus_zero() -> None:
    result = CliRunner(mix_stderr=False).invoke(cli, ["arm", "ik-batch"],
                                                input='{"x": 200, "y": 0, "z": 40}\n')
    assert result.exit_code == 0, result.stderr
    assert "-0.0" not in result.stdout
    assert json.loads(result.stdout)["solutions"][0]["base_yaw"] == 0.0


def test_workspace_says_what_it_drew_in_words(tmp_path: Path) -> None:
    result = run("arm", "workspace", "--png", str(tmp_path / "ws.png"))
    assert result.exit_code == 0, result.stderr
    _readable(" ".join(result.stdout.split()))
    assert re.search(r"reaches \d+-\d+ mm from the base axis", " ".join(result.stdout.split()))


def test_the_gripper_is_said_in_mm() -> None:
    opened = run("arm", "gripper", "open")
    assert opened.exit_code == 0, opened.stderr
    assert re.search(r"gripper open [\d.]+ mm \(\d+ pulses\)", opened.stdout), opened.stdout
    closed = run("arm", "gripper", "close")
    assert re.search(r"closed on nothing: [\d.]+ mm apart", closed.stdout), closed.stdout


def test_errors_and_moves_show_no_python_lists_or_minus_zero() -> None:
    short = run("arm", "move-joints", "0", "-30", "45")
    assert short.exit_code == 2 and "got 3: 0, -30, 45" in short.stderr, short.stderr
    assert "[" not in short.stderr
    odd = CliRunner(mix_stderr=False).invoke(
        cli, ["--port", "sim", "arm", "move-joints", "--json", "-"],
        input='{"joints_deg": {"base_yaw": 1}}')
    assert odd.exit_code == 2 and "[" not in odd.stderr, odd.stderr
    assert "joint names base_yaw are not this arm's base_yaw, shoulder_pitch" in odd.stderr
    moved = run("move", "1", "-0.04", "--time", "0.2")
    assert moved.exit_code == 0, moved.stderr
    assert "moving 1 -> +0.0 deg" in moved.stdout and "-0.0" not in moved.stdout
