"""Lidar sources named by model: ``open_lidar_source("rplidar-a1", "/dev/ttyUSB1")``.

``LIDARS`` maps a model to ``"module:factory"`` (python-can's interface table), imported
only when that model is opened; installed packages add theirs under the entry-point
group ``busarm.lidars``. A factory takes where the Lidar is (its first argument: a
device path, an open transport, a twin...) and options, and returns a ``LidarSource``:

- ``rplidar-a1``: the Slamtec RPLIDAR A1 on a device path, a pyserial URL or an open
  transport (``busarm.lidar.rplidar.open_lidar``);
- ``twin``: a twin's own A1, ray-cast in its arena (``busarm.robot.lidar_port.twin_lidar``,
  given the ``Twin``), read through the same driver.

Every source keeps the ``LidarSource`` contract (busarm.lidar.scan): ``read_scan`` gives
one revolution or raises BusTimeoutError by its timeout, ``close`` stops the device;
tests/conformance/test_lidar_conformance.py checks it on each.
"""

from __future__ import annotations

from typing import Any

from busarm.errors import ConfigError
from busarm.lazy import backend_table, load_backend
from busarm.lidar.scan import LidarSource

__all__ = [
    "ENTRY_POINT_GROUP",
    "LIDARS",
    "lidar_models",
    "open_lidar_source",
]


ENTRY_POINT_GROUP = "busarm.lidars"
LIDARS: dict[str, str] = {
    "rplidar-a1": "busarm.lidar.rplidar:open_lidar",
    "twin": "busarm.robot.lidar_port:twin_lidar",
}
"""Model -> ``"module:factory"``; ``factory(where, **options)`` returns a LidarSource.
Higher layers (the twin's) are named here only as text, imported when chosen."""


def lidar_models() -> dict[str, str]:
    """Every Lidar model: ``LIDARS`` and those of the ``busarm.lidars`` entry-point group."""
    return backend_table(LIDARS, ENTRY_POINT_GROUP)


def open_lidar_source(model: str, where: Any, **options: Any) -> LidarSource:
    """The Lidar of ``model`` at ``where`` (what its factory opens: a device, a transport,
    a twin); ``options`` go to the factory. ConfigError for an unknown model, or a
    factory that gives something else than a LidarSource."""
    source = load_backend("Lidar model", model, lidar_models())(where, **options)
    if not isinstance(source, LidarSource):
        raise ConfigError(f"Lidar model {model!r}: the factory gave a "
                          f"{type(source).__name__}, which is not a LidarSource "
                          "(docs/adding_a_backend.md)")
    return source
