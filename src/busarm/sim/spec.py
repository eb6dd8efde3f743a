"""The simulators as ports, typed: ``SimSpec`` (simulated servos, optionally behind a
simulated controller board: ``BoardSettings``) and ``SimLidarSpec`` (a simulated A1).

Each is checked once when made (every value against its range, ConfigError naming the
key, the value and what is allowed) and opens its transport in this process. The command
line's ``sim://?ids=1,2&echo=1``, ``board://sim?...`` and ``lidar://sim?...`` are read into
these by ``busarm.robot.port_url``; a robot file's ``[world]`` table likewise.

The simulator runs on a simulated clock (``busarm.clock.SimClock``), as the twin does:
a move or a reply waited for costs only the CPU it takes to simulate, and every time
reported is simulated seconds. ``realtime`` puts it on the wall clock (to time a program
against a real line's pace); ``pace=1`` keeps simulated time no faster than the wall
clock, for a person watching.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from busarm.bus.transport import DEFAULT_BAUDRATE
from busarm.clock import WALL_CLOCK, Clock, SimClock
from busarm.errors import ConfigError
from busarm.protocol import SERVO_TURNAROUND_S
from busarm.protocol.rplidar import Health, HealthStatus
from busarm.sim.board import BATTERY_HZ, IMU_HZ, BoardFaults, SimBoard
from busarm.sim.bus import ARM_SERVO_IDS, FaultInjection, SimBus, WireTiming
from busarm.sim.rplidar import SimRplidar
from busarm.sim.transport import SimTransport
from busarm.units import check_int_range, check_range, short_repr

__all__ = [
    "BoardSettings",
    "SimLidarSpec",
    "SimSpec",
    "check_flag",
    "check_pace",
]


def check_flag(what: str, value: object) -> bool:
    """``value`` if it is a bool; ConfigError naming ``what`` otherwise."""
    if not isinstance(value, bool):
        raise ConfigError(f"{what} must be true or false, got {value!r}")
    return value


def check_pace(what: str, pace: float | None, realtime: bool) -> None:
    """A pace (simulated seconds per wall second) is 0.01..1000, and not with realtime."""
    if pace is None:
        return
    check_range(f"{what}: pace", pace, 0.01, 1000.0)
    if realtime:
        raise ConfigError(f"{what}: pace and realtime exclude each other: realtime is the "
                          "wall clock")


@dataclass(frozen=True)
class BoardSettings:
    """The simulated controller board in front of simulated servos (``board://sim``):
    its sensor rates, battery, wheel encoders and injected faults."""

    __repr__ = short_repr

    imu_hz: float = IMU_HZ
    battery_hz: float = BATTERY_HZ
    battery_v: float = 12.3
    encoders: bool = True
    silent: bool = False
    board_corrupt: float = 0.0
    wrong_id: float = 0.0
    board_seed: int = 0

    def __post_init__(self) -> None:
        check_range("board: imu_hz", self.imu_hz, 0.0, 5000.0, "Hz")
        check_range("board: battery_hz", self.battery_hz, 0.0, 100.0, "Hz")
        check_range("board: battery_v", self.battery_v, 0.0, 30.0, "V")
        check_range("board: board_corrupt", self.board_corrupt, 0.0, 1.0)
        check_range("board: wrong_id", self.wrong_id, 0.0, 1.0)
        check_int_range("board: board_seed", self.board_seed, 0, 2**32 - 1)
        check_flag("board: encoders", self.encoders)
        check_flag("board: silent", self.silent)

    def build(self, servos: SimBus) -> SimBoard:
        """A simulated board in front of ``servos``."""
        faults = BoardFaults(silent=self.silent, corrupt_rate=self.board_corrupt,
                             wrong_id_rate=self.wrong_id, seed=self.board_seed)
        return SimBoard(servos, imu_hz=self.imu_hz, battery_hz=self.battery_hz,
                        battery_v=self.battery_v, faults=faults, seed=self.board_seed,
                        encoders=self.encoders)


@dataclass(frozen=True)
class SimSpec:
    """Simulated servos (``sim``): the arm's IDs by default, with an adapter that may echo,
    wire timing, injected faults (probabilities per byte; ``late`` per reply), a state
    file kept at power-off, a block in the gripper; ``controller``: behind a simulated
    controller board."""

    __repr__ = short_repr

    ids: tuple[int, ...] = tuple(ARM_SERVO_IDS)
    echo: bool = False
    timing: bool = True
    turnaround_ms: float = SERVO_TURNAROUND_S * 1000
    drop: float = 0.0
    corrupt: float = 0.0
    late: float = 0.0
    late_ms: float = 50.0
    seed: int = 0
    state: Path | None = None
    block: bool = False
    realtime: bool = False
    pace: float | None = None
    controller: BoardSettings | None = None
    label: str = field(default="", compare=False)
    """The port in the user's own words (for messages), if given that way."""

    def __post_init__(self) -> None:
        if self.controller is not None and not isinstance(self.controller, BoardSettings):
            raise ConfigError(f"sim: controller must be a BoardSettings() (the simulated "
                              f"controller board in front), got {self.controller!r}")
        for sid in self.ids:
            check_int_range("sim: ids", sid, 0, 253)
        for key in ("echo", "timing", "block", "realtime"):
            check_flag(f"sim: {key}", getattr(self, key))
        check_range("sim: turnaround_ms", self.turnaround_ms, 0.0, 100.0, "ms")
        for key in ("drop", "corrupt", "late"):
            check_range(f"sim: {key}", getattr(self, key), 0.0, 1.0)
        check_range("sim: late_ms", self.late_ms, 0.0, 10000.0, "ms")
        check_int_range("sim: seed", self.seed, 0, 2**32 - 1)
        check_pace("sim", self.pace, self.realtime)

    @property
    def name(self) -> str:
        return self.label or ("sim behind a simulated board" if self.controller is not None
                              else "sim")

    @property
    def robot_key(self) -> str:
        return "sim"

    @property
    def through_board(self) -> bool:
        return self.controller is not None

    def check(self) -> None:
        """Nothing to check before opening: the simulator is always there."""

    def clock(self) -> Clock:
        """The wall clock with ``realtime``, else a simulated one (paced by ``pace``)."""
        if self.realtime:
            return WALL_CLOCK
        return SimClock() if self.pace is None else SimClock(pace=self.pace)

    def build(self, baudrate: int = DEFAULT_BAUDRATE) -> SimBus:
        """The simulated servos (without the board)."""
        faults = FaultInjection(drop_rate=self.drop, corrupt_rate=self.corrupt,
                                late_rate=self.late, late_s=self.late_ms / 1000.0,
                                seed=self.seed)
        timing = WireTiming(baudrate, self.turnaround_ms / 1000.0, self.timing)
        bus = SimBus.with_ids(list(self.ids), timing=timing, echo=self.echo, faults=faults,
                              state_file=self.state, clock=self.clock())
        if self.block:
            bus.put_block_in_gripper()
        return bus

    def open(self, baudrate: int = DEFAULT_BAUDRATE) -> SimTransport:
        servos = self.build(baudrate)
        line = servos if self.controller is None else self.controller.build(servos)
        return SimTransport(line, name=self.name)


@dataclass(frozen=True)
class SimLidarSpec:
    """A simulated RPLIDAR A1 (``lidar://sim``): ``hz`` revolutions a second, ``silent``
    (answers nothing), ``garbage`` (probability per node of random bytes before it),
    ``seed`` (of the garbage), ``health`` (0 good, 1 warning, 2 error)."""

    __repr__ = short_repr

    hz: float = 5.5
    silent: bool = False
    garbage: float = 0.0
    seed: int = 0
    health: int = 0
    label: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        check_range("lidar: hz", self.hz, 2.0, 10.0, "Hz")
        check_range("lidar: garbage", self.garbage, 0.0, 1.0)
        check_int_range("lidar: seed", self.seed, 0, 2**32 - 1)
        check_flag("lidar: silent", self.silent)
        if self.health not in (0, 1, 2) or isinstance(self.health, bool):
            raise ConfigError(f"lidar: health = {self.health!r}; allowed: 0, 1 or 2")

    @property
    def name(self) -> str:
        return self.label or "the simulated A1"

    def open(self, clock: Clock | None = None) -> SimTransport:
        """The simulated A1 in this process, on its own simulated clock (scans take no
        wall time) unless ``clock`` is given."""
        status = HealthStatus(self.health)
        device = SimRplidar(scan_hz=self.hz, garbage_rate=self.garbage, seed=self.seed,
                            silent=self.silent, clock=clock,
                            health=Health(status, 0 if self.health == 0 else 0x8001))
        return SimTransport(device, name=self.name)
