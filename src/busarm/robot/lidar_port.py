"""Opening the robot's Lidar: a real A1 on its port, the simulated one, or the twin's.

The Lidar layer knows devices and ``lidar://sim``; a twin's Lidar lives in the twin, above
it, so the one place that opens "whatever Lidar this port means" is here.
"""

from __future__ import annotations

from busarm.errors import ConfigError
from busarm.lidar.rplidar import IDENTIFY_TIMEOUT_S, RplidarA1, open_lidar
from busarm.sim.transport import SimTransport
from busarm.twin.lidar import lidar_for_twin
from busarm.twin.transport import TwinTransport, is_twin_url, twin_from_url
from busarm.twin.twin import Twin

__all__ = [
    "open_any_lidar",
    "twin_lidar",
]


def twin_lidar(twin: Twin) -> RplidarA1:
    """The twin's simulated A1, read through its bytes by the A1 driver (the twin stays
    open when the Lidar closes)."""
    return RplidarA1(SimTransport(lidar_for_twin(twin, noise=twin.lidar_noise),
                                  name="the twin's Lidar"), timeout_s=IDENTIFY_TIMEOUT_S)


def open_any_lidar(port: str) -> RplidarA1:
    """The A1 on ``port``: a device or pyserial URL, ``lidar://sim?...``, or a twin URL with
    an arena (``twin://?family=arena&seed=3``: a twin made for it, closed with it)."""
    if not is_twin_url(port):
        return open_lidar(port)
    twin = twin_from_url(port)
    try:
        if twin.arena is None:
            raise ConfigError(f"Lidar port {port!r}: this twin is an arm on a table, with no "
                              "Lidar; give twin://?family=arena[&seed=N] or arena=FILE")
        device = lidar_for_twin(twin, noise=twin.lidar_noise)
        return RplidarA1(TwinTransport(twin, name=port, line=device))
    except BaseException:
        twin.close()
        raise
