"""Every exception busarm raises, by the phase in which it happens.

Failures raise; they never return ``None`` or a success flag. Several classes also
inherit a builtin (``ValueError``, ``OSError``, ``TimeoutError``) so generic handlers
still catch them.
"""

from __future__ import annotations

import functools
import os


class BusArmError(Exception):
    """Root of every busarm error."""


class ConfigError(BusArmError, ValueError):
    """A bad argument or file: the message names the value and the allowed range."""


class LimitError(ConfigError):
    """A target outside the configured limits; raised before any byte is sent."""


class UnsupportedError(ConfigError):
    """What this port cannot do: the controller board has no command for it (it offers no
    raw pass-through to the servo line). Raised before anything is sent."""


class ProtocolError(BusArmError):
    """An undecodable or unexpected frame. ``raw`` keeps the offending bytes."""

    def __init__(self, message: str, raw: bytes = b"") -> None:
        super().__init__(message)
        self.raw = bytes(raw)


class ChecksumError(ProtocolError):
    """A frame whose checksum does not match its contents."""


class EchoMismatchError(ProtocolError):
    """Replies that show the echo setting is wrong: the servo's reply came with no copy of
    our request before it, though echo is on (the adapter does not echo)."""


class TransportError(BusArmError, OSError):
    """The port cannot be opened, or vanished while in use."""


class NotALidarError(TransportError):
    """A port given as a Lidar's whose device does not answer like one (no valid reply to
    the Lidar's identification requests)."""


class LidarFaultError(BusArmError):
    """The Lidar reports itself in error (its health status), or stopped scanning."""


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


class UnreliableLineError(BusTimeoutError):
    """No reply by the deadline from a servo that may well be there: it answered on this
    bus before, or the line has lately delivered replies late or damaged."""


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
    """A target outside the workspace: beyond reach, below the table, inside the arm's
    base, or past a joint limit.

    ``reason`` is ``"reach"``, ``"table"``, ``"base"`` or ``"joint_limit"``; ``joint``
    names the joint for a joint limit.
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


class MotionError(BusArmError):
    """A move that did not go as commanded: a servo did not arrive, or the arm hit something."""


class HaltedError(MotionError):
    """The bus is halted (an e-stop): nothing moves until it is re-armed explicitly."""


class MotionTimeoutError(MotionError, TimeoutError):
    """Servos did not reach their targets within the allowed time."""


class ContactError(MotionError):
    """A guarded move found a joint stopped short of its commanded path: the arm touched
    something. The arm is stopped; ``backed_off`` says whether it then went back to where
    the move started (else it is stopped and holding where it was).

    ``joint`` names the joint that stopped short and ``lag_deg`` by how much; ``along_mm``
    is how far along the line the tool was, ``tool_mm`` where it was (x, y, z), and
    ``detected_s`` the arm clock's time of the detection.
    """

    def __init__(
        self, message: str, *, joint: str, lag_deg: float, along_mm: float,
        tool_mm: tuple[float, float, float], backed_off: bool, detected_s: float,
    ) -> None:
        super().__init__(message)
        self.joint = joint
        self.lag_deg = lag_deg
        self.along_mm = along_mm
        self.tool_mm = tool_mm
        self.backed_off = backed_off
        self.detected_s = detected_s

    def __reduce__(self) -> tuple[object, ...]:
        # Keyword-only fields: pickle them by name (bench workers send errors back).
        fields = {k: getattr(self, k) for k in (
            "joint", "lag_deg", "along_mm", "tool_mm", "backed_off", "detected_s")}
        return (functools.partial(type(self), **fields), (str(self),))


__all__ = [
    "BusArmError",
    "BusConflictError",
    "BusTimeoutError",
    "CalibrationError",
    "CameraError",
    "ChecksumError",
    "ConfigError",
    "ContactError",
    "DeviceInUseError",
    "EchoMismatchError",
    "HaltedError",
    "KinematicsError",
    "LidarFaultError",
    "LimitError",
    "MotionError",
    "MotionTimeoutError",
    "NavigationError",
    "NotALidarError",
    "ProtocolError",
    "ServoFaultError",
    "TransportError",
    "TwinError",
    "UnreachableError",
    "UnreliableLineError",
    "UnsupportedError",
    "VisionError",
    "why_stopped",
]


class NavigationError(BusArmError):
    """A mobile job could not go on: no path, lost localisation, a Lidar that stopped
    sending, an obstacle that did not go away. The base is stopped when it is raised."""


class DeviceInUseError(TransportError):
    """The device is open by another driver (which may be this very program)."""

    def __init__(self, port: str, device: str, pid: int | None, command: str) -> None:
        self.port = port
        self.device = device
        self.pid = pid
        self.command = command
        shown = port if port == device else f"{port} ({device})"
        who = f"PID {pid} ({command})" if pid is not None else "another program"
        if pid == os.getpid():
            who += ", this program itself, which has it open already"
        super().__init__(f"{shown} is in use by {who}: one program drives a robot at a "
                         "time; stop that one first, or wait for it to end")

    def __reduce__(self) -> tuple[type[DeviceInUseError], tuple[str, str, int | None, str]]:
        # Made again from its parts (OSError's own would pass the message as the port).
        return type(self), (self.port, self.device, self.pid, self.command)


def why_stopped(exc: BaseException) -> str:
    """What a job's report says of ``exc``, which ended it: a person's stop (Ctrl+C,
    SIGTERM or SIGHUP, a halt or a page's Stop) in its own words, "stopped by SIGTERM";
    anything else as an error."""
    if isinstance(exc, KeyboardInterrupt | HaltedError):
        return str(exc) or "interrupted"
    return f"stopped by an error: {str(exc) or type(exc).__name__}"
