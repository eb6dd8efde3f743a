"""The base on a simulated controller board: in this process on simulated time, through a
pty on the wall clock (its watchdog thread), and by the CLI (in this process on
``board://sim``, simulated time; the README's `base move-by` line is its run as a
process). The truth is the simulated board's wheels."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import pytest
from click.testing import CliRunner, Result

from busarm.base.base import Base
from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.bus.board import BoardLink
from busarm.bus.ports import SerialPort, open_transport
from busarm.cli.main import cli
from busarm.clock import WALL_CLOCK, SimClock
from busarm.errors import ConfigError
from busarm.sim.board import SimBoard
from busarm.sim.bus import SimBus
from busarm.sim.pty import PtyServer
from busarm.sim.transport import SimTransport
from conftest import PTY_MARGIN_S, wait_for

CONFIG = load_chassis_config()
KIN = MecanumKinematics(CONFIG)


def wheel_rev_s(board: SimBoard) -> list[float]:
    board.next_output_at()  # the board's wheels move on when it is looked at
    return [w.rev_s for w in board.wheels]


def turns(board: SimBoard) -> list[float]:
    board.next_output_at()
    return [w.turns for w in board.wheels]


def moved(board: SimBoard, before: list[float]) -> Twist:
    """The body's displacement from the wheels' true turns (a move along one axis)."""
    after = turns(board)
    motors = {m: a - b for m, (a, b) in enumerate(zip(after, before, strict=True), 1)}
    return KIN.twist_from_rev_s(KIN.wheels_from_motors(motors))


@pytest.fixture(params=[True, False], ids=["encoders", "commands"])
def sim(request: pytest.FixtureRequest) -> Iterator[tuple[SimClock, SimBoard, Base]]:
    clock = SimClock()
    board = SimBoard(SimBus.with_ids([1], clock=clock), encoders=request.param)
    with Base(BoardLink(SimTransport(board)), CONFIG) as base:
        assert base.odometry_source == ("encoders" if request.param else "commands")
        yield clock, board, base


def test_drive_turns_the_wheels_and_the_watchdog_stops_them(
        sim: tuple[SimClock, SimBoard, Base]) -> None:
    clock, board, base = sim
    end = clock.now() + 1.0
    while clock.now() < end:
        base.drive(0.2, 0.0, 0.0)
        clock.sleep(0.05)
    want = 0.2 / CONFIG.wheel_circumference_m
    signs = [m.sign for m in CONFIG.motors]
    assert wheel_rev_s(board) == pytest.approx([s * want for s in signs], rel=0.02)
    assert base.odometry().twist.vx_m_s == pytest.approx(0.2, rel=0.05)
    clock.sleep(CONFIG.command_timeout_s - 0.1)
    assert all(w.target_rev_s != 0 for w in board.wheels)  # not yet
    clock.sleep(0.2)
    assert [w.target_rev_s for w in board.wheels] == [0.0] * 4
    assert base.watchdog_stops == 1
    clock.sleep(0.5)
    assert wheel_rev_s(board) == pytest.approx([0.0] * 4, abs=0.01)


@pytest.mark.parametrize(("dx", "dy", "dyaw"), [(0.4, 0, 0), (0, -0.25, 0), (0, 0, 60)])
def test_move_by_ends_near_the_target_by_the_wheels_turns(
        sim: tuple[SimClock, SimBoard, Base], dx: float, dy: float, dyaw: float) -> None:
    clock, board, base = sim
    before = turns(board)
    pose = base.move_by(dx, dy, math.radians(dyaw))
    truth = moved(board, before)
    assert truth.vx_m_s == pytest.approx(dx, abs=0.01)
    assert truth.vy_m_s == pytest.approx(dy, abs=0.01)
    assert math.degrees(truth.wz_rad_s) == pytest.approx(dyaw, abs=1.0)
    assert (pose.x_m, pose.y_m) == pytest.approx((dx, dy), abs=0.01)
    assert pose.yaw_deg == pytest.approx(dyaw, abs=1.0)
    assert [w.target_rev_s for w in board.wheels] == [0.0] * 4
    assert wheel_rev_s(board) == pytest.approx([0.0] * 4, abs=0.02)


def test_bad_numbers_are_refused_and_nothing_is_sent(
        sim: tuple[SimClock, SimBoard, Base]) -> None:
    _, board, base = sim
    for args in ((math.nan, 0.0, 0.0), (0.0, math.inf, 0.0)):
        with pytest.raises(ConfigError, match=r"(nan|inf) m/s .*-0\.4\.\.0\.4 m/s"):
            base.drive(*args)
    with pytest.raises(ConfigError, match="dyaw"):
        base.move_by(0.0, 0.0, math.nan)
    assert all(w.target_rev_s == 0.0 for w in board.wheels)


def test_an_exception_leaves_the_wheels_stopped() -> None:
    clock = SimClock()
    board = SimBoard(SimBus.with_ids([1], clock=clock))
    with pytest.raises(RuntimeError), Base(BoardLink(SimTransport(board)), CONFIG) as base:
        for _ in range(10):
            base.drive(0.3, 0.1, 0.5)
            clock.sleep(0.02)
        assert any(w.target_rev_s != 0 for w in board.wheels)
        raise RuntimeError("the caller failed")
    assert [w.target_rev_s for w in board.wheels] == [0.0] * 4
    with pytest.raises(ConfigError, match="closed"):
        base.drive(0.1, 0, 0)


@pytest.mark.wallclock("the watchdog is a thread waiting in wall-clock time, the board "
                        "served on a real pty")
def test_through_a_pty_on_the_wall_clock_the_watchdog_thread_stops_the_wheels() -> None:
    board = SimBoard(SimBus.with_ids([1], clock=WALL_CLOCK))
    server = PtyServer(board)
    port = SerialPort(server.start(), board=True)
    link = BoardLink(open_transport(port), timeout_margin_s=PTY_MARGIN_S)
    try:
        with Base(link, CONFIG) as base:
            assert base.odometry_source == "encoders"
            end = time.monotonic() + 0.4
            while time.monotonic() < end:
                base.drive(0.2, 0.0, 0.0)
                time.sleep(0.02)
            assert all(w.target_rev_s != 0 for w in board.wheels)
            assert base.odometry().pose.x_m > 0.02
            # Generous deadlines: only a failing test waits them out.
            assert wait_for(lambda: base.watchdog_stops > 0, CONFIG.command_timeout_s + 10.0)
            # The stop frame crosses the pty to the board.
            assert wait_for(lambda: [w.target_rev_s for w in board.wheels] == [0.0] * 4)
            assert base.watchdog_stops == 1
    finally:
        link.close()
        server.stop()


# ---------------------------------------------------------------------- the CLI


def busarm(*args: str) -> Result:
    """The command line in this process (``board://sim`` is on simulated time there)."""
    return CliRunner(mix_stderr=False).invoke(cli, list(args))


def test_cli_move_by_and_drive_on_a_simulated_board() -> None:
    done = busarm("--port", "board://sim", "base", "move-by", "0.2", "-0.1", "-30")
    assert done.exit_code == 0, done.stderr
    assert "x +0.20" in done.stdout and "y -0.10" in done.stdout and "yaw -30." in done.stdout
    assert "from encoders" in done.stdout and "wheels stopped" in done.stdout
    done = busarm("--port", "board://sim?encoders=0", "base", "drive", "0.4", "0", "0",
                  "--time", "0.3")
    assert done.exit_code == 0, done.stderr
    assert "vx +0.2" in done.stdout  # ramping up at 0.8 m/s^2
    assert "from commands" in done.stdout


def test_cli_odom_and_stop() -> None:
    done = busarm("--port", "board://sim?encoders=0", "base", "odom", "--time", "0.1")
    assert done.exit_code == 0, done.stderr
    assert "x +0.000 m" in done.stdout and "odometry from commands" in done.stdout
    done = busarm("--port", "board://sim", "base", "stop")
    assert done.exit_code == 0 and "0 rev/s" in done.stdout


@pytest.mark.parametrize(("args", "said"), [
    (["--port", "sim", "base", "stop"], "not a controller board's port"),
    (["--port", "board://sim", "base", "drive", "nan", "0", "0"], "'nan' is not a finite"),
    (["--port", "board://sim", "base", "move-by", "0", "0", "9999"], "-3600..3600"),
    (["--port", "board://sim", "base", "drive", "5", "0", "0"],
     "vx = 5 m/s is beyond the chassis's limit; allowed: -0.4..0.4 m/s"),
    (["--port", "board://sim", "base", "drive", "0", "0", "-200"],
     "wz = -200 deg/s is beyond the chassis's limit; allowed: -120..120 deg/s"),
    (["--port", "board://sim", "base", "drive", "0.4", "0.4", "120"],
     "together need a wheel at"),
])
def test_cli_bad_input_is_one_error(args: list[str], said: str) -> None:
    done = busarm(*args)
    assert done.exit_code == 2, (done.stdout, done.stderr)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and said in lines[0], lines
