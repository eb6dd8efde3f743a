"""The vendor controller board's serial protocol: pure, byte-exact, no I/O.

``frames`` holds the frame format, the CRC and the stream parser; ``messages`` the
typed requests and reports in the user's units.
"""

from busarm.protocol.board.frames import (
    BOARD_BAUDRATE,
    BOARD_HEADER,
    FRAME_OVERHEAD,
    BoardFrame,
    BoardFrameParser,
    Func,
    crc8_maxim,
    decode_frame,
    encode_frame,
)
from busarm.protocol.board.messages import (
    BROADCAST_SERVO_ID,
    LX_COMMANDS,
    MOTOR_COUNT,
    READ_FORMATS,
    WRITE_FORMATS,
    Battery,
    BoardReport,
    BoardRequest,
    BuzzerBeep,
    GamepadState,
    ImuSample,
    KeyEvent,
    KeyEventKind,
    LedBlink,
    MotorEncoders,
    MotorSpeeds,
    OledText,
    PwmServoMove,
    SbusState,
    ServoMove,
    ServoRead,
    ServoReply,
    ServoStop,
    ServoSub,
    ServoWrite,
    decode_report,
    decode_request,
)

__all__ = [
    "BOARD_BAUDRATE", "BOARD_HEADER", "BROADCAST_SERVO_ID", "FRAME_OVERHEAD", "LX_COMMANDS",
    "MOTOR_COUNT",
    "READ_FORMATS", "WRITE_FORMATS", "Battery", "BoardFrame", "BoardFrameParser", "BoardReport",
    "BoardRequest", "BuzzerBeep", "Func", "GamepadState", "ImuSample", "KeyEvent",
    "KeyEventKind", "LedBlink", "MotorEncoders", "MotorSpeeds", "OledText", "PwmServoMove",
    "SbusState",
    "ServoMove", "ServoRead", "ServoReply", "ServoStop", "ServoSub", "ServoWrite", "crc8_maxim",
    "decode_frame", "decode_report", "decode_request", "encode_frame",
]
