"""Where a robot's line is, typed: a ``PortSpec`` says it once and opens its transport.

A port is told once, at the edge (a robot file, or the command line's ``--port`` read by
``busarm.robot.port_url``), as one of these; below that nothing reads or rebuilds a
string. This module holds the hardware kinds: a serial device (a path, or a pyserial
URL, which is pyserial's own address), alone or behind the vendor's controller board.
The simulated kinds live with their simulators (``busarm.sim.spec.SimSpec``,
``busarm.twin.spec.TwinSpec``) and the remote robot with its link
(``busarm.bus.zenoh_link.ZenohPort``); each opens its own transport, so this layer
never imports them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

from busarm.bus.transport import (
    BOARD_BAUDRATE,
    DEFAULT_BAUDRATE,
    Transport,
    check_baudrate,
    check_device,
    open_serial,
)
from busarm.errors import ConfigError
from busarm.fileio import robot_key

__all__ = [
    "PortSpec",
    "SerialPort",
    "open_transport",
]


@runtime_checkable
class PortSpec(Protocol):
    """A robot's line, typed: what kind it is and how to open it."""

    @property
    def name(self) -> str:
        """How a person names it (the port as given, or the kind: ``twin``, ``sim``)."""
        ...

    @property
    def robot_key(self) -> str:
        """The folder name of this robot's kept files (calibrations, poses)."""
        ...

    @property
    def through_board(self) -> bool:
        """Whether the servos are behind a controller board (its frames, its wheels)."""
        ...

    def check(self) -> None:
        """Raise (TransportError, ConfigError) before opening if it cannot be opened."""
        ...

    def open(self, baudrate: int = DEFAULT_BAUDRATE) -> Transport:
        """Open its transport (``baudrate``: the servo line's; a board's link is fixed)."""
        ...


@dataclass(frozen=True)
class SerialPort:
    """A serial device: ``/dev/ttyUSB0``, ``COM3``, or a pyserial URL
    (``socket://host:port``, ``rfc2217://...``, ``loop://``); ``board``: the servos
    are behind the vendor's controller board on it (its frames at 1,000,000 baud)."""

    device: str
    board: bool = False
    label: str = field(default="", compare=False)
    """The port in the user's own words (for messages), if given that way."""

    def __post_init__(self) -> None:
        if not isinstance(self.device, str) or not self.device.strip():
            raise ConfigError(f"port: a serial device path or pyserial URL, got "
                              f"{self.device!r}")

    @property
    def name(self) -> str:
        return self.label or (f"the controller board on {self.device}" if self.board
                              else self.device)

    @property
    def robot_key(self) -> str:
        return robot_key(self.device)

    @property
    def through_board(self) -> bool:
        return self.board

    def check(self) -> None:
        check_device(self.device)

    def open(self, baudrate: int = DEFAULT_BAUDRATE) -> Transport:
        if self.board:
            return open_serial(self.device, BOARD_BAUDRATE, name=self.name, framing="board")
        return open_serial(self.device, baudrate, name=self.device, framing="lx")

    def __repr__(self) -> str:
        return f"SerialPort({self.device!r}{', board=True' if self.board else ''})"


def open_transport(port: PortSpec | str, *, baudrate: int = DEFAULT_BAUDRATE) -> Transport:
    """Open ``port``: a ``PortSpec``, or a serial device's path or pyserial URL
    (``baudrate`` is the servo line's; a controller board's link is always 1,000,000 baud)."""
    baudrate = check_baudrate(baudrate)
    if isinstance(port, str):
        return SerialPort(port).open(baudrate)
    if not isinstance(port, PortSpec):
        raise ConfigError(f"port: a PortSpec (SerialPort, SimSpec, TwinSpec, ZenohPort) or a "
                          f"device path, got {port!r}")
    return port.open(baudrate)
