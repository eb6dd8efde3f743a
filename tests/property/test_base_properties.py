"""The base's kinematics and limits as properties: twist -> wheels -> twist is exact, and
no motor command beyond a wheel's or the body's limits (speed, acceleration) ever reaches
the simulated board, whatever sequence of commands ``Base.drive`` is given."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.base.base import Base
from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.bus.board import BoardLink
from busarm.clock import SimClock
from busarm.errors import ConfigError
from busarm.protocol.board import (
    BoardFrameParser,
    MotorEncoders,
    MotorSpeeds,
    decode_report,
    decode_request,
)
from busarm.sim.board import SimBoard
from busarm.sim.bus import SimBus
from busarm.sim.transport import SimTransport

CONFIG = load_chassis_config()
KIN = MecanumKinematics(CONFIG)
SPEED = st.floats(-5.0, 5.0, allow_nan=False)


class RecordingBoard(SimBoard):
    """A SimBoard that keeps every MotorSpeeds frame it hears, with its time."""

    def __init__(self, servos: SimBus) -> None:
        super().__init__(servos)
        self.heard: list[tuple[float, dict[int, float]]] = []
        self._spy = BoardFrameParser()

    def receive(self, data: bytes) -> None:
        for frame in self._spy.feed(data):
            request = decode_request(frame)
            if isinstance(request, MotorSpeeds):
                self.heard.append((self.clock.now(), dict(request.speeds)))
        super().receive(data)


@given(SPEED, SPEED, st.floats(-20.0, 20.0, allow_nan=False))
def test_twist_to_wheels_to_twist_is_exact(vx: float, vy: float, wz: float) -> None:
    back = KIN.twist(KIN.wheel_speeds_m_s(Twist(vx, vy, wz)))
    assert math.isclose(back.vx_m_s, vx, abs_tol=1e-12)
    assert math.isclose(back.vy_m_s, vy, abs_tol=1e-12)
    assert math.isclose(back.wz_rad_s, wz, abs_tol=1e-12)
    motors = KIN.motor_speeds(Twist(vx, vy, wz))
    again = KIN.twist_from_rev_s(KIN.wheels_from_motors(motors))
    assert math.isclose(again.vx_m_s, vx, abs_tol=1e-12)
    assert math.isclose(again.wz_rad_s, wz, abs_tol=1e-12)


@given(st.tuples(*(st.integers(-(2**31), 2**31 - 1),) * 4))
def test_encoder_report_round_trips(ticks: tuple[int, int, int, int]) -> None:
    frames = BoardFrameParser().feed(MotorEncoders(ticks).encode())
    assert [decode_report(f) for f in frames] == [MotorEncoders(ticks)]


COMMANDS = st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-100, 100),
                              st.sampled_from([0.0, 0.001, 0.02, 0.05, 0.3, 0.7])),
                    min_size=1, max_size=25)


@settings(max_examples=40, deadline=None)
@given(COMMANDS)
def test_no_command_beyond_the_limits_reaches_the_board(
        commands: list[tuple[float, float, float, float]]) -> None:
    clock = SimClock()
    board = RecordingBoard(SimBus.with_ids([1], clock=clock))
    with Base(BoardLink(SimTransport(board)), CONFIG) as base:
        for vx, vy, wz, wait_s in commands:
            base.drive(vx, vy, wz)
            clock.sleep(wait_s)
    assert board.heard and all(v == 0.0 for v in board.heard[-1][1].values())
    last_t, last = 0.0, Twist()
    for t, speeds in board.heard:
        assert all(abs(v) <= CONFIG.max_wheel_rev_s for v in speeds.values()), speeds
        twist = KIN.twist_from_rev_s(KIN.wheels_from_motors(speeds))
        assert KIN.within_limits(twist, slack=1e-6), twist
        if not twist.is_zero or last.is_zero:  # a stop may be sudden; a ramp may not
            dt = t - last_t
            slack = 1e-6 + 1e-9 / max(dt, 1e-9)
            assert abs(twist.vx_m_s - last.vx_m_s) <= CONFIG.max_accel_m_s2 * dt + slack
            assert abs(twist.vy_m_s - last.vy_m_s) <= CONFIG.max_accel_m_s2 * dt + slack
            assert (abs(twist.wz_rad_s - last.wz_rad_s)
                    <= CONFIG.max_yaw_accel_rad_s2 * dt + 10 * slack)
        last_t, last = t, twist


@given(SPEED, SPEED, SPEED)
def test_a_persons_command_is_refused_exactly_when_it_is_beyond_a_limit(
        vx: float, vy: float, wz: float) -> None:
    twist = Twist(vx, vy, wz)
    try:
        KIN.check_limits(twist)
    except ConfigError as exc:
        assert not KIN.within_limits(twist, slack=-1e-9), exc
        assert "beyond the chassis's limit" in str(exc) or "need a wheel at" in str(exc)
    else:
        assert KIN.within_limits(twist)
