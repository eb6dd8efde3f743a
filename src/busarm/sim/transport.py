"""The simulator as an in-process transport: a simulated line (servos, a controller board
in front of them, a Lidar) behind the ``Transport`` interface.

What is simulated and how (IDs, echo, faults, clock) is a ``busarm.sim.spec.SimSpec``;
this module moves its bytes.
"""

from __future__ import annotations

import threading

from busarm.errors import TransportError
from busarm.sim.bus import SimLine

__all__ = [
    "SimTransport",
]


class SimTransport:
    """A transport whose other end is a simulated line in this process: a SimBus, or a
    SimBoard in front of one."""

    def __init__(self, bus: SimLine, name: str = "sim") -> None:
        self.bus = bus
        self.name = name
        self.framing = bus.framing
        self.baudrate = bus.timing.baudrate
        self.latency_s = 0.0
        self.clock = bus.clock
        self._closed = False
        self._lock = threading.Lock()

    def write(self, data: bytes) -> None:
        self._check_open()
        self.bus.receive(bytes(data))

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        self._check_open()
        clock = self.clock
        deadline = clock.now() + max(timeout_s, 0.0)
        with self._lock:
            while True:
                data = self.bus.pop_output(max_bytes)
                if data:
                    return data
                now = clock.now()
                due = self.bus.next_output_at()
                if now >= deadline:
                    return b""
                wake = deadline if due is None else min(max(due, now), deadline)
                clock.sleep(max(wake - now, 0.0))

    def reset_input(self) -> None:
        self._check_open()
        self.bus.pop_output()

    def exchange(self, request: bytes, timeout_s: float) -> bytes:
        self.reset_input()
        self.write(request)
        return self.read(256, timeout_s)

    def close(self) -> None:
        """Close; the servos power off, saving their state file (``state=``) with each
        horn where it is, as a real servo's horn stays where the power left it."""
        if not self._closed:
            self._closed = True
            self.bus.power_off()

    def _check_open(self) -> None:
        if self._closed:
            raise TransportError(f"{self.name}: transport is closed")
