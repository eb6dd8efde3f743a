"""Issue 31: ``busarm board pwm`` on a simulated board in this process (``board://sim``),
as a user runs it (click's runner), and ``busarm board --help`` telling a user of the
vendor's SDK what its "enable torque" really does."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner, Result

from busarm.cli.main import cli
from conftest import not_crashed

Env = dict[str, str | None]


@pytest.fixture
def env(tmp_path: Path) -> Env:
    runtime = tmp_path / "xdg-run"
    runtime.mkdir(mode=0o700)
    return {"BUSARM_PORT": None, "BUSARM_ARM": None, "BUSARM_CALIBRATION": None,
            "XDG_CONFIG_HOME": str(tmp_path / "config"), "XDG_RUNTIME_DIR": str(runtime),
            "BUSARM_RUNTIME_DIR": str(tmp_path / "run"), "COLUMNS": "200"}


def busarm(*args: str, env: Env) -> Result:
    result = CliRunner(mix_stderr=False).invoke(cli, list(args), env=env, prog_name="busarm")
    not_crashed(result)
    return result


def test_pwm_moves_the_ports_and_shows_the_pulses_the_board_reads_back(env: Env) -> None:
    result = busarm("board", "pwm", "1=2000", "3=900", "--time", "0.2",
                    "--port", "board://sim", env=env)
    assert result.exit_code == 0, result.stderr
    assert result.stdout.splitlines() == ["PWM port 1: 2000 us", "PWM port 3: 900 us"]
    shown = busarm("board", "pwm", "--port", "board://sim", env=env)
    assert shown.stdout.splitlines() == [f"PWM port {p}: 1500 us" for p in range(1, 5)]


@pytest.mark.parametrize(("target", "said"), [
    ("1=2600", "error: PWM port 1 pulse_us = 2600 us is out of range 500..2500 us"),
    ("5=1500", "error: PWM port = 5 is out of range 1..4"),
    ("1:1500", "error: '1:1500' is not PORT=US (e.g. 1=1500: port 1..4, pulse 500..2500 us)"),
])
def test_a_bad_pwm_target_is_one_error_before_the_board_is_opened(
        env: Env, target: str, said: str) -> None:
    # A silent board would make opening it the error: the value is refused before that.
    result = busarm("board", "pwm", target, "--port", "board://sim?silent=1", env=env)
    assert result.exit_code == 2, (result.stdout, result.stderr)
    assert result.stderr.strip().splitlines() == [said]


def test_board_help_says_the_vendor_sdks_enable_torque_unloads(env: Env) -> None:
    text = " ".join(busarm("board", "--help", env=env).stdout.split())
    assert "bus_servo_enable_torque(id, 1) sends sub-command 0x0B" in text
    assert "switches the servo's torque OFF" in text
