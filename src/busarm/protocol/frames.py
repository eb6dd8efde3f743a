"""Frames, typed requests and replies, and their byte-exact encoding.

Pure functions: no I/O, no clock. Everything the bus driver sends and the simulator
answers goes through here.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, fields
from typing import ClassVar, TypeVar

from busarm.errors import ChecksumError, ConfigError, ProtocolError
from busarm.protocol.commands import (
    BROADCAST_ID,
    HEADER,
    MAX_SERVO_ID,
    SPECS,
    AlarmFlag,
    Command,
    CommandSpec,
    Field,
    ServoMode,
)
from busarm.protocol.lx_units import DEG_PER_PULSE, deg_from_pulses

__all__ = [
    "MIN_LENGTH",
    "REPLY_TYPES",
    "AngleLimitReply",
    "AngleOffsetReply",
    "Frame",
    "IdReply",
    "LedCtrlReply",
    "LedErrorReply",
    "LoadReply",
    "ModeReply",
    "MoveTimeReply",
    "MoveTimeWaitReply",
    "PositionReply",
    "Reply",
    "Request",
    "TempMaxLimitReply",
    "TempReply",
    "VinLimitReply",
    "VinReply",
    "check_servo_id",
    "checksum",
    "decode_frame",
    "decode_message",
    "decode_reply",
    "decode_request",
    "describe",
    "encode_reply",
    "encode_request",
]


MIN_LENGTH = 3


def checksum(body: bytes | bytearray | memoryview) -> int:
    """The manual's checksum of ID, Length, Cmd and parameters: ~sum, low byte."""
    return (~sum(body)) & 0xFF


@dataclass(frozen=True, slots=True)
class Frame:
    """One packet on the wire, undecoded: ``55 55 ID LEN CMD PARAMS.. CHECKSUM``."""

    servo_id: int
    command: int
    params: bytes = b""

    @property
    def length(self) -> int:
        """The Length byte: parameters + 3."""
        return len(self.params) + 3

    def to_bytes(self) -> bytes:
        body = bytes((self.servo_id, self.length, self.command)) + self.params
        return HEADER + body + bytes((checksum(body),))

    def hex(self) -> str:
        return self.to_bytes().hex(" ")


def check_servo_id(servo_id: object, *, allow_broadcast: bool = False) -> int:
    """Return ``servo_id`` if valid (0..253, or 254 if allowed), else raise ConfigError."""
    hi = BROADCAST_ID if allow_broadcast else MAX_SERVO_ID
    extra = " (254 = broadcast)" if allow_broadcast else ""
    if isinstance(servo_id, bool) or not isinstance(servo_id, int):
        raise ConfigError(
            f"servo ID must be an integer 0..{hi}{extra}, got {servo_id!r} "
            f"(a {type(servo_id).__name__})"
        )
    if not 0 <= servo_id <= hi:
        raise ConfigError(f"servo ID {servo_id!r} is out of range 0..{hi}{extra}")
    return servo_id


def _check_fields(
    command: Command, spec_fields: tuple[Field, ...], values: tuple[int, ...]
) -> None:
    if len(values) != len(spec_fields):
        names = " ".join(f.name for f in spec_fields) or "(none)"
        raise ConfigError(
            f"{command.name} takes {len(spec_fields)} parameter(s): {names}; got {len(values)}"
        )
    for f, v in zip(spec_fields, values, strict=False):
        unit = f" {f.unit}" if f.unit else ""
        # bool is an int subclass: accept it only for the is_* flags, never as a number.
        if not isinstance(v, int) or (isinstance(v, bool) and not f.name.startswith("is_")):
            raise ConfigError(
                f"{command.name} {f.name} = {v!r} must be an integer in range "
                f"{f.lo}..{f.hi}{unit}"
            )
        if not f.lo <= v <= f.hi:
            raise ConfigError(
                f"{command.name} {f.name} = {v!r} is out of range {f.lo}..{f.hi}{unit}"
            )
    if command in (Command.ANGLE_LIMIT_WRITE, Command.VIN_LIMIT_WRITE) and values[0] >= values[1]:
        raise ConfigError(
            f"{command.name} minimum {values[0]} must be less than maximum {values[1]}"
        )


@dataclass(frozen=True, slots=True)
class Request:
    """A command from host to servo, with its parameters in wire units."""

    servo_id: int
    command: Command
    args: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        check_servo_id(self.servo_id, allow_broadcast=True)
        command: object = self.command
        if not isinstance(command, Command):
            # A plain int would otherwise fail later with a KeyError (unknown value)
            # or an AttributeError (no .manual_name); bool is not a command number.
            if isinstance(command, bool) or not isinstance(command, int):
                raise ConfigError(f"command must be a Command or its number, got {command!r}")
            object.__setattr__(self, "command", Command.parse(str(command)))
        _check_fields(self.command, SPECS[self.command].request, self.args)

    @property
    def spec(self) -> CommandSpec:
        return SPECS[self.command]

    @property
    def values(self) -> dict[str, int]:
        """Parameters by name (the null byte of the mode command left out)."""
        pairs = zip(self.spec.request, self.args, strict=True)
        return {f.name: v for f, v in pairs if f.kind != "null"}

    def to_frame(self) -> Frame:
        return Frame(self.servo_id, int(self.command), self.spec.request_struct.pack(*self.args))

    def to_bytes(self) -> bytes:
        return self.to_frame().to_bytes()


def encode_request(servo_id: int, command: Command, *args: int) -> bytes:
    """The exact bytes of a request; raises ConfigError for any bad value.

    For SERVO_OR_MOTOR_MODE_WRITE pass (mode, 0, speed) as the manual lays it out,
    or (mode, speed): the null byte is filled in.
    """
    if command is Command.OR_MOTOR_MODE_WRITE and len(args) == 2:
        args = (args[0], 0, args[1])
    return Request(servo_id, command, tuple(args)).to_bytes()


# ---------------------------------------------------------------------------- replies

R = TypeVar("R", bound="Reply")


@dataclass(frozen=True, slots=True)
class Reply:
    """Base of the typed replies of the manual's Table 4 (wire units, with unit names)."""

    COMMAND: ClassVar[Command]

    def wire_values(self) -> tuple[int, ...]:
        """The parameters in wire order, as integers (null byte included)."""
        spec = SPECS[self.COMMAND]
        assert spec.reply is not None
        return tuple(0 if f.kind == "null" else int(getattr(self, f.name)) for f in spec.reply)


@dataclass(frozen=True, slots=True)
class MoveTimeReply(Reply):
    COMMAND: ClassVar[Command] = Command.MOVE_TIME_READ
    position_pulses: int
    time_ms: int

    @property
    def position_deg(self) -> float:
        return deg_from_pulses(self.position_pulses)

    @property
    def time_s(self) -> float:
        return self.time_ms / 1000.0


@dataclass(frozen=True, slots=True)
class MoveTimeWaitReply(Reply):
    COMMAND: ClassVar[Command] = Command.MOVE_TIME_WAIT_READ
    position_pulses: int
    time_ms: int

    @property
    def position_deg(self) -> float:
        return deg_from_pulses(self.position_pulses)

    @property
    def time_s(self) -> float:
        return self.time_ms / 1000.0


@dataclass(frozen=True, slots=True)
class IdReply(Reply):
    COMMAND: ClassVar[Command] = Command.ID_READ
    reported_id: int


@dataclass(frozen=True, slots=True)
class AngleOffsetReply(Reply):
    COMMAND: ClassVar[Command] = Command.ANGLE_OFFSET_READ
    offset_pulses: int

    @property
    def offset_deg(self) -> float:
        return self.offset_pulses * DEG_PER_PULSE


@dataclass(frozen=True, slots=True)
class AngleLimitReply(Reply):
    COMMAND: ClassVar[Command] = Command.ANGLE_LIMIT_READ
    min_pulses: int
    max_pulses: int

    @property
    def min_deg(self) -> float:
        return deg_from_pulses(self.min_pulses)

    @property
    def max_deg(self) -> float:
        return deg_from_pulses(self.max_pulses)


@dataclass(frozen=True, slots=True)
class VinLimitReply(Reply):
    COMMAND: ClassVar[Command] = Command.VIN_LIMIT_READ
    min_mv: int
    max_mv: int

    @property
    def min_v(self) -> float:
        return self.min_mv / 1000.0

    @property
    def max_v(self) -> float:
        return self.max_mv / 1000.0


@dataclass(frozen=True, slots=True)
class TempMaxLimitReply(Reply):
    COMMAND: ClassVar[Command] = Command.TEMP_MAX_LIMIT_READ
    temp_max_c: int


@dataclass(frozen=True, slots=True)
class TempReply(Reply):
    COMMAND: ClassVar[Command] = Command.TEMP_READ
    temp_c: int


@dataclass(frozen=True, slots=True)
class VinReply(Reply):
    COMMAND: ClassVar[Command] = Command.VIN_READ
    vin_mv: int

    @property
    def vin_v(self) -> float:
        return self.vin_mv / 1000.0


@dataclass(frozen=True, slots=True)
class PositionReply(Reply):
    """SERVO_POS_READ: signed, because a servo near its end may read below 0."""

    COMMAND: ClassVar[Command] = Command.POS_READ
    position_pulses: int

    @property
    def position_deg(self) -> float:
        return deg_from_pulses(self.position_pulses)


@dataclass(frozen=True, slots=True)
class ModeReply(Reply):
    COMMAND: ClassVar[Command] = Command.OR_MOTOR_MODE_READ
    mode: ServoMode
    motor_speed: int


@dataclass(frozen=True, slots=True)
class LoadReply(Reply):
    COMMAND: ClassVar[Command] = Command.LOAD_OR_UNLOAD_READ
    is_loaded: bool


@dataclass(frozen=True, slots=True)
class LedCtrlReply(Reply):
    COMMAND: ClassVar[Command] = Command.LED_CTRL_READ
    is_led_off: bool


@dataclass(frozen=True, slots=True)
class LedErrorReply(Reply):
    """SERVO_LED_ERROR_READ: which faults make the LED flash (the configured mask)."""

    COMMAND: ClassVar[Command] = Command.LED_ERROR_READ
    alarm_mask: AlarmFlag


REPLY_TYPES: dict[Command, type[Reply]] = {
    cls.COMMAND: cls
    for cls in (
        MoveTimeReply, MoveTimeWaitReply, IdReply, AngleOffsetReply, AngleLimitReply,
        VinLimitReply, TempMaxLimitReply, TempReply, VinReply, PositionReply, ModeReply,
        LoadReply, LedCtrlReply, LedErrorReply,
    )
}
assert set(REPLY_TYPES) == {c for c, s in SPECS.items() if s.is_read}

_CONVERT = {
    "mode": ServoMode,
    "is_loaded": bool,
    "is_led_off": bool,
    "alarm_mask": AlarmFlag,
}


def _reply_from_values(command: Command, values: tuple[int, ...], frame: Frame) -> Reply:
    spec = SPECS[command]
    assert spec.reply is not None
    kwargs: dict[str, object] = {}
    for f, v in zip(spec.reply, values, strict=False):
        if f.kind == "null":
            continue
        if f.strict_reply and not f.lo <= v <= f.hi:
            raise ProtocolError(
                f"{command.name} reply {f.name} = {v} is out of range {f.lo}..{f.hi}",
                frame.to_bytes(),
            )
        conv = _CONVERT.get(f.name)
        kwargs[f.name] = conv(v) if conv is not None else v
    return REPLY_TYPES[command](**kwargs)


def encode_reply(servo_id: int, reply: Reply) -> bytes:
    """The exact bytes a servo sends for ``reply`` (used by the simulator)."""
    spec = SPECS[reply.COMMAND]
    assert spec.reply_struct is not None
    try:
        params = spec.reply_struct.pack(*reply.wire_values())
    except struct.error as exc:
        raise ConfigError(f"{reply!r} does not fit the wire format: {exc}") from None
    return Frame(servo_id, int(reply.COMMAND), params).to_bytes()


# ---------------------------------------------------------------------------- decoding


def decode_frame(data: bytes | bytearray) -> Frame:
    """Exactly one frame from ``data``; raises ProtocolError/ChecksumError saying what is wrong."""
    raw = bytes(data)
    if len(raw) < 6:
        raise ProtocolError(f"frame too short: {len(raw)} bytes, a frame has at least 6", raw)
    if raw[:2] != HEADER:
        raise ProtocolError(f"frame must start with 55 55, got {raw[:2].hex(' ')}", raw)
    length = raw[3]
    if length < MIN_LENGTH:
        raise ProtocolError(f"length byte {length} is below the minimum 3", raw)
    if len(raw) != length + 3:
        raise ProtocolError(
            f"length byte {length} means {length + 3} bytes, got {len(raw)}", raw
        )
    body = raw[2:-1]
    expected = checksum(body)
    if raw[-1] != expected:
        raise ChecksumError(f"checksum {raw[-1]:02x} should be {expected:02x}", raw)
    return Frame(raw[2], raw[4], raw[5:-1])


def _command_of(frame: Frame) -> Command:
    try:
        return Command(frame.command)
    except ValueError:
        raise ProtocolError(f"unknown command {frame.command}", frame.to_bytes()) from None


def decode_reply(frame: Frame) -> Reply:
    """The typed reply in ``frame``; raises ProtocolError if it is not a valid reply."""
    command = _command_of(frame)
    spec = SPECS[command]
    if spec.reply_struct is None or spec.reply_length != frame.length:
        raise ProtocolError(
            f"{command.name} frame of length {frame.length} is not a reply", frame.to_bytes()
        )
    return _reply_from_values(command, spec.reply_struct.unpack(frame.params), frame)


def decode_request(frame: Frame) -> Request:
    """The request in ``frame``; raises ProtocolError if it is not a valid request."""
    command = _command_of(frame)
    spec = SPECS[command]
    if spec.request_length != frame.length:
        raise ProtocolError(
            f"{command.name} frame of length {frame.length} is not a request "
            f"(a request has length {spec.request_length})",
            frame.to_bytes(),
        )
    values = spec.request_struct.unpack(frame.params)
    try:
        return Request(frame.servo_id, command, values)
    except ConfigError as exc:
        raise ProtocolError(str(exc), frame.to_bytes()) from None


def decode_message(frame: Frame) -> Request | Reply:
    """A request or a reply, told apart by the length byte (they never share one)."""
    command = _command_of(frame)
    spec = SPECS[command]
    if frame.length == spec.request_length:
        return decode_request(frame)
    return decode_reply(frame)


def describe(message: Request | Reply, servo_id: int | None = None) -> str:
    """One line for people: direction, command (named as everywhere else in busarm,
    without the manual's SERVO_ prefix), ID and named values in units."""
    if isinstance(message, Request):
        target = "broadcast" if message.servo_id == BROADCAST_ID else f"id {message.servo_id}"
        vals = " ".join(f"{k}={v}" for k, v in message.values.items())
        return f"request {message.command.name} to {target}" + (f": {vals}" if vals else "")
    parts = []
    for f in fields(message):
        v = getattr(message, f.name)
        parts.append(f"{f.name}={v.name if isinstance(v, ServoMode) else v}")
    for extra in ("position_deg", "offset_deg", "vin_v", "time_s", "min_deg", "max_deg"):
        if hasattr(type(message), extra):
            parts.append(f"{extra}={getattr(message, extra):g}")
    origin = f" from id {servo_id}" if servo_id is not None else ""
    return f"reply {message.COMMAND.name}{origin}: " + " ".join(parts)
