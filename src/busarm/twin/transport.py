"""The twin as an in-process transport: its servo bus, or another simulated line of it (a
controller board in front of its servos, its Lidar).

Which twin is a ``busarm.twin.spec.TwinSpec`` (``TwinSpec().open()`` makes one behind
this transport). Closing the transport closes the twin; ``transport.twin`` is the twin,
for whoever opened it (``busarm.robot`` hands it out).
"""

from __future__ import annotations

from busarm.sim.bus import SimLine
from busarm.sim.transport import SimTransport
from busarm.twin.twin import Twin

__all__ = [
    "TwinTransport",
]


class TwinTransport(SimTransport):
    """A transport to a twin's simulated bus, or to another simulated line of it (``line``:
    a controller board in front of its servos, its Lidar); closing it closes the twin."""

    def __init__(self, twin: Twin, name: str = "twin", *, line: SimLine | None = None) -> None:
        super().__init__(line if line is not None else twin.bus, name)
        self.twin = twin

    def close(self) -> None:
        super().close()
        self.twin.close()
