"""The 28 commands of the LX bus-servo protocol, as data.

Each command's request and reply parameters are listed as typed fields with the
manual's ranges, so encoding, decoding and validation are driven by one table.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum, IntFlag

from busarm.errors import ConfigError

__all__ = [
    "BROADCAST_ID",
    "HEADER",
    "MAX_SERVO_ID",
    "SAVED_ON_POWER_OFF",
    "SERVO_TURNAROUND_S",
    "SPECS",
    "VALID_LENGTHS",
    "AlarmFlag",
    "Command",
    "CommandSpec",
    "Field",
    "ServoMode",
]


BROADCAST_ID = 254
"""Every servo obeys a frame to ID 254; only ID_READ is answered."""
MAX_SERVO_ID = 253
HEADER = b"\x55\x55"
SERVO_TURNAROUND_S = 0.0005
"""Assumed time a servo takes from the end of a request to the start of its reply:
the driver's default and the simulator's (both configurable)."""


class Command(IntEnum):
    """Command values of the manual's command table (names without the SERVO_ prefix)."""

    MOVE_TIME_WRITE = 1
    MOVE_TIME_READ = 2
    MOVE_TIME_WAIT_WRITE = 7
    MOVE_TIME_WAIT_READ = 8
    MOVE_START = 11
    MOVE_STOP = 12
    ID_WRITE = 13
    ID_READ = 14
    ANGLE_OFFSET_ADJUST = 17
    ANGLE_OFFSET_WRITE = 18
    ANGLE_OFFSET_READ = 19
    ANGLE_LIMIT_WRITE = 20
    ANGLE_LIMIT_READ = 21
    VIN_LIMIT_WRITE = 22
    VIN_LIMIT_READ = 23
    TEMP_MAX_LIMIT_WRITE = 24
    TEMP_MAX_LIMIT_READ = 25
    TEMP_READ = 26
    VIN_READ = 27
    POS_READ = 28
    OR_MOTOR_MODE_WRITE = 29
    OR_MOTOR_MODE_READ = 30
    LOAD_OR_UNLOAD_WRITE = 31
    LOAD_OR_UNLOAD_READ = 32
    LED_CTRL_WRITE = 33
    LED_CTRL_READ = 34
    LED_ERROR_WRITE = 35
    LED_ERROR_READ = 36

    @property
    def manual_name(self) -> str:
        """The name as the manual spells it, e.g. ``SERVO_POS_READ``."""
        return "SERVO_" + self.name

    @classmethod
    def parse(cls, text: str) -> Command:
        """A command from its value or name (``28``, ``POS_READ``, ``servo-pos-read``)."""
        t = text.strip()
        if t.isdigit():
            try:
                return cls(int(t))
            except ValueError:
                pass
        else:
            name = t.upper().replace("-", "_")
            name = name.removeprefix("SERVO_")
            if name in cls.__members__:
                return cls[name]
        known = ", ".join(f"{c.name}({c.value})" for c in cls)
        raise ConfigError(f"unknown command {text!r}; known commands: {known}")


class ServoMode(IntEnum):
    """SERVO_OR_MOTOR_MODE: position control or continuous-rotation motor."""

    POSITION = 0
    MOTOR = 1


class AlarmFlag(IntFlag):
    """Fault kinds of SERVO_LED_ERROR (bit values of the manual's alarm table)."""

    NONE = 0
    OVER_TEMPERATURE = 1
    OVER_VOLTAGE = 2
    STALLED = 4


# Wire layouts: (struct code, byte size).
_KINDS: dict[str, tuple[str, int]] = {
    "u8": ("B", 1), "s8": ("b", 1), "u16": ("H", 2), "s16": ("h", 2), "null": ("B", 1),
}


@dataclass(frozen=True)
class Field:
    """One parameter of a frame: its name, wire kind and the manual's range.

    ``strict_reply`` fields are range-checked on replies too (enums, flags); numeric
    readings are only checked on requests, because servos may report any value.
    """

    name: str
    kind: str
    lo: int
    hi: int
    unit: str = ""
    strict_reply: bool = False

    @property
    def size(self) -> int:
        return _KINDS[self.kind][1]


@dataclass(frozen=True)
class CommandSpec:
    """How one command looks on the wire, both ways."""

    command: Command
    request: tuple[Field, ...] = ()
    reply: tuple[Field, ...] | None = None
    """None for write commands, which the servo never answers."""
    request_struct: struct.Struct = field(init=False, repr=False, compare=False)
    reply_struct: struct.Struct | None = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "request_struct", _struct_for(self.request))
        object.__setattr__(
            self, "reply_struct", None if self.reply is None else _struct_for(self.reply)
        )

    @property
    def is_read(self) -> bool:
        return self.reply is not None

    @property
    def request_length(self) -> int:
        """The Length byte of a request (parameters + 3)."""
        return 3 + self.request_struct.size

    @property
    def reply_length(self) -> int | None:
        """The Length byte of the reply, or None for a write command."""
        return None if self.reply_struct is None else 3 + self.reply_struct.size


def _struct_for(fields: tuple[Field, ...]) -> struct.Struct:
    return struct.Struct("<" + "".join(_KINDS[f.kind][0] for f in fields))


_POS = Field("position_pulses", "u16", 0, 1000, "pulses")
_TIME = Field("time_ms", "u16", 0, 30000, "ms")
_OFFSET = Field("offset_pulses", "s8", -125, 125, "pulses")
_MIN_POS = Field("min_pulses", "u16", 0, 1000, "pulses")
_MAX_POS = Field("max_pulses", "u16", 0, 1000, "pulses")
_MIN_MV = Field("min_mv", "u16", 4500, 12000, "mV")
_MAX_MV = Field("max_mv", "u16", 4500, 12000, "mV")
_TEMP_MAX = Field("temp_max_c", "u8", 50, 100, "degC")
_MODE = Field("mode", "u8", 0, 1, strict_reply=True)
_NULL = Field("null", "null", 0, 0)
_SPEED = Field("motor_speed", "s16", -1000, 1000)
_LOADED = Field("is_loaded", "u8", 0, 1, strict_reply=True)
_LED_OFF = Field("is_led_off", "u8", 0, 1, strict_reply=True)
_ALARM = Field("alarm_mask", "u8", 0, 7, strict_reply=True)

SPECS: dict[Command, CommandSpec] = {
    s.command: s
    for s in (
        CommandSpec(Command.MOVE_TIME_WRITE, (_POS, _TIME)),
        CommandSpec(Command.MOVE_TIME_READ, (), (_POS, _TIME)),
        CommandSpec(Command.MOVE_TIME_WAIT_WRITE, (_POS, _TIME)),
        CommandSpec(Command.MOVE_TIME_WAIT_READ, (), (_POS, _TIME)),
        CommandSpec(Command.MOVE_START),
        CommandSpec(Command.MOVE_STOP),
        CommandSpec(Command.ID_WRITE, (Field("new_id", "u8", 0, MAX_SERVO_ID),)),
        CommandSpec(Command.ID_READ, (), (Field("reported_id", "u8", 0, 255),)),
        CommandSpec(Command.ANGLE_OFFSET_ADJUST, (_OFFSET,)),
        CommandSpec(Command.ANGLE_OFFSET_WRITE),
        CommandSpec(Command.ANGLE_OFFSET_READ, (), (_OFFSET,)),
        CommandSpec(Command.ANGLE_LIMIT_WRITE, (_MIN_POS, _MAX_POS)),
        CommandSpec(Command.ANGLE_LIMIT_READ, (), (_MIN_POS, _MAX_POS)),
        CommandSpec(Command.VIN_LIMIT_WRITE, (_MIN_MV, _MAX_MV)),
        CommandSpec(Command.VIN_LIMIT_READ, (), (_MIN_MV, _MAX_MV)),
        CommandSpec(Command.TEMP_MAX_LIMIT_WRITE, (_TEMP_MAX,)),
        CommandSpec(Command.TEMP_MAX_LIMIT_READ, (), (_TEMP_MAX,)),
        CommandSpec(Command.TEMP_READ, (), (Field("temp_c", "u8", 0, 255, "degC"),)),
        CommandSpec(Command.VIN_READ, (), (Field("vin_mv", "u16", 0, 65535, "mV"),)),
        CommandSpec(Command.POS_READ, (), (Field("position_pulses", "s16", -32768, 32767),)),
        CommandSpec(Command.OR_MOTOR_MODE_WRITE, (_MODE, _NULL, _SPEED)),
        CommandSpec(Command.OR_MOTOR_MODE_READ, (), (_MODE, _NULL, _SPEED)),
        CommandSpec(Command.LOAD_OR_UNLOAD_WRITE, (_LOADED,)),
        CommandSpec(Command.LOAD_OR_UNLOAD_READ, (), (_LOADED,)),
        CommandSpec(Command.LED_CTRL_WRITE, (_LED_OFF,)),
        CommandSpec(Command.LED_CTRL_READ, (), (_LED_OFF,)),
        CommandSpec(Command.LED_ERROR_WRITE, (_ALARM,)),
        CommandSpec(Command.LED_ERROR_READ, (), (_ALARM,)),
    )
}
assert len(SPECS) == 28 and set(SPECS) == set(Command)

VALID_LENGTHS = frozenset(
    {s.request_length for s in SPECS.values()}
    | {s.reply_length for s in SPECS.values() if s.reply_length is not None}
)
"""Length bytes that occur in the protocol (3..7): used to resynchronise faster."""

SAVED_ON_POWER_OFF: frozenset[Command] = frozenset(
    {
        Command.ID_WRITE,
        Command.ANGLE_OFFSET_WRITE,
        Command.ANGLE_LIMIT_WRITE,
        Command.VIN_LIMIT_WRITE,
        Command.TEMP_MAX_LIMIT_WRITE,
        Command.LED_CTRL_WRITE,
    }
)
"""Write commands whose effect the manual says survives power-down."""
