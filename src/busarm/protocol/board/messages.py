"""The board's messages as typed values in the user's units, both ways, byte-exact.

Host to board (requests): ``ServoMove``, ``ServoStop``, ``ServoRead``, ``ServoWrite``,
``MotorSpeeds``, ``LedBlink``, ``BuzzerBeep`` and (from ``peripherals``) the PWM servo,
OLED, RGB, motor duty and battery-warning requests. Board to host (reports):
``ServoReply``, ``PwmServoReply``, ``Battery``, ``ImuSample``, ``KeyEvent``,
``GamepadState``, ``SbusState``, and busarm's own ``MotorEncoders`` (not the stock
firmware's). ``decode_request`` and ``decode_report`` turn a frame
into one of them; anything else raises ProtocolError naming the bytes.

Units on the wire, as the vendor's firmware and SDK use them: servo positions in pulses
(0..1000 over 240 deg), times in ms, motor speeds as float32 rev/s with motors numbered
from 0, battery in mV, IMU acceleration in g and angular rate in deg/s (the vendor's
ROS node multiplies by 9.80665 and converts deg to rad).
"""

from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass

from busarm.errors import ConfigError, ProtocolError
from busarm.protocol.board.fields import FLOAT32_MAX, check_range, motor_floats, pack_fields
from busarm.protocol.board.frames import BoardFrame, Func, encode_frame
from busarm.protocol.board.peripherals import (
    BatteryWarning,
    MotorDuties,
    OledText,
    PwmServoMove,
    PwmServoRead,
    PwmServoReply,
    PwmServoSetOffset,
    RgbSet,
    decode_peripheral_report,
    decode_peripheral_request,
)
from busarm.protocol.commands import Command

__all__ = [
    "BROADCAST_SERVO_ID",
    "FLOAT32_MAX",
    "LX_COMMANDS",
    "MOTOR_COUNT",
    "MOTOR_ENCODERS",
    "MOTOR_SET_SPEEDS",
    "PWM_SERVO_MOVE",
    "READ_FORMATS",
    "STANDARD_GRAVITY",
    "SYS_BATTERY",
    "WRITE_FORMATS",
    "Battery",
    "BatteryWarning",
    "BoardReport",
    "BoardRequest",
    "BuzzerBeep",
    "GamepadState",
    "ImuSample",
    "KeyEvent",
    "KeyEventKind",
    "LedBlink",
    "MotorDuties",
    "MotorEncoders",
    "MotorSpeeds",
    "OledText",
    "PwmServoMove",
    "PwmServoRead",
    "PwmServoReply",
    "PwmServoSetOffset",
    "RgbSet",
    "SbusState",
    "ServoMove",
    "ServoRead",
    "ServoReply",
    "ServoStop",
    "ServoSub",
    "ServoWrite",
    "decode_report",
    "decode_request",
]


STANDARD_GRAVITY = 9.80665
SYS_BATTERY = 0x04
"""SYS report sub-code: the battery voltage."""
MOTOR_SET_SPEEDS = 0x01
MOTOR_ENCODERS = 0x10
"""MOTOR report sub-code: the four encoder counts. busarm's extension, not the stock
firmware's (which reports no encoder counts): the simulated board sends it, and a
firmware that adds it should use this layout (``MotorEncoders``)."""
PWM_SERVO_MOVE = 0x01
MOTOR_COUNT = 4
BROADCAST_SERVO_ID = 254


class ServoSub(enum.IntEnum):
    """BUS_SERVO (func 5) sub-commands, the first data byte."""

    MOVE = 0x01
    STOP = 0x03
    READ_POSITION = 0x05
    READ_VOLTAGE = 0x07
    READ_TEMPERATURE = 0x09
    TORQUE_OFF = 0x0B
    """Motor power off (the vendor's Python SDK calls this one "enable torque")."""
    TORQUE_ON = 0x0C
    READ_TORQUE = 0x0D
    SET_ID = 0x10
    READ_ID = 0x12
    SET_OFFSET = 0x20
    READ_OFFSET = 0x22
    SAVE_OFFSET = 0x24
    SET_ANGLE_LIMITS = 0x30
    READ_ANGLE_LIMITS = 0x32
    SET_VOLTAGE_LIMITS = 0x34
    READ_VOLTAGE_LIMITS = 0x36
    SET_TEMP_LIMIT = 0x38
    READ_TEMP_LIMIT = 0x3A


READ_FORMATS: dict[ServoSub, str] = {
    ServoSub.READ_POSITION: "<h",
    ServoSub.READ_VOLTAGE: "<H",
    ServoSub.READ_TEMPERATURE: "<B",
    ServoSub.READ_TORQUE: "<b",
    ServoSub.READ_ID: "<B",
    ServoSub.READ_OFFSET: "<b",
    ServoSub.READ_ANGLE_LIMITS: "<HH",
    ServoSub.READ_VOLTAGE_LIMITS: "<HH",
    ServoSub.READ_TEMP_LIMIT: "<B",
}
"""Each read's value in its reply, after ``id, sub, status``."""
WRITE_FORMATS: dict[ServoSub, str] = {
    ServoSub.TORQUE_OFF: "<B",
    ServoSub.TORQUE_ON: "<B",
    ServoSub.SET_ID: "<BB",
    ServoSub.SET_OFFSET: "<Bb",
    ServoSub.SAVE_OFFSET: "<B",
    ServoSub.SET_ANGLE_LIMITS: "<BHH",
    ServoSub.SET_VOLTAGE_LIMITS: "<BHH",
    ServoSub.SET_TEMP_LIMIT: "<BB",
}
"""Each single-servo write's arguments after the sub-command: the servo ID first."""
LX_COMMANDS: dict[ServoSub, Command] = {
    ServoSub.READ_POSITION: Command.POS_READ,
    ServoSub.READ_VOLTAGE: Command.VIN_READ,
    ServoSub.READ_TEMPERATURE: Command.TEMP_READ,
    ServoSub.READ_TORQUE: Command.LOAD_OR_UNLOAD_READ,
    ServoSub.READ_ID: Command.ID_READ,
    ServoSub.READ_OFFSET: Command.ANGLE_OFFSET_READ,
    ServoSub.READ_ANGLE_LIMITS: Command.ANGLE_LIMIT_READ,
    ServoSub.READ_VOLTAGE_LIMITS: Command.VIN_LIMIT_READ,
    ServoSub.READ_TEMP_LIMIT: Command.TEMP_MAX_LIMIT_READ,
    ServoSub.TORQUE_OFF: Command.LOAD_OR_UNLOAD_WRITE,
    ServoSub.TORQUE_ON: Command.LOAD_OR_UNLOAD_WRITE,
    ServoSub.SET_ID: Command.ID_WRITE,
    ServoSub.SET_OFFSET: Command.ANGLE_OFFSET_ADJUST,
    ServoSub.SAVE_OFFSET: Command.ANGLE_OFFSET_WRITE,
    ServoSub.SET_ANGLE_LIMITS: Command.ANGLE_LIMIT_WRITE,
    ServoSub.SET_VOLTAGE_LIMITS: Command.VIN_LIMIT_WRITE,
    ServoSub.SET_TEMP_LIMIT: Command.TEMP_MAX_LIMIT_WRITE,
    ServoSub.MOVE: Command.MOVE_TIME_WRITE,
    ServoSub.STOP: Command.MOVE_STOP,
}
"""The LX bus command the board's firmware sends for each sub-command. Its reads' values
are the LX replies' parameter bytes, unchanged."""


class KeyEventKind(enum.IntFlag):
    """What a KEY report says happened to the board's button."""

    PRESSED = 0x01
    LONG_PRESS = 0x02
    LONG_PRESS_REPEAT = 0x04
    RELEASED_FROM_LONG_PRESS = 0x08
    RELEASED_FROM_SHORT_PRESS = 0x10
    CLICK = 0x20
    DOUBLE_CLICK = 0x40
    TRIPLE_CLICK = 0x80




# ---------------------------------------------------------------------- requests


@dataclass(frozen=True)
class ServoMove:
    """Move several bus servos at once: each to its position (pulses) in ``duration_ms``."""

    duration_ms: int
    targets: tuple[tuple[int, int], ...]
    """(servo ID, position in pulses 0..1000) pairs."""

    def encode(self) -> bytes:
        check_range("duration_ms", self.duration_ms, 0, 0xFFFF)
        check_range("servo count", len(self.targets), 1, 83)  # 4 + 3 * 83 data bytes fit one frame
        data = bytearray(pack_fields("move", "<BHB", ServoSub.MOVE, self.duration_ms,
                                     len(self.targets)))
        for sid, pulses in self.targets:
            data += pack_fields("move", "<BH", check_range("servo ID", sid, 0, BROADCAST_SERVO_ID),
                          check_range("position_pulses", pulses, 0, 1000))
        return encode_frame(Func.BUS_SERVO, data)


@dataclass(frozen=True)
class ServoStop:
    """Stop these servos where they are (MOVE_STOP on the servo bus)."""

    servo_ids: tuple[int, ...]

    def encode(self) -> bytes:
        check_range("servo count", len(self.servo_ids), 1, 253)
        ids = [check_range("servo ID", s, 0, BROADCAST_SERVO_ID) for s in self.servo_ids]
        return encode_frame(Func.BUS_SERVO, bytes((ServoSub.STOP, len(ids), *ids)))


@dataclass(frozen=True)
class ServoRead:
    """Ask one servo for one value; the board answers with a ``ServoReply``."""

    sub: ServoSub
    servo_id: int

    def encode(self) -> bytes:
        if self.sub not in READ_FORMATS:
            raise ConfigError(f"sub-command {self.sub!r} is not a read")
        check_range("servo ID", self.servo_id, 0, BROADCAST_SERVO_ID)
        return encode_frame(Func.BUS_SERVO, bytes((self.sub, self.servo_id)))


@dataclass(frozen=True)
class ServoWrite:
    """One servo's setting or torque: ``values`` are the wire fields after its ID."""

    sub: ServoSub
    servo_id: int
    values: tuple[int, ...] = ()

    def encode(self) -> bytes:
        fmt = WRITE_FORMATS.get(self.sub)
        if fmt is None:
            raise ConfigError(f"sub-command {self.sub!r} is not a single-servo write")
        if len(self.values) != len(fmt) - 2:
            raise ConfigError(f"{self.sub.name} takes {len(fmt) - 2} value(s) after the servo "
                              f"ID, got {len(self.values)}")
        check_range("servo ID", self.servo_id, 0, BROADCAST_SERVO_ID)
        data = bytes((self.sub,)) + pack_fields(self.sub.name, fmt, self.servo_id, *self.values)
        return encode_frame(Func.BUS_SERVO, data)


@dataclass(frozen=True)
class MotorSpeeds:
    """Wheel motor speeds: (motor 1..4, rev/s) pairs; 0 stops a motor."""

    speeds: tuple[tuple[int, float], ...]

    def encode(self) -> bytes:
        return encode_frame(Func.MOTOR, motor_floats(MOTOR_SET_SPEEDS, self.speeds,
                                                     MOTOR_COUNT, "speed", " rev/s"))


@dataclass(frozen=True)
class LedBlink:
    """Blink the board's LED ``repeat`` times (0: for ever), times in ms."""

    led_id: int
    on_ms: int
    off_ms: int
    repeat: int = 1

    def encode(self) -> bytes:
        return encode_frame(Func.LED, pack_fields("LED", "<BHHH", self.led_id, self.on_ms,
                                                  self.off_ms, self.repeat))


@dataclass(frozen=True)
class BuzzerBeep:
    """Sound the buzzer at ``freq_hz`` ``repeat`` times, times in ms (freq 0: silence)."""

    freq_hz: int
    on_ms: int
    off_ms: int
    repeat: int = 1

    def encode(self) -> bytes:
        return encode_frame(Func.BUZZER, pack_fields("buzzer", "<HHHH", self.freq_hz, self.on_ms,
                                               self.off_ms, self.repeat))


BoardRequest = (ServoMove | ServoStop | ServoRead | ServoWrite | MotorSpeeds | LedBlink
                | BuzzerBeep | PwmServoMove | PwmServoRead | PwmServoSetOffset | OledText
                | RgbSet | MotorDuties | BatteryWarning)


def decode_request(frame: BoardFrame) -> BoardRequest:
    """What a host asked of the board (the simulated board's side)."""
    data = frame.data
    try:
        if frame.func == Func.BUS_SERVO:
            return _decode_servo_request(data)
        peripheral = decode_peripheral_request(frame)
        if peripheral is not None:
            return peripheral
        if frame.func == Func.MOTOR and data[:1] == bytes((MOTOR_SET_SPEEDS,)):
            _expect_len(frame, 2 + 5 * data[1])
            pairs = list(struct.iter_unpack("<Bf", data[2:]))
            if not pairs or any(m >= MOTOR_COUNT for m, _ in pairs):
                raise struct.error("motor numbers")
            return MotorSpeeds(tuple((int(m) + 1, float(v)) for m, v in pairs))
        if frame.func == Func.LED:
            _expect_len(frame, 7)
            return LedBlink(*struct.unpack("<BHHH", data))
        if frame.func == Func.BUZZER:
            _expect_len(frame, 8)
            return BuzzerBeep(*struct.unpack("<HHHH", data))
    except (IndexError, ValueError, struct.error):  # ValueError: an unknown sub-command
        pass
    raise ProtocolError(f"not a request this board model takes: {frame.name} "
                        f"{data.hex(' ') or '(no data)'}", frame.to_bytes())


def _decode_servo_request(data: bytes) -> BoardRequest:
    sub = ServoSub(data[0])
    if sub is ServoSub.MOVE:
        duration_ms, n = struct.unpack_from("<HB", data, 1)
        if len(data) != 4 + 3 * n or n == 0:
            raise struct.error("move length")
        pairs = struct.iter_unpack("<BH", data[4:])
        return ServoMove(duration_ms, tuple((int(i), int(p)) for i, p in pairs))
    if sub is ServoSub.STOP:
        if len(data) != 2 + data[1] or data[1] == 0:
            raise struct.error("stop length")
        return ServoStop(tuple(data[2:]))
    if sub in READ_FORMATS:
        if len(data) != 2:
            raise struct.error("read length")
        return ServoRead(sub, data[1])
    fields = struct.unpack("<" + WRITE_FORMATS[sub][1:], data[1:])
    return ServoWrite(sub, fields[0], tuple(fields[1:]))


def _expect_len(frame: BoardFrame, n: int) -> None:
    if len(frame.data) != n:
        raise struct.error(f"{frame.name} wants {n} data bytes")


# ---------------------------------------------------------------------- reports


@dataclass(frozen=True)
class ServoReply:
    """A servo read's answer: ``ok`` False when the servo did not answer the board."""

    servo_id: int
    sub: ServoSub
    status: int
    values: tuple[int, ...]

    @property
    def ok(self) -> bool:
        return self.status == 0

    @property
    def value_bytes(self) -> bytes:
        """The value as it came, little-endian (the same bytes as the LX reply's)."""
        return struct.pack(READ_FORMATS[self.sub], *self.values)

    def encode(self) -> bytes:
        return encode_frame(Func.BUS_SERVO, struct.pack("<BBb", self.servo_id, self.sub,
                                                        self.status) + self.value_bytes)


@dataclass(frozen=True)
class Battery:
    """The battery voltage the board measures."""

    voltage_v: float

    def encode(self) -> bytes:
        mv = check_range("battery mV", round(self.voltage_v * 1000), 0, 0xFFFF)
        return encode_frame(Func.SYS, struct.pack("<BH", SYS_BATTERY, mv))


@dataclass(frozen=True)
class ImuSample:
    """One IMU reading: acceleration (m/s^2) and angular rate (rad/s) about x, y, z."""

    accel_mps2: tuple[float, float, float]
    gyro_rad_s: tuple[float, float, float]

    def encode(self) -> bytes:
        wire = [a / STANDARD_GRAVITY for a in self.accel_mps2]
        wire += [math.degrees(g) for g in self.gyro_rad_s]
        return encode_frame(Func.IMU, struct.pack("<6f", *wire))


@dataclass(frozen=True)
class KeyEvent:
    """The board's button ``key_id`` (1 or 2) did ``event``."""

    key_id: int
    event: KeyEventKind

    def encode(self) -> bytes:
        return encode_frame(Func.KEY, bytes((self.key_id, int(self.event))))


@dataclass(frozen=True)
class GamepadState:
    """A USB gamepad plugged into the board: button bits, hat and sticks (-128..127)."""

    buttons: int
    hat: int
    sticks: tuple[int, int, int, int]

    def encode(self) -> bytes:
        sticks = [check_range("gamepad stick", v, -128, 127) for v in self.sticks]
        buttons = check_range("gamepad buttons", self.buttons, 0, 0xFFFF)
        hat = check_range("gamepad hat", self.hat, 0, 255)
        return encode_frame(Func.GAMEPAD, pack_fields("gamepad", "<HB4b", buttons, hat, *sticks))


@dataclass(frozen=True)
class SbusState:
    """An RC receiver on the board's SBUS input."""

    channels: tuple[int, ...]
    """16 channels as the receiver sends them (about 192..1792)."""
    signal_lost: bool
    fail_safe: bool
    channel_17: bool = False
    channel_18: bool = False
    """The two digital channels."""

    def encode(self) -> bytes:
        check_range("SBUS channel count", len(self.channels), 16, 16)
        values = [check_range("SBUS channel", v, -32768, 32767) for v in self.channels]
        return encode_frame(Func.SBUS, struct.pack(
            "<16hBBBB", *values, self.channel_17, self.channel_18, self.signal_lost,
            self.fail_safe))


@dataclass(frozen=True)
class MotorEncoders:
    """The wheel motors' encoder counts (motor 1..4 order), signed 32-bit, wrapping.

    busarm's extension (func MOTOR, data ``[0x10, int32 LE x 4]``): the vendor's stock
    firmware sends no encoder counts; busarm's simulated board does, and without it the
    base's odometry integrates the commanded wheel speeds instead.
    """

    ticks: tuple[int, int, int, int]

    def encode(self) -> bytes:
        for motor, ticks in enumerate(self.ticks, 1):
            check_range(f"motor {motor} encoder ticks", ticks, -(2**31), 2**31 - 1)
        return encode_frame(Func.MOTOR, struct.pack("<B4i", MOTOR_ENCODERS, *self.ticks))


BoardReport = (ServoReply | PwmServoReply | Battery | ImuSample | KeyEvent | GamepadState
               | SbusState               | MotorEncoders)


def decode_report(frame: BoardFrame) -> BoardReport:
    """What the board said; ProtocolError for a frame no board sends."""
    data, func = frame.data, frame.func
    try:
        if func == Func.BUS_SERVO:
            sid, sub, status = struct.unpack_from("<BBb", data)
            fmt = READ_FORMATS[ServoSub(sub)]
            if len(data) != 3 + struct.calcsize(fmt):
                raise struct.error("servo reply length")
            return ServoReply(sid, ServoSub(sub), status, struct.unpack_from(fmt, data, 3))
        pwm = decode_peripheral_report(frame)
        if pwm is not None:
            return pwm
        if func == Func.SYS and len(data) == 3 and data[0] == SYS_BATTERY:
            return Battery(struct.unpack_from("<H", data, 1)[0] / 1000.0)
        if func == Func.IMU and len(data) == 24:
            v = struct.unpack("<6f", data)
            return ImuSample((v[0] * STANDARD_GRAVITY, v[1] * STANDARD_GRAVITY,
                              v[2] * STANDARD_GRAVITY),
                             (math.radians(v[3]), math.radians(v[4]), math.radians(v[5])))
        if func == Func.MOTOR and len(data) == 17 and data[0] == MOTOR_ENCODERS:
            a, b, c, d = struct.unpack_from("<4i", data, 1)
            return MotorEncoders((a, b, c, d))
        if func == Func.KEY and len(data) == 2:
            return KeyEvent(data[0], KeyEventKind(data[1]))
        if func == Func.GAMEPAD and len(data) == 7:
            buttons, hat, *sticks = struct.unpack("<HB4b", data)
            return GamepadState(buttons, hat, (sticks[0], sticks[1], sticks[2], sticks[3]))
        if func == Func.SBUS and len(data) == 36:
            *channels, ch17, ch18, lost, fail_safe = struct.unpack("<16hBBBB", data)
            return SbusState(tuple(channels), bool(lost), bool(fail_safe), bool(ch17),
                             bool(ch18))
    except (IndexError, KeyError, ValueError, struct.error):
        pass
    raise ProtocolError(f"not a report the board sends: {frame.name} "
                        f"{data.hex(' ') or '(no data)'}", frame.to_bytes())
