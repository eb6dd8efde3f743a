"""The servo port: the one contract ``Arm`` (and every job above it) drives servos through.

A ``ServoPort`` is a set of position servos by ID, commanded and read in degrees from
each servo's mid-point and in seconds, with whole-pulse readings in its own
``ServoModel`` (how many degrees a pulse is, where the mid-point is, the range). Backends
are peers, each implementing the whole contract, chosen by name from ``SERVO_PORTS``
(python-can's interface table), which installed packages extend through the
entry-point group ``busarm.servo_ports``:

- ``lx``: LX bus servos on a serial line (``busarm.bus.driver.ServoBus``);
- ``board``: LX servos behind the vendor's controller board
  (``busarm.bus.board_bus.BoardServoBus``);
- ``zenoh``: a robot served on another computer (``busarm.bus.remote_port``).

``open_servo_port(kind, transport, **options)`` builds one on an open transport. What a
backend must do (and ``tests/conformance`` checks on every backend): a target outside
the servo's range or the limits set is refused before anything is sent (LimitError); a
servo that does not answer is a BusTimeoutError within the port's own budget, never a
hang; ``stop`` and ``emergency_stop`` hold the servos where they are; ``halt`` latches
that stop until ``rearm``. docs/adding_a_backend.md says how to write one.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Protocol, runtime_checkable

from busarm.clock import Clock
from busarm.errors import ConfigError
from busarm.lazy import backend_table, load_backend
from busarm.units import check_range

__all__ = [
    "ENTRY_POINT_GROUP",
    "SERVO_PORTS",
    "ServoModel",
    "ServoPort",
    "ServoState",
    "open_servo_port",
    "servo_port_kinds",
]


ENTRY_POINT_GROUP = "busarm.servo_ports"
SERVO_PORTS: dict[str, str] = {
    "lx": "busarm.bus.driver:ServoBus",
    "board": "busarm.bus.board_bus:BoardServoBus.on",
    "zenoh": "busarm.bus.remote_port:remote_servo_port",
}
"""Kind -> ``"module:factory"``; ``factory(transport, **options)`` returns a ServoPort.
Imported only when that kind is opened (a backend's own dependencies load with it)."""


@dataclass(frozen=True)
class ServoModel:
    """A servo family's position scale: pulses a degree, the mid-point, the range, and
    the longest timed move it takes."""

    name: str
    deg_per_pulse: float
    center_pulses: int
    min_pulses: int
    max_pulses: int
    max_move_s: float

    def __post_init__(self) -> None:
        check_range(f"{self.name} deg_per_pulse", self.deg_per_pulse, 1e-6, 360.0, "deg")
        check_range(f"{self.name} max_move_s", self.max_move_s, 0.001, 3600.0, "s")
        if not self.min_pulses < self.center_pulses < self.max_pulses:
            raise ConfigError(f"{self.name}: need min_pulses < center_pulses < max_pulses, "
                              f"got {self.min_pulses}, {self.center_pulses}, "
                              f"{self.max_pulses}")

    @property
    def min_deg(self) -> float:
        return self.deg_from_pulses(self.min_pulses)

    @property
    def max_deg(self) -> float:
        return self.deg_from_pulses(self.max_pulses)

    def deg_from_pulses(self, position_pulses: float) -> float:
        """Degrees from the mid-point for a position in (possibly fractional) pulses."""
        return (position_pulses - self.center_pulses) * self.deg_per_pulse

    def pulses_exact(self, angle_deg: float) -> float:
        """The fractional position for an angle (not rounded, not range-checked)."""
        return self.center_pulses + angle_deg / self.deg_per_pulse

    def pulses_from_deg(self, angle_deg: float) -> int:
        """The nearest whole position for an angle; ConfigError outside the range."""
        check_range("angle_deg", angle_deg, self.min_deg, self.max_deg, "deg")
        return round(self.pulses_exact(angle_deg))


@dataclass(frozen=True)
class ServoState:
    """One servo's live readings."""

    servo_id: int
    position_deg: float
    temp_c: int
    vin_v: float


@runtime_checkable
class ServoPort(Protocol):
    """Position servos by ID, in degrees from their mid-point and seconds (see the module
    docstring). Thread-safe; a context manager whose exit on an exception stops and holds
    the servos (if anything was written since the last stop), then closes the port."""

    @property
    def model(self) -> ServoModel:
        """The servos' position scale: what a pulse of ``read_position_pulses`` is."""
        ...

    @property
    def clock(self) -> Clock:
        """The port's time: every wait on these servos (simulated seconds on a twin)."""
        ...

    @property
    def name(self) -> str:
        """Where the port is open (a device, a URL): for messages."""
        ...

    @property
    def wrote(self) -> bool:
        """Whether anything that can move or change a servo has been sent."""
        ...

    @property
    def written_ids(self) -> set[int]:
        """The servos written to by ID."""
        ...

    @property
    def halted(self) -> str | None:
        """Why the port is halted (``halt``), or None."""
        ...

    # ------------------------------------------------------------------ reading

    def read_position_pulses(self, servo_id: int) -> int:
        """The servo's position in whole pulses of ``model``."""
        ...

    def read_position_deg(self, servo_id: int) -> float: ...

    def read_positions_deg(self, servo_ids: Iterable[int]) -> dict[int, float]: ...

    def last_target_pulses(self, servo_id: int) -> int | None:
        """Where the servo was last told to go (pulses), or None if unknown."""
        ...

    def read_torque(self, servo_id: int) -> bool: ...

    def read_offset_deg(self, servo_id: int) -> float: ...

    def read_angle_limits_deg(self, servo_id: int) -> tuple[float, float]:
        """The servo's own stored angle limits (it clamps every target to them)."""
        ...

    def read_temp_c(self, servo_id: int) -> int: ...

    def read_vin_v(self, servo_id: int) -> float: ...

    def read_temp_limit_c(self, servo_id: int) -> int: ...

    def read_vin_limits_v(self, servo_id: int) -> tuple[float, float]: ...

    def read_states(self, servo_ids: Iterable[int]) -> list[ServoState]: ...

    # ------------------------------------------------------------------ moving

    def set_limits_deg(self, servo_id: int, min_deg: float, max_deg: float) -> None:
        """Software limits: a move outside them raises LimitError, sending nothing."""
        ...

    def move_deg(self, servo_id: int, angle_deg: float, duration_s: float = 0.0) -> None:
        """Go to ``angle_deg`` at uniform speed over ``duration_s``."""
        ...

    def sync_move_deg(self, targets_deg: Mapping[int, float], duration_s: float | None = None,
                      *, speed_deg_s: float | None = None) -> float:
        """Move several servos so that they start and arrive together (every target checked
        before anything is sent); give ``duration_s`` or ``speed_deg_s``. Returns the
        duration in seconds."""
        ...

    def wait_until_reached(self, targets_deg: Mapping[int, float], *,
                           tolerance_deg: float = 1.0, timeout_s: float | None = None
                           ) -> dict[int, float]:
        """Poll until every servo is within ``tolerance_deg``; MotionTimeoutError naming
        those that are not by ``timeout_s`` (default: the end of their last move + 2 s)."""
        ...

    def move_end_s(self, servo_ids: Iterable[int]) -> float:
        """When (on ``clock``) the last move commanded to any of ``servo_ids`` ends."""
        ...

    def set_torque(self, servo_id: int, enabled: bool) -> None: ...

    def adjust_offset_deg(self, servo_id: int, offset_deg: float) -> None: ...

    def save_offset(self, servo_id: int) -> None: ...

    # ------------------------------------------------------------------ stopping

    def stop(self, servo_ids: Iterable[int] | None = None) -> None:
        """Stop moving and hold where they are (every servo if none given)."""
        ...

    def emergency_stop(self) -> None:
        """Stop every servo and hold; never raises."""
        ...

    def halt(self, why: str = "e-stop") -> None:
        """``emergency_stop`` now, and every later write but a stop raises HaltedError
        (from any thread) until ``rearm()``."""
        ...

    def rearm(self) -> None: ...

    def close(self) -> None: ...

    def __enter__(self) -> ServoPort: ...

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None: ...


def servo_port_kinds() -> dict[str, str]:
    """Every servo port kind: ``SERVO_PORTS`` and those of the ``busarm.servo_ports``
    entry-point group."""
    return backend_table(SERVO_PORTS, ENTRY_POINT_GROUP)


def open_servo_port(kind: str, transport: Any, **options: Any) -> ServoPort:
    """A ServoPort of ``kind`` (``lx``, ``board``, ``zenoh`` or a plugin's) on an open
    ``transport``; ``options`` go to the backend. ConfigError for an unknown kind or a
    factory that gives something else than a ServoPort."""
    factory: Callable[..., Any] = load_backend("servo port", kind, servo_port_kinds())
    port = factory(transport, **options)
    if not isinstance(port, ServoPort):
        raise ConfigError(f"servo port {kind!r}: the factory gave a {type(port).__name__}, "
                          "which is not a ServoPort (docs/adding_a_backend.md)")
    return port
