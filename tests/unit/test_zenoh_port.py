"""`zenoh://` ports, the robot's side's check of each request from the link, and the
benchmark's reading of when a joint stood still."""

from __future__ import annotations

import re

import pytest

from busarm.arm.arm import Arm
from busarm.bench.ros import stop_time_ms
from busarm.bus.zenoh_link import ZenohPort
from busarm.bus.zenoh_session import endpoint_host, is_loopback, session_config
from busarm.errors import ConfigError, HaltedError, LimitError, ProtocolError
from busarm.protocol import Command
from busarm.protocol.frames import encode_request
from busarm.robot.port_url import parse_port
from busarm.robot.remote import bus_guard
from busarm.sim.spec import SimSpec


@pytest.mark.parametrize(("port", "endpoint", "robot"), [
    ("zenoh://127.0.0.1", "tcp/127.0.0.1:7447", "busarm"),
    ("zenoh://robot.local:7500?robot=left", "tcp/robot.local:7500", "left"),
    ("zenoh://[::1]:7447", "tcp/[::1]:7447", "busarm"),
])
def test_a_zenoh_port_names_the_endpoint_and_the_robot(port: str, endpoint: str,
                                                       robot: str) -> None:
    parsed = parse_port(port)
    assert isinstance(parsed, ZenohPort)
    assert (parsed.endpoint, parsed.robot) == (endpoint, robot)


@pytest.mark.parametrize(("port", "says"), [
    ("zenoh://", "give zenoh://HOST"), ("zenoh://h:99999", "1..65535"),
    ("zenoh://h?robt=x", "unknown key(s) robt; allowed: robot"),
])
def test_a_bad_zenoh_port_is_refused(port: str, says: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(says)):
        parse_port(port)


def test_only_loopback_listens_without_a_token() -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.5")
    assert endpoint_host("tcp/[::1]:7447") == ("::1", 7447)
    with pytest.raises(ConfigError, match="needs a token"):
        session_config(listen=["tcp/192.168.1.5:7447"])
    with pytest.raises(ConfigError, match="cannot contain ':'"):
        session_config(listen=["tcp/127.0.0.1:7447"], token="a:b")
    config = session_config(connect=["tcp/127.0.0.1:7447"])
    assert '"enabled":false' in config.get_json("scouting/multicast").replace(" ", "")


def test_the_guard_lets_through_what_the_arm_may_do_and_nothing_else() -> None:
    with Arm.open(SimSpec()) as arm:
        check = bus_guard(arm)
        lo, hi = arm.pulse_limits[2]
        check(encode_request(2, Command.MOVE_TIME_WRITE, lo, 500))
        check(encode_request(2, Command.POS_READ))
        check(encode_request(1, Command.MOVE_TIME_WRITE, 500, 500)
              + encode_request(2, Command.MOVE_TIME_WRITE, hi, 500))
        with pytest.raises(LimitError, match=f"servo 2 position {hi + 1} refused: allowed "
                                             f"{lo}..{hi} pulses"):
            check(encode_request(2, Command.MOVE_TIME_WRITE, hi + 1, 500))
        with pytest.raises(LimitError, match="one at a time"):
            check(encode_request(254, Command.MOVE_TIME_WRITE, 500, 500))
        with pytest.raises(LimitError, match="servo 7"):
            check(encode_request(7, Command.MOVE_TIME_WRITE, 500, 500))
        with pytest.raises(ProtocolError, match="not whole LX request frames"):
            check(encode_request(1, Command.POS_READ)[:-1])
        with pytest.raises(ProtocolError):
            check(b"hello")
        arm.bus.halt("test")
        check(encode_request(254, Command.MOVE_STOP))
        with pytest.raises(HaltedError, match="halted"):
            check(encode_request(1, Command.MOVE_TIME_WRITE, 500, 500))
        arm.bus.rearm()


def test_a_joint_is_still_from_the_first_sample_that_stays_near_where_it_ends() -> None:
    moving = [(1.00, 10.0), (1.01, 10.5), (1.02, 10.8), (1.03, 10.9), (1.04, 10.95)]
    assert stop_time_ms(moving, 1.0) == pytest.approx(30.0)
    still = [(1.005, 3.0), (1.015, 3.0), (1.025, 3.02)]
    assert stop_time_ms(still, 1.0) == pytest.approx(5.0)  # still at the first look
