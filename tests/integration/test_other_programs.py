"""Other programs talk to ``busarm sim serve`` as they would to real servos.

The server runs as a subprocess; a client opens the pty path it prints first. Bytes
in these tests are written out by hand from the vendor manual (header 55 55, ID,
length, command, parameters, checksum = ~(ID + length + command + parameters)), not
produced by busarm's own codec.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator

import pytest
import serial

from busarm.bench.bus import SimServerProcess
from busarm.bus.driver import ServoBus
from conftest import PTY_MARGIN_S

pytestmark = pytest.mark.wallclock(
    "other programs talk to `busarm sim serve`, a process of its own serving a pty in "
    "wall-clock time")

SETTLE_BUDGET_S = 10.0
"""How long a move of servo 2 to 600 may take to show (it takes well under a second, on
the wall clock: generous, as a loaded machine may run the server late; only a failing
test waits it out)."""


@contextlib.contextmanager
def sim_server(*args: str) -> Iterator[str]:
    """``busarm sim serve ARGS`` in a subprocess; yields its pty path, then checks
    that SIGINT stopped it cleanly."""
    server = SimServerProcess(*args)
    with server as path:
        yield path
    assert server.returncode == 0, server.stderr


def transact(port: serial.Serial, request: str, reply_len: int) -> bytes:
    port.reset_input_buffer()
    port.write(bytes.fromhex(request))
    return bytes(port.read(reply_len))


# (request, expected reply), as hex, for servos 1 and 2 at power-on:
# position 500 (0x01f4), 11.1 V (0x2b5c), 25 C (0x19).
EXCHANGES = [
    ("55 55 01 03 1c df", "55 55 01 05 1c f4 01 e8"),  # POS_READ 1
    ("55 55 02 03 1c de", "55 55 02 05 1c f4 01 e7"),  # POS_READ 2
    ("55 55 01 03 1b e0", "55 55 01 05 1b 5c 2b 57"),  # VIN_READ 1
    ("55 55 02 03 1a e0", "55 55 02 04 1a 19 c6"),  # TEMP_READ 2
    ("55 55 01 03 0e ed", "55 55 01 04 0e 01 eb"),  # ID_READ 1
    ("55 55 02 03 15 e5", "55 55 02 07 15 00 00 e8 03 f6"),  # ANGLE_LIMIT_READ 2: 0..1000
]


def test_plain_pyserial_gets_the_exact_reply_bytes() -> None:
    with sim_server("--ids", "1,2") as path, serial.Serial(path, 115200, timeout=0.5) as port:
        for request, reply in EXCHANGES:
            expected = bytes.fromhex(reply)
            assert transact(port, request, len(expected)) == expected, request
            # ... and nothing after it.
            port.timeout = 0.02
            assert port.read(1) == b"", request
            port.timeout = 0.5

        # MOVE_TIME_WRITE servo 2 to 600 (0x0258) at full speed: no reply; then it is there.
        port.write(bytes.fromhex("55 55 02 07 01 58 02 00 00 9b"))
        there = bytes.fromhex("55 55 02 05 1c 58 02 82")
        deadline = time.monotonic() + SETTLE_BUDGET_S
        while transact(port, "55 55 02 03 1c de", 8) != there:
            assert time.monotonic() < deadline, "servo 2 never reached 600"
        assert transact(port, "55 55 01 03 1c df", 8) == bytes.fromhex("55 55 01 05 1c f4 01 e8")

        # No servo 3: silence, not an error frame.
        port.timeout = 0.05
        assert transact(port, "55 55 03 03 1c dd", 8) == b""
        # A request with a bad checksum is ignored too.
        assert transact(port, "55 55 01 03 1c 00", 8) == b""


def test_lewansoul_lx16a_library() -> None:
    import lewansoul_lx16a as lx16a  # a test dependency (the dev extra), never used by busarm
    with sim_server("--ids", "1,2") as path:
        with serial.Serial(path, 115200, timeout=0.5) as port:
            controller = lx16a.ServoController(port, timeout=0.5)
            assert controller.get_position(1) == 500
            assert controller.get_voltage(2) == 11100
            assert controller.get_temperature(1) == 25
            assert controller.get_servo_id(1) == 1
            assert controller.get_position_limits(2) == (0, 1000)
            controller.set_position_limits(2, 100, 900)
            assert controller.get_position_limits(2) == (100, 900)
            controller.move(2, 600, 0)
            deadline = time.monotonic() + SETTLE_BUDGET_S
            while controller.get_position(2) != 600:
                assert time.monotonic() < deadline, "servo 2 never reached 600"
            controller.led_off(1)
            assert controller.is_led_on(1) is False
            with pytest.raises(lx16a.TimeoutError):
                controller.get_position(3, timeout=0.05)
        # busarm sees what the other program did, on the same simulated servos.
        bus = ServoBus.open(path, timeout_margin_s=PTY_MARGIN_S)
        try:
            assert bus.read_position_pulses(2) == 600
            assert bus.read_angle_limits_deg(2) == pytest.approx((-96.0, 96.0))
            assert bus.read_led(1) is False
            assert bus.read_led(2) is True
        finally:
            bus.close()
