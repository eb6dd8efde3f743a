"""Transport selection and the USB latency check (with a stand-in sysfs tree)."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from busarm.bus.ports import open_transport
from busarm.bus.transport import adapter_latency_s, usb_latency_timer_ms
from busarm.errors import ConfigError, TransportError
from busarm.robot.port_url import parse_port


def _sysfs(tmp_path: Path, name: str, value: str) -> Path:
    d = tmp_path / "bus" / "usb-serial" / "devices" / name
    d.mkdir(parents=True)
    (d / "latency_timer").write_text(value + "\n")
    return tmp_path


def test_latency_timer_read_from_sysfs(tmp_path: Path) -> None:
    sysfs = _sysfs(tmp_path, "ttyUSB7", "16")
    assert usb_latency_timer_ms("/dev/ttyUSB7", sysfs=sysfs) == 16
    assert usb_latency_timer_ms("/dev/ttyUSB8", sysfs=sysfs) is None


def test_high_latency_timer_warns_with_the_fix(tmp_path: Path) -> None:
    sysfs = _sysfs(tmp_path, "ttyUSB0", "16")
    with pytest.warns(RuntimeWarning, match=r"16 ms.*echo 1 \| sudo tee .*ttyUSB0/latency_timer"):
        assert adapter_latency_s("/dev/ttyUSB0", sysfs=sysfs) == pytest.approx(0.016)


def test_one_ms_latency_timer_is_quiet(tmp_path: Path) -> None:
    sysfs = _sysfs(tmp_path, "ttyUSB0", "1")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert adapter_latency_s("/dev/ttyUSB0", sysfs=sysfs) == pytest.approx(0.001)


def test_unreadable_latency_timer_counts_as_unknown(tmp_path: Path) -> None:
    sysfs = _sysfs(tmp_path, "ttyUSB0", "garbage")
    assert adapter_latency_s("/dev/ttyUSB0", sysfs=sysfs) == 0.0


@pytest.mark.parametrize("port", ["", "   ", None, 3])
def test_bad_port_is_a_config_error(port: object) -> None:
    # Typed, below the edge: a device path or a PortSpec, and it says which it wanted.
    with pytest.raises(ConfigError, match=r"port: a .*(device path|PortSpec).*, got "):
        open_transport(port)  # type: ignore[arg-type]
    # At the edge, the command line's port string.
    with pytest.raises(ConfigError, match="port must be"):
        parse_port(port)  # type: ignore[arg-type]


@pytest.mark.parametrize("baud", [0, 1199, 4_000_001, 9600.5, True])
def test_bad_baudrate_is_a_config_error(baud: object) -> None:
    with pytest.raises(ConfigError, match="baudrate"):
        open_transport("loop://", baudrate=baud)  # type: ignore[arg-type]


def test_missing_device_is_a_transport_error(tmp_path: Path) -> None:
    with pytest.raises(TransportError, match="cannot open"):
        open_transport(str(tmp_path / "ttyUSB99"))


def test_unknown_url_scheme_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="cannot open"):
        open_transport("nosuch://x")


def test_loop_url_echoes_through_the_transport() -> None:
    t = open_transport("loop://")
    try:
        t.write(b"\x55\x55\x01\x03\x1c\xdf")
        assert t.read(64, 0.5) == b"\x55\x55\x01\x03\x1c\xdf"
        assert t.read(64, 0.01) == b""
    finally:
        t.close()
