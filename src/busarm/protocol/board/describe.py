"""One line of plain words for a controller-board frame (``busarm decode``)."""

from __future__ import annotations

import math

from busarm.errors import ProtocolError
from busarm.protocol.board.frames import BoardFrame, Func
from busarm.protocol.board.messages import (
    Battery,
    BatteryWarning,
    BoardReport,
    BoardRequest,
    BuzzerBeep,
    GamepadState,
    ImuSample,
    KeyEvent,
    LedBlink,
    MotorDuties,
    MotorEncoders,
    MotorSpeeds,
    OledText,
    PwmServoMove,
    PwmServoRead,
    PwmServoReply,
    PwmServoSetOffset,
    RgbSet,
    SbusState,
    ServoMove,
    ServoRead,
    ServoReply,
    ServoStop,
    ServoWrite,
    decode_report,
    decode_request,
)

__all__ = [
    "describe_board_frame",
]


def describe_board_frame(frame: BoardFrame) -> str:
    """What ``frame`` says, as a request to the board or a report from it."""
    message: BoardRequest | BoardReport
    try:
        message = decode_request(frame)
        side = "to the board"
    except ProtocolError:
        try:
            message = decode_report(frame)
            side = "from the board"
        except ProtocolError:
            return f"board {frame.name}: not a message this codec knows ({frame.data.hex(' ')})"
    return f"board {Func(frame.func).name} {side}: {_words(message)}"


def _words(m: BoardRequest | BoardReport) -> str:
    if isinstance(m, ServoMove):
        moves = ", ".join(f"servo {sid} to {p} pulses" for sid, p in m.targets)
        return f"move {moves} in {m.duration_ms} ms"
    if isinstance(m, ServoStop):
        return "stop servo(s) " + ", ".join(map(str, m.servo_ids))
    if isinstance(m, ServoRead):
        return f"{m.sub.name.lower().replace('_', ' ')} of servo {m.servo_id}"
    if isinstance(m, ServoWrite):
        values = " ".join(map(str, m.values))
        return f"{m.sub.name.lower().replace('_', ' ')} servo {m.servo_id} {values}".rstrip()
    if isinstance(m, ServoReply):
        what = m.sub.name.lower().replace("read_", "").replace("_", " ")
        if not m.ok:
            return f"servo {m.servo_id} {what}: no answer from the servo (status {m.status})"
        return f"servo {m.servo_id} {what}: " + " ".join(map(str, m.values))
    if isinstance(m, MotorSpeeds):
        return ", ".join(f"motor {n} at {v:g} rev/s" for n, v in m.speeds)
    if isinstance(m, PwmServoMove | PwmServoRead | PwmServoSetOffset | PwmServoReply):
        return _pwm_words(m)
    if isinstance(m, MotorDuties):
        return ", ".join(f"motor {n} at duty {v:g} (open loop)" for n, v in m.duties)
    if isinstance(m, OledText):
        return f"OLED line {m.line}: {m.text!r}"
    if isinstance(m, RgbSet):
        return "RGB " + ", ".join(f"pixel {p} to ({r}, {g}, {b})" for p, r, g, b in m.pixels)
    if isinstance(m, BatteryWarning):
        return f"warn below battery {m.threshold_v:.3f} V"
    if isinstance(m, LedBlink):
        return f"LED {m.led_id}: on {m.on_ms} ms, off {m.off_ms} ms, {m.repeat} time(s)"
    if isinstance(m, BuzzerBeep):
        return f"buzzer {m.freq_hz} Hz: on {m.on_ms} ms, off {m.off_ms} ms, {m.repeat} time(s)"
    if isinstance(m, Battery):
        return f"battery {m.voltage_v:.3f} V"
    if isinstance(m, ImuSample):
        a = "  ".join(f"{v:.2f}" for v in m.accel_mps2)
        g = "  ".join(f"{math.degrees(v):.2f}" for v in m.gyro_rad_s)
        return f"IMU acceleration {a} m/s^2, angular rate {g} deg/s"
    if isinstance(m, MotorEncoders):
        return "encoder counts " + ", ".join(
            f"motor {n} {t}" for n, t in enumerate(m.ticks, start=1)) + " (busarm's extension)"
    if isinstance(m, KeyEvent):
        return f"key {m.key_id} {m.event.name}"
    if isinstance(m, GamepadState):
        return f"gamepad buttons {m.buttons:#06x}, hat {m.hat}, sticks {m.sticks}"
    sbus: SbusState = m  # the last kind left
    return (f"SBUS channels {' '.join(map(str, sbus.channels))}, signal "
            f"{'lost' if sbus.signal_lost else 'ok'}{', fail-safe' if sbus.fail_safe else ''}")


def _pwm_words(m: PwmServoMove | PwmServoRead | PwmServoSetOffset | PwmServoReply) -> str:
    if isinstance(m, PwmServoMove):
        moves = ", ".join(f"port {p} to {us} us" for p, us in m.targets)
        return f"PWM servo move {moves} in {m.duration_ms} ms"
    if isinstance(m, PwmServoRead):
        return f"PWM servo {m.sub.name.lower().replace('_', ' ')} of port {m.port}"
    if isinstance(m, PwmServoSetOffset):
        return f"PWM servo set offset of port {m.port} to {m.offset} us"
    what = m.sub.name.lower().replace("read_", "")
    unit = " us" if what == "position" else ""
    return f"PWM servo port {m.port} {what}: {m.value}{unit}"
