"""Every exception busarm raises, by the phase in which it happens.

Failures raise; they never return ``None`` or a success flag. Several classes also
inherit a builtin (``ValueError``, ``OSError``, ``TimeoutError``) so generic handlers
still catch them.
"""

from __future__ import annotations


class BusArmError(Exception):
    """Root of every busarm error."""


class ConfigError(BusArmError, ValueError):
    """A bad argument or file: the message names the value and the allowed range."""


class LimitError(ConfigError):
    """A target outside the configured limits; raised before any byte is sent."""


class ProtocolError(BusArmError):
    """An undecodable or unexpected frame. ``raw`` keeps the offending bytes."""

    def __init__(self, message: str, raw: bytes = b"") -> None:
        super().__init__(message)
        self.raw = bytes(raw)


class ChecksumError(ProtocolError):
    """A frame whose checksum does not match its contents."""


class TransportError(BusArmError, OSError):
    """The port cannot be opened, or vanished while in use."""


class BusTimeoutError(BusArmError, TimeoutError):
    """No valid reply arrived by the deadline (after the allowed retries)."""

    def __init__(
        self, message: str, servo_id: int | None = None, command: int | None = None,
        timeout_s: float | None = None,
    ) -> None:
        super().__init__(message)
        self.servo_id = servo_id
        self.command = command
        self.timeout_s = timeout_s


class ServoFaultError(BusArmError):
    """A servo reports (or its readings show) a fault: over-temperature, voltage, stall."""

    def __init__(self, message: str, servo_id: int | None = None) -> None:
        super().__init__(message)
        self.servo_id = servo_id


class BusConflictError(BusArmError):
    """More than one servo answered where exactly one was required (duplicate IDs)."""


class KinematicsError(BusArmError, ValueError):
    """A pose the arm's model cannot produce."""


class UnreachableError(KinematicsError):
    """A target outside the workspace: beyond reach, below the table, or past a joint limit.

    ``reason`` is ``"reach"``, ``"table"`` or ``"joint_limit"``; ``joint`` names the joint
    for a joint limit.
    """

    def __init__(self, message: str, reason: str = "reach", joint: str | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.joint = joint


class CalibrationError(ConfigError):
    """A calibration file that is unreadable or does not match the arm it is used with."""


class VisionError(BusArmError):
    """A camera image could not be turned into what was asked (no frame, nothing found)."""


class CameraError(VisionError, OSError):
    """A camera source that cannot be opened or stopped delivering frames."""


class TwinError(BusArmError):
    """The digital twin cannot be built or rendered (MuJoCo or its OpenGL backend missing)."""


__all__ = [
    "BusArmError",
    "BusConflictError",
    "BusTimeoutError",
    "CalibrationError",
    "CameraError",
    "ChecksumError",
    "ConfigError",
    "KinematicsError",
    "LimitError",
    "MotionTimeoutError",
    "ProtocolError",
    "ServoFaultError",
    "TransportError",
    "TwinError",
    "UnreachableError",
    "VisionError",
]


class MotionTimeoutError(BusArmError, TimeoutError):
    """Servos did not reach their targets within the allowed time."""
