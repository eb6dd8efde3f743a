"""The board's own peripherals, both ways: PWM servos, OLED, RGB, motor duty, battery warning.

Layouts as the vendor's firmware (``packet_handle.c``) and Python SDK
(``ros_robot_controller_sdk.py``) publish them, little-endian:

- PWM servo (func 4), sub-command first: ``01`` move ``[01, dur u16, N, (port, pulse u16)
  x N]``; ``05`` read position ``[05, port]``, answered ``[port, 05, pulse u16]``; ``07`` set
  offset ``[07, port, offset i8]``; ``09`` read offset ``[09, port]``, answered ``[port, 09,
  offset i8]``. Ports are 1..4; the firmware answers every read for those ports (the
  reply has no status byte: the pulse is the board's own).
- OLED (func 10): ``[line, len, UTF-8 bytes]``; the firmware shows lines 1 and 2.
- RGB (func 11): ``01`` ``[01, N, (pixel - 1, r, g, b) x N]``.
- MOTOR (func 3) ``05``: ``[05, N, (motor - 1, float32 duty) x N]`` as every SDK version
  sends it (``set_motor_duty``); one published firmware takes sub-command 05 as its
  motor-type switch instead.
- SYS (func 0) ``01``: the battery warning threshold ``[01, mV u16]``.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from busarm.errors import ConfigError
from busarm.protocol.board.fields import check_range, motor_floats, pack_fields
from busarm.protocol.board.frames import BoardFrame, Func, encode_frame

__all__ = [
    "MOTOR_SET_DUTIES",
    "PWM_PORTS",
    "RGB_SET",
    "SYS_BATTERY_WARNING",
    "BatteryWarning",
    "MotorDuties",
    "OledText",
    "PwmServoMove",
    "PwmServoRead",
    "PwmServoReply",
    "PwmServoSetOffset",
    "PwmSub",
    "RgbSet",
    "decode_peripheral_report",
    "decode_peripheral_request",
]


PWM_PORTS = 4
"""The board's PWM servo headers, numbered 1..4."""
MOTOR_SET_DUTIES = 0x05
RGB_SET = 0x01
SYS_BATTERY_WARNING = 0x01


class PwmSub(enum.IntEnum):
    """PWM_SERVO (func 4) sub-commands, the first data byte of a request."""

    MOVE = 0x01
    READ_POSITION = 0x05
    SET_OFFSET = 0x07
    READ_OFFSET = 0x09


_PWM_READ_FORMATS = {PwmSub.READ_POSITION: "<H", PwmSub.READ_OFFSET: "<b"}


@dataclass(frozen=True)
class PwmServoMove:
    """Hobby (PWM) servos on the board's four headers: (port 1..4, pulse width us) pairs."""

    duration_ms: int
    targets: tuple[tuple[int, int], ...]

    def encode(self) -> bytes:
        check_range("PWM servo count", len(self.targets), 1, 83)  # as many as fit one frame
        data = bytearray(pack_fields("PWM move", "<BHB", PwmSub.MOVE, self.duration_ms,
                                     len(self.targets)))
        for port, pulse_us in self.targets:
            data += pack_fields("PWM move", "<BH", check_range("PWM port", port, 1, PWM_PORTS),
                                pulse_us)
        return encode_frame(Func.PWM_SERVO, data)


@dataclass(frozen=True)
class PwmServoRead:
    """Ask for a PWM servo's pulse (us) or offset; the board answers ``PwmServoReply``."""

    sub: PwmSub
    port: int

    def encode(self) -> bytes:
        _check_read_sub(self.sub)
        return encode_frame(Func.PWM_SERVO, bytes((self.sub, check_range(
            "PWM port", self.port, 1, PWM_PORTS))))


def _check_read_sub(sub: PwmSub) -> str:
    fmt = _PWM_READ_FORMATS.get(sub)
    if fmt is None:
        raise ConfigError(f"PWM sub-command {sub!r} is not a read; allowed: READ_POSITION "
                          "(0x05), READ_OFFSET (0x09)")
    return fmt


@dataclass(frozen=True)
class PwmServoSetOffset:
    """A PWM servo's offset (the firmware adds it to every pulse)."""

    port: int
    offset: int

    def encode(self) -> bytes:
        check_range("PWM port", self.port, 1, PWM_PORTS)
        return encode_frame(Func.PWM_SERVO, bytes((PwmSub.SET_OFFSET, self.port)) + pack_fields(
            "PWM offset", "<b", check_range("PWM offset", self.offset, -128, 127)))


@dataclass(frozen=True)
class PwmServoReply:
    """The board's answer to a ``PwmServoRead``: the pulse (us) or the offset."""

    port: int
    sub: PwmSub
    value: int

    def encode(self) -> bytes:
        fmt = _check_read_sub(self.sub)
        head = bytes((check_range("PWM port", self.port, 1, PWM_PORTS), self.sub))
        return encode_frame(Func.PWM_SERVO, head + pack_fields("PWM reply", fmt, self.value))


@dataclass(frozen=True)
class OledText:
    """A line of text on the board's OLED (the firmware shows lines 1 and 2)."""

    line: int
    text: str

    def encode(self) -> bytes:
        raw = self.text.encode()
        check_range("OLED text bytes (UTF-8)", len(raw), 0, 253)  # 2 + 253 data bytes: full
        return encode_frame(Func.OLED, bytes((check_range("OLED line", self.line, 0, 255),
                                              len(raw))) + raw)


@dataclass(frozen=True)
class RgbSet:
    """The board's RGB LEDs: (pixel 1.., red, green, blue 0..255) tuples."""

    pixels: tuple[tuple[int, int, int, int], ...]

    def encode(self) -> bytes:
        check_range("RGB pixel count", len(self.pixels), 1, 63)  # 2 + 4 * 63 bytes fit
        data = bytearray((RGB_SET, len(self.pixels)))
        for pixel, red, green, blue in self.pixels:
            data.append(check_range("RGB pixel", pixel, 1, 256) - 1)
            data += bytes(check_range(name, v, 0, 255)
                          for name, v in (("red", red), ("green", green), ("blue", blue)))
        return encode_frame(Func.RGB, data)


@dataclass(frozen=True)
class MotorDuties:
    """Open-loop motor drive, bypassing the speed loop: (motor 1..4, duty) pairs, the duty
    as the vendor's SDK sends it (a float32)."""

    duties: tuple[tuple[int, float], ...]

    def encode(self) -> bytes:
        return encode_frame(Func.MOTOR, motor_floats(MOTOR_SET_DUTIES, self.duties, 4, "duty"))


@dataclass(frozen=True)
class BatteryWarning:
    """The battery voltage below which the board warns (it beeps)."""

    threshold_v: float

    def encode(self) -> bytes:
        mv = check_range("battery warning mV", round(self.threshold_v * 1000), 0, 0xFFFF)
        return encode_frame(Func.SYS, struct.pack("<BH", SYS_BATTERY_WARNING, mv))


PeripheralRequest = (PwmServoMove | PwmServoRead | PwmServoSetOffset | OledText | RgbSet
                     | MotorDuties | BatteryWarning)


def decode_peripheral_request(frame: BoardFrame) -> PeripheralRequest | None:
    """One of this module's requests, or None; struct.error or ValueError if malformed."""
    data, func = frame.data, frame.func
    if func == Func.PWM_SERVO:
        return _decode_pwm_request(data)
    if func == Func.OLED:
        if len(data) != 2 + data[1]:
            raise struct.error("OLED length")
        return OledText(data[0], data[2:].decode(errors="replace"))
    if func == Func.RGB and data[:1] == bytes((RGB_SET,)):
        if len(data) != 2 + 4 * data[1] or data[1] == 0:
            raise struct.error("RGB length")
        pixels = struct.iter_unpack("<4B", data[2:])
        return RgbSet(tuple((p + 1, r, g, b) for p, r, g, b in pixels))
    if func == Func.MOTOR and data[:1] == bytes((MOTOR_SET_DUTIES,)):
        if len(data) != 2 + 5 * data[1] or data[1] == 0:
            raise struct.error("duty length")
        pairs = list(struct.iter_unpack("<Bf", data[2:]))
        if any(m >= 4 for m, _ in pairs):
            raise struct.error("motor numbers")
        return MotorDuties(tuple((int(m) + 1, float(v)) for m, v in pairs))
    if func == Func.SYS and len(data) == 3 and data[0] == SYS_BATTERY_WARNING:
        return BatteryWarning(struct.unpack_from("<H", data, 1)[0] / 1000.0)
    return None


def _decode_pwm_request(data: bytes) -> PeripheralRequest:
    sub = PwmSub(data[0])
    if sub is PwmSub.MOVE:
        duration_ms, n = struct.unpack_from("<HB", data, 1)
        if len(data) != 4 + 3 * n or n == 0:
            raise struct.error("PWM move length")
        pairs = tuple((int(p), int(u)) for p, u in struct.iter_unpack("<BH", data[4:]))
        if any(not 1 <= p <= PWM_PORTS for p, _ in pairs):
            raise struct.error("PWM port")
        return PwmServoMove(duration_ms, pairs)
    if not 1 <= data[1] <= PWM_PORTS:
        raise struct.error("PWM port")
    if sub is PwmSub.SET_OFFSET:
        if len(data) != 3:
            raise struct.error("PWM offset length")
        return PwmServoSetOffset(data[1], struct.unpack_from("<b", data, 2)[0])
    if len(data) != 2:
        raise struct.error("PWM read length")
    return PwmServoRead(sub, data[1])


def decode_peripheral_report(frame: BoardFrame) -> PwmServoReply | None:
    """A PWM servo's reply, or None; struct.error or ValueError if malformed."""
    data = frame.data
    if frame.func != Func.PWM_SERVO:
        return None
    if len(data) < 2:
        raise struct.error("PWM reply length")
    port, sub = data[0], PwmSub(data[1])
    fmt = _PWM_READ_FORMATS[sub]
    if len(data) != 2 + struct.calcsize(fmt) or not 1 <= port <= PWM_PORTS:
        raise struct.error("PWM reply")
    return PwmServoReply(port, sub, int(struct.unpack_from(fmt, data, 2)[0]))
