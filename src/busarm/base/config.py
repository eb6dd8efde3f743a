"""The mobile base's description from a TOML file: wheels, motors, limits, Lidar mount.

``load_chassis_config("jetauto")`` gives the shipped JetAuto mecanum chassis; any other
path is read as a file. Every value is checked as it is read; unknown keys are refused.
Axes as in ROS (REP 103): x forward, y left, z up, yaw counter-clockwise from above.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from busarm.tomlfile import TomlReader, load_toml, parse_toml

__all__ = [
    "DEFAULT_ARM_MOUNT",
    "DEFAULT_CHASSIS",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "MOTOR_COUNT",
    "SHIPPED",
    "WHEELS",
    "ChassisConfig",
    "Mount",
    "WheelMotor",
    "chassis_config_from_toml",
    "load_chassis_config",
]


FORMAT_NAME = "busarm.chassis"
FORMAT_VERSION = 1
SHIPPED = ("jetauto",)
DEFAULT_CHASSIS = "jetauto"
WHEELS = ("front_left", "rear_left", "front_right", "rear_right")
"""The wheel order of every per-wheel tuple in busarm.base."""
MOTOR_COUNT = 4


@dataclass(frozen=True)
class WheelMotor:
    """Which of the board's motors drives a wheel, and the sign that makes it roll forward."""

    motor: int
    sign: int


@dataclass(frozen=True)
class Mount:
    """Where a part sits on the base: the Lidar (its scan's origin and zero angle), the
    arm (its base frame), in the base frame (x forward, y left, z up from the floor)."""

    x_m: float
    y_m: float
    z_m: float
    yaw_rad: float


DEFAULT_ARM_MOUNT = Mount(0.0, 0.0, 0.145, 0.0)


@dataclass(frozen=True)
class ChassisConfig:
    """One mecanum chassis, in metres, seconds and radians."""

    name: str
    wheel_diameter_m: float
    track_m: float
    wheelbase_m: float
    encoder_ticks_per_rev: int
    max_wheel_rev_s: float
    motors: tuple[WheelMotor, WheelMotor, WheelMotor, WheelMotor]
    """In WHEELS order."""
    max_speed_m_s: float
    max_yaw_rate_rad_s: float
    max_accel_m_s2: float
    max_yaw_accel_rad_s2: float
    command_timeout_s: float
    lidar: Mount
    arm: Mount = DEFAULT_ARM_MOUNT
    """Where the arm's base frame is (on the JetAuto Pro: the top deck)."""
    source: str = ""

    @property
    def wheel_circumference_m(self) -> float:
        return math.pi * self.wheel_diameter_m

    @property
    def max_wheel_m_s(self) -> float:
        """The fastest a wheel's rim may go (the firmware's limit)."""
        return self.max_wheel_rev_s * self.wheel_circumference_m

    @property
    def half_spread_m(self) -> float:
        """Half the track plus half the wheelbase: the lever of yaw on each wheel."""
        return (self.track_m + self.wheelbase_m) / 2.0


def load_chassis_config(name_or_path: str | Path = DEFAULT_CHASSIS) -> ChassisConfig:
    """A shipped chassis by name (``jetauto``) or any TOML file by path."""
    data, source = load_toml(name_or_path, what="chassis config", package="busarm.base",
                             shipped=SHIPPED)
    return _Reader(source).chassis(data)


def chassis_config_from_toml(text: str, source: str = "<string>") -> ChassisConfig:
    """Parse and check a chassis description; errors name ``source`` and the key."""
    return _Reader(source).chassis(parse_toml(text, what="chassis config", source=source))


class _Reader(TomlReader):
    def __init__(self, source: str) -> None:
        super().__init__("chassis config", source)

    def chassis(self, data: dict[str, Any]) -> ChassisConfig:
        self.unknown(data, "top level", {"format", "version", "name", "wheels", "limits",
                                         "lidar", "arm"})
        name = self.header(data, FORMAT_NAME, FORMAT_VERSION)
        wheels = self.table(data, "wheels")
        self.unknown(wheels, "wheels", {"diameter_mm", "track_mm", "wheelbase_mm",
                                        "encoder_ticks_per_rev", "max_rev_s", "motors"})
        limits = self.table(data, "limits")
        self.unknown(limits, "limits", {"max_speed_m_s", "max_yaw_rate_deg_s", "max_accel_m_s2",
                                        "max_yaw_accel_deg_s2", "command_timeout_s"})
        return ChassisConfig(
            name=name,
            wheel_diameter_m=self.number(wheels, "diameter_mm", "wheels", 10, 1000) / 1000,
            track_m=self.number(wheels, "track_mm", "wheels", 10, 5000) / 1000,
            wheelbase_m=self.number(wheels, "wheelbase_mm", "wheels", 10, 5000) / 1000,
            encoder_ticks_per_rev=self.integer(wheels, "encoder_ticks_per_rev", "wheels", 1,
                                               1_000_000),
            max_wheel_rev_s=self.number(wheels, "max_rev_s", "wheels", 0.01, 100),
            motors=self.motors(self.table(wheels, "motors")),
            max_speed_m_s=self.number(limits, "max_speed_m_s", "limits", 0.01, 10),
            max_yaw_rate_rad_s=math.radians(
                self.number(limits, "max_yaw_rate_deg_s", "limits", 1, 3600)),
            max_accel_m_s2=self.number(limits, "max_accel_m_s2", "limits", 0.01, 50),
            max_yaw_accel_rad_s2=math.radians(
                self.number(limits, "max_yaw_accel_deg_s2", "limits", 1, 36000)),
            command_timeout_s=self.number(limits, "command_timeout_s", "limits", 0.05, 10,
                                          0.5),
            lidar=self.mount(data, "lidar", 150.0),
            arm=self.mount(data, "arm", 145.0),
            source=self.source,
        )

    def mount(self, data: dict[str, Any], key: str, default_z_mm: float) -> Mount:
        table = data.get(key, {})
        if not isinstance(table, dict):
            raise self.fail(key, "must be a table")
        self.unknown(table, key, {"x_mm", "y_mm", "z_mm", "yaw_deg"})
        return Mount(self.number(table, "x_mm", key, -2000, 2000, 0.0) / 1000,
                     self.number(table, "y_mm", key, -2000, 2000, 0.0) / 1000,
                     self.number(table, "z_mm", key, 0, 3000, default_z_mm) / 1000,
                     math.radians(self.number(table, "yaw_deg", key, -180, 180, 0.0)))

    def motors(self, data: dict[str, Any]) -> tuple[WheelMotor, WheelMotor, WheelMotor,
                                                    WheelMotor]:
        self.unknown(data, "wheels.motors", set(WHEELS))
        found: list[WheelMotor] = []
        for wheel in WHEELS:
            entry = data.get(wheel)
            where = f"wheels.motors.{wheel}"
            if not isinstance(entry, dict):
                raise self.fail(where, "missing" if entry is None else
                                "must be a table such as { motor = 1, sign = 1 }")
            self.unknown(entry, where, {"motor", "sign"})
            sign = self.integer(entry, "sign", where, -1, 1)
            if sign == 0:
                raise self.fail(f"{where}.sign", "must be 1 or -1, got 0")
            found.append(WheelMotor(self.integer(entry, "motor", where, 1, MOTOR_COUNT), sign))
        motors = [m.motor for m in found]
        if len(set(motors)) != MOTOR_COUNT:
            raise self.fail("wheels.motors", f"each wheel needs its own motor 1..4, got "
                                             f"{motors}")
        return found[0], found[1], found[2], found[3]
