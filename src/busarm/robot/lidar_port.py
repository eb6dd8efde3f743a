"""Opening the robot's Lidar: a real A1 on its port, the simulated one, or the twin's.

The Lidar layer knows devices and transports; a twin's Lidar lives in the twin, above
it, so the one place that opens "whatever Lidar this port is" is here.
"""

from __future__ import annotations

from busarm.bus.ports import SerialPort
from busarm.errors import ConfigError
from busarm.lidar.rplidar import IDENTIFY_TIMEOUT_S, RplidarA1, open_lidar
from busarm.sim.spec import SimLidarSpec
from busarm.sim.transport import SimTransport
from busarm.twin.lidar import lidar_for_twin
from busarm.twin.spec import TwinSpec
from busarm.twin.transport import TwinTransport
from busarm.twin.twin import Twin

__all__ = [
    "open_lidar_port",
    "twin_lidar",
]


def twin_lidar(twin: Twin) -> RplidarA1:
    """The twin's simulated A1, read through its bytes by the A1 driver (the twin stays
    open when the Lidar closes)."""
    return RplidarA1(SimTransport(lidar_for_twin(twin, noise=twin.lidar_noise),
                                  name="the twin's Lidar"), timeout_s=IDENTIFY_TIMEOUT_S)


def open_lidar_port(port: SerialPort | SimLidarSpec | TwinSpec) -> RplidarA1:
    """The A1 at ``port``: a device, the simulated A1, or a twin with an arena (a twin
    made for it, closed with it)."""
    if isinstance(port, SerialPort):
        return open_lidar(port.device)
    if isinstance(port, SimLidarSpec):
        return open_lidar(port.open())
    twin = port.build()
    try:
        if twin.arena is None:
            raise ConfigError(f"Lidar port {port.name!r}: this twin is an arm on a table, with "
                              "no Lidar; give twin://?family=arena[&seed=N] or arena=FILE")
        device = lidar_for_twin(twin, noise=twin.lidar_noise)
        return RplidarA1(TwinTransport(twin, name=port.name, line=device))
    except BaseException:
        twin.close()
        raise
