"""The backend tables: a name picks a backend (servo port, Lidar model, camera scheme),
installed packages add names through entry-point groups (python-can's pattern), a
built-in name cannot be taken over, and a factory that gives something else than the
contract is refused."""

from __future__ import annotations

import importlib.metadata
from typing import Any

import numpy as np
import pytest

from busarm.bus.servo_port import SERVO_PORTS, ServoPort, open_servo_port, servo_port_kinds
from busarm.errors import ConfigError
from busarm.lidar.scan import LaserScan
from busarm.lidar.sources import lidar_models, open_lidar_source
from busarm.sim.bus import SimBus
from busarm.sim.transport import SimTransport
from busarm.vision.camera import CameraBase, camera_schemes, open_camera
from conformance.example_backend import ToyServoPort, ToyWire


def installed(monkeypatch: pytest.MonkeyPatch, group: str, **names: str) -> None:
    """Pretend an installed package declares ``names`` in the entry-point ``group``."""
    real = importlib.metadata.entry_points

    def entry_points(**selection: Any) -> importlib.metadata.EntryPoints:
        if selection.get("group") != group:
            return real(**selection)
        return importlib.metadata.EntryPoints(
            importlib.metadata.EntryPoint(name, value, group) for name, value in names.items())

    monkeypatch.setattr(importlib.metadata, "entry_points", entry_points)


# ---------------------------------------------------------------------- servo ports


def test_the_servo_ports_are_the_lx_line_the_board_and_a_served_robot() -> None:
    assert {"lx", "board", "zenoh"} <= set(servo_port_kinds())
    with pytest.raises(ConfigError, match="servo port 'acme' is not known; known: board, "):
        open_servo_port("acme", None)


def test_an_installed_package_adds_a_servo_family(monkeypatch: pytest.MonkeyPatch) -> None:
    assert "toy" not in SERVO_PORTS
    installed(monkeypatch, "busarm.servo_ports", toy="conformance.example_backend:open_toy_port",
              lx="conformance.example_backend:open_toy_port")
    assert servo_port_kinds()["toy"] == "conformance.example_backend:open_toy_port"
    port = open_servo_port("toy", ToyWire())
    assert isinstance(port, ToyServoPort) and isinstance(port, ServoPort)
    # A plugin cannot take over a built-in name.
    assert servo_port_kinds()["lx"] == SERVO_PORTS["lx"]
    with open_servo_port("lx", SimTransport(SimBus.with_ids((1,)))) as lx:
        assert not isinstance(lx, ToyServoPort)


def not_a_port(transport: object) -> object:
    return object()


def test_a_factory_that_gives_no_servo_port_is_refused(monkeypatch: pytest.MonkeyPatch
                                                        ) -> None:
    monkeypatch.setitem(SERVO_PORTS, "odd", "conformance.test_backend_tables:not_a_port")
    monkeypatch.setitem(SERVO_PORTS, "gone", "no_such_module:factory")
    with pytest.raises(ConfigError, match="the factory gave a object, which is not a "
                                          "ServoPort"):
        open_servo_port("odd", None)
    with pytest.raises(ConfigError, match="servo port 'gone': cannot load no_such_module"):
        open_servo_port("gone", None)


def test_the_zenoh_port_needs_a_zenoh_link() -> None:
    with pytest.raises(ConfigError, match="needs a Zenoh link"):
        open_servo_port("zenoh", SimTransport(SimBus.with_ids((1,))))


# ---------------------------------------------------------------------- Lidars, cameras


class StillLidar:
    """A Lidar that always sees a wall 1 m away all round (a plugin's, in this test)."""

    def __init__(self, where: str) -> None:
        self.where = where

    def read_scan(self, timeout_s: float) -> LaserScan:
        angles = np.linspace(0.0, 2 * np.pi, 360, endpoint=False)
        return LaserScan(angles, np.ones(360), np.full(360, 40.0), 0.0, 0.15, 12.0)

    def close(self) -> None:
        pass


class StillCamera(CameraBase):
    """A camera that always gives the same grey picture (a plugin's, in this test)."""

    def __init__(self, spec: str, *, shade: int = 128) -> None:
        super().__init__(spec, 64, 48)
        self.shade = shade

    def _grab(self) -> np.ndarray:
        return np.full((48, 64, 3), self.shade, dtype=np.uint8)

    def _release(self) -> None:
        pass


def test_an_installed_package_adds_a_lidar_model(monkeypatch: pytest.MonkeyPatch) -> None:
    assert {"rplidar-a1", "twin"} <= set(lidar_models())
    installed(monkeypatch, "busarm.lidars", still="conformance.test_backend_tables:StillLidar",
              odd="conformance.test_backend_tables:not_a_port")
    source = open_lidar_source("still", "here")
    assert isinstance(source, StillLidar) and source.where == "here"
    assert np.all(source.read_scan(1.0).ranges_m == 1.0)
    with pytest.raises(ConfigError, match="Lidar model 'odd': the factory gave a object, "
                                          "which is not a LidarSource"):
        open_lidar_source("odd", "here")


def test_an_installed_package_adds_a_camera_scheme(monkeypatch: pytest.MonkeyPatch) -> None:
    installed(monkeypatch, "busarm.cameras", still="conformance.test_backend_tables:StillCamera",
              twin="conformance.test_backend_tables:StillCamera")
    assert camera_schemes()["still"] == "conformance.test_backend_tables:StillCamera"
    assert camera_schemes()["twin"] == "busarm.twin.camera:open_twin_camera"  # built in
    with open_camera("still://front", shade=200) as camera:
        frame = camera.read()
        assert frame.image.shape == (48, 64, 3) and int(frame.image[0, 0, 0]) == 200
    with pytest.raises(ConfigError, match="option.*not accepted"):
        open_camera("still://front", exposure=3)
