"""The robot description (issue 29): typed, checked once; a robot file round-trips; a bad
key or value is one error naming the key, the value and what is allowed; the command line
writes one (`robot init`) and opens it (`--robot FILE`)."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st

from busarm.bus.ports import SerialPort
from busarm.bus.zenoh_link import ZenohPort
from busarm.cli.main import cli
from busarm.errors import ConfigError
from busarm.robot import ArmSpec, BaseSpec, CameraSpec, LidarSpec, RobotConfig, ServoLine
from busarm.robot.port_url import parse_port
from busarm.robot.robot_file import load_robot_file, save_robot_file
from busarm.sim.spec import BoardSettings, SimLidarSpec, SimSpec
from busarm.twin.spec import TwinSpec

HARDWARE = RobotConfig(
    SerialPort("/dev/ttyACM0", board=True),
    ArmSpec("jetauto_pro", line=ServoLine(retries=3, timeout_margin_s=0.01)),
    base=BaseSpec("jetauto"), lidar=LidarSpec(SerialPort("/dev/ttyUSB1")),
    camera=CameraSpec("/dev/video0"), bins={"red": (150.0, -120.0), "blue": (150.0, 120.0)})


@pytest.mark.parametrize("config", [
    RobotConfig(),
    HARDWARE,
    RobotConfig(TwinSpec(family="arena", seed=3, slip=False,
                         controller=BoardSettings(imu_hz=50.0))),
    RobotConfig(TwinSpec(family="clutter", seed=7, blocks=10, lens="vendor")),
    RobotConfig(SimSpec(ids=(1, 2), echo=True, drop=0.01, controller=BoardSettings()),
                lidar=LidarSpec(SimLidarSpec(hz=10.0))),
    RobotConfig(ZenohPort("127.0.0.1", 7448, "lab")),
], ids=["twin", "hardware", "arena", "clutter", "sim", "zenoh"])
def test_a_robot_file_reads_back_as_the_robot_written(tmp_path: Path, config: RobotConfig) -> None:
    path = tmp_path / "robot.toml"
    save_robot_file(path, config, "desk robot")
    again, name = load_robot_file(path)
    assert (again, name) == (config, "desk robot")


def test_paths_in_a_robot_file_are_relative_to_its_folder(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text('format = "busarm.robot"\nversion = 1\nname = "r"\n[world]\nkind = "twin"\n'
                    '[camera]\nintrinsics = "cal/camera.json"\nhand_eye = "cal/hand_eye.json"\n',
                    encoding="utf-8")
    config, _ = load_robot_file(path)
    assert config.camera.intrinsics == tmp_path / "cal" / "camera.json"


@pytest.mark.parametrize("body, named", [
    ('[world]\nkind = "moon"\n', ["world.kind", "'moon'", "serial, sim, twin, zenoh"]),
    ('[world]\nkind = "twin"\nseeds = 3\n', ["world", "seeds", "known:"]),
    ('[world]\nkind = "twin"\nblocks = 40\n', ["world", "blocks", "40", "0..8"]),
    ('[world]\nkind = "sim"\ndrop = 2\n', ["world", "drop", "2", "0..1"]),
    ('[world]\nkind = "serial"\ndevice = "/dev/x"\n[arm.line]\nretries = 99\n',
     ["arm.line", "retries", "99", "0..10"]),
    ('[world]\nkind = "twin"\n[lidar]\nsim = {hz = 50}\n', ["lidar.sim", "hz", "50", "2..10"]),
    ('[world]\nkind = "serial"\ndevice = "/dev/x"\n[base]\nchassis = "jetauto"\n',
     ["board://", "/dev/x"]),
    ('[world]\nkind = "twin"\n[bins]\nred = [1]\n', ["bins.red", "[x_mm, y_mm]"]),
    ('[world]\nkind = "twin"\ncolour = "red"\n', ["colour", "known:"]),
])
def test_a_bad_robot_file_is_one_error_naming_the_key(tmp_path: Path, body: str,
                                                      named: list[str]) -> None:
    path = tmp_path / "robot.toml"
    path.write_text('format = "busarm.robot"\nversion = 1\nname = "r"\n' + body,
                    encoding="utf-8")
    with pytest.raises(ConfigError) as err:
        load_robot_file(path)
    assert str(path) in str(err.value)
    for word in named:
        assert word in str(err.value)


@pytest.mark.parametrize("make, named", [
    (lambda: RobotConfig(SerialPort("/dev/ttyUSB0"), base=BaseSpec()), "controller board"),
    (lambda: RobotConfig(ZenohPort("h"), lidar=LidarSpec(SimLidarSpec())), "served"),
    (lambda: RobotConfig(TwinSpec(controller=BoardSettings()), base=BaseSpec()), "twin's base"),
    (lambda: RobotConfig(SerialPort("/dev/ttyUSB0"), camera=CameraSpec(
        intrinsics=Path("c.json"))), "both camera calibration files"),
    (lambda: CameraSpec(hand_eye=Path("h.json")), "intrinsics it was made with"),
    (lambda: LidarSpec(TwinSpec()), "no Lidar"),
    (lambda: LidarSpec(SimLidarSpec(), model="vlp16"), "rplidar-a1"),
    (lambda: TwinSpec(scene=Path("s.json"), seed=3), "either scene"),
    (lambda: TwinSpec(family="arena", blocks=3), "seed only"),
    (lambda: TwinSpec(slip=False), "arena"),
    (lambda: TwinSpec(board="chessboard", family="clutter"), "family random"),
    (lambda: SimSpec(pace=2.0, realtime=True), "exclude each other"),
    (lambda: ServoLine(echo="maybe"), "echo = .maybe.; allowed: on, off, auto"),
], ids=lambda v: v if isinstance(v, str) else "")
def test_a_description_that_cannot_be_is_refused_when_made(make: object, named: str) -> None:
    with pytest.raises(ConfigError, match=named):
        make()  # type: ignore[operator]


def test_reprs_are_short_and_say_what_differs() -> None:
    assert repr(RobotConfig()) == "RobotConfig()"
    assert repr(TwinSpec(family="arena", seed=3)) == "TwinSpec(family='arena', seed=3)"
    assert len(repr(HARDWARE)) < 400


@given(st.integers(0, 2**32 - 1), st.integers(0, 8), st.booleans(), st.booleans())
def test_a_twin_port_reads_as_the_twin_it_names(seed: int, blocks: int, echo: bool,
                                                board: bool) -> None:
    text = (("board://twin" if board else "twin://") + f"?seed={seed}&blocks={blocks}"
            + f"&echo={int(echo)}")
    assert parse_port(text) == TwinSpec(seed=seed, blocks=blocks, echo=echo,
                                        controller=BoardSettings() if board else None)


@given(st.text(min_size=1, max_size=12).filter(lambda k: k.isidentifier()))
def test_an_unknown_key_in_a_port_is_refused_by_name(key: str) -> None:
    known = {"ids", "echo", "timing", "turnaround_ms", "drop", "corrupt", "late", "late_ms",
             "seed", "state", "block", "realtime", "pace"}
    if key in known:
        return
    with pytest.raises(ConfigError, match=f"unknown parameter.*{key}"):
        parse_port(f"sim://?{key}=1")


def test_robot_init_writes_a_file_that_the_commands_open(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    runner = CliRunner()
    made = runner.invoke(cli, ["--port", "twin://?blocks=0", "robot", "init", str(path),
                               "--name", "bench arm"])
    assert made.exit_code == 0, made.output
    assert load_robot_file(path) == (RobotConfig(TwinSpec(blocks=0)), "bench arm")
    again = runner.invoke(cli, ["--port", "twin", "robot", "init", str(path)])
    assert again.exit_code != 0 and "--force" in again.output  # never replaced unasked
    pose = runner.invoke(cli, ["--robot", str(path), "arm", "pose", "--json"])
    assert pose.exit_code == 0, pose.output
    assert '"joints_deg"' in pose.output
