"""Byte transports under the servo bus: serial devices and pyserial URLs.

A transport moves bytes and nothing else; framing, echo and timeouts belong to the
driver. ``open_serial`` opens a serial device given by its name (``busarm.bus.ports``
opens any kind of port):

- ``/dev/ttyUSB0``, ``COM3``: a serial device (pyserial, with a direct file-descriptor
  fast path on POSIX);
- ``socket://``, ``rfc2217://``, ``loop://``, ``spy://`` ...: any pyserial URL.

A transport's ``framing`` says which protocol its bytes are: ``lx`` (the servos' own)
or ``board`` (the controller board's frames at 1,000,000 baud).
"""

from __future__ import annotations

import errno
import os
import select
import stat
import termios
import warnings
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from busarm.bus.device_lock import DeviceLock, lock_device
from busarm.clock import WALL_CLOCK, Clock
from busarm.errors import ConfigError, TransportError

__all__ = [
    "BOARD_BAUDRATE",
    "DEFAULT_BAUDRATE",
    "SYSFS",
    "SerialTransport",
    "Transport",
    "adapter_latency_s",
    "check_baudrate",
    "check_device",
    "is_pyserial_url",
    "open_serial",
    "usb_latency_timer_ms",
]


DEFAULT_BAUDRATE = 115200

BOARD_BAUDRATE = 1_000_000
"""The controller board's fixed USB serial rate."""
@runtime_checkable
class Transport(Protocol):
    """What the driver needs from a byte pipe."""

    name: str
    baudrate: int
    framing: str
    """The protocol of the bytes: ``lx`` (bus servos' own) or ``board`` (controller board)."""
    latency_s: float
    """Extra delay the adapter adds before received bytes reach us (USB latency timer)."""
    clock: Clock
    """The time the other end lives in: the wall clock for hardware, a simulation's own
    clock for a simulator in this process. Everyone above waits on it."""

    def write(self, data: bytes) -> None: ...

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        """Wait up to ``timeout_s`` for input; return what is there (b'' on timeout)."""
        ...

    def reset_input(self) -> None:
        """Discard every byte received and not yet read."""
        ...

    def exchange(self, request: bytes, timeout_s: float) -> bytes:
        """reset_input(), write(request), then read(): one half-duplex turn."""
        ...

    def close(self) -> None: ...


SYSFS = Path("/sys")


def _latency_file(device: str, sysfs: Path) -> Path:
    name = Path(os.path.realpath(device)).name
    return sysfs / "bus" / "usb-serial" / "devices" / name / "latency_timer"


def usb_latency_timer_ms(device: str, *, sysfs: Path = SYSFS) -> int | None:
    """The FTDI-style latency timer of a USB serial device, from Linux sysfs, or None."""
    try:
        return int(_latency_file(device, sysfs).read_text().strip())
    except (OSError, ValueError):
        return None


def adapter_latency_s(device: str, *, sysfs: Path = SYSFS) -> float:
    """How long the adapter may hold received bytes (0 if unknown).

    Warns (RuntimeWarning) when the USB latency timer is above 1 ms: every reply then
    waits that long, and the warning says how to lower it.
    """
    latency_ms = usb_latency_timer_ms(device, sysfs=sysfs)
    if latency_ms is None:
        return 0.0
    if latency_ms > 1:
        warnings.warn(
            f"{device}: USB latency timer is {latency_ms} ms; every reply waits that long. "
            f"Set it to 1 ms: echo 1 | sudo tee {_latency_file(device, sysfs)}",
            RuntimeWarning,
            stacklevel=4,
        )
    return latency_ms / 1000.0


class SerialTransport:
    """A pyserial port. Device paths on POSIX use the file descriptor directly,
    which saves tens of microseconds per transaction over ``Serial.read``."""

    def __init__(self, port: Any, name: str, *, use_fd: bool, framing: str = "lx") -> None:
        self._port = port
        self.name = name
        self.framing = framing
        self.baudrate = int(port.baudrate)
        self.latency_s = 0.0
        self.clock: Clock = WALL_CLOCK
        self._fd: int | None = port.fileno() if use_fd else None
        if self._fd is not None:
            self.latency_s = adapter_latency_s(name)

    @property
    def fd(self) -> int | None:
        """The OS file descriptor of a device path (None for URL handlers)."""
        return self._fd

    def write(self, data: bytes) -> None:
        try:
            if self._fd is not None:
                n = os.write(self._fd, data)
                if n < len(data):  # a full kernel buffer: rare, never on a 6-10 byte frame
                    view = memoryview(data)[n:]
                    while view:
                        select.select((), (self._fd,), (), 1.0)
                        view = view[os.write(self._fd, view) :]
            else:
                self._port.write(data)
        except Exception as exc:
            raise TransportError(f"{self.name}: write failed: {exc}") from exc

    def read(self, max_bytes: int, timeout_s: float) -> bytes:
        try:
            if self._fd is not None:
                r, _, _ = select.select((self._fd,), (), (), max(timeout_s, 0.0))
                if not r:
                    return b""
                data = os.read(self._fd, max_bytes)
                if not data:
                    raise TransportError(f"{self.name}: device disconnected")
                return data
            port = self._port
            waiting = port.in_waiting
            if waiting:
                return bytes(port.read(min(waiting, max_bytes)))
            port.timeout = max(timeout_s, 0.0)
            first = port.read(1)
            if not first:
                return b""
            more = port.in_waiting
            return bytes(first) + (bytes(port.read(min(more, max_bytes - 1))) if more else b"")
        except TransportError:
            raise
        except Exception as exc:
            raise TransportError(f"{self.name}: read failed: {exc}") from exc

    def exchange(self, request: bytes, timeout_s: float) -> bytes:
        fd = self._fd
        if fd is None:
            self.reset_input()
            self.write(request)
            return self.read(256, timeout_s)
        # One frame for the whole turn: this is the driver's hot path.
        try:
            termios.tcflush(fd, termios.TCIFLUSH)
            if os.write(fd, request) < len(request):
                raise TransportError(f"{self.name}: short write")
            if not select.select((fd,), (), (), timeout_s)[0]:
                return b""
            data = os.read(fd, 256)
        except TransportError:
            raise
        except Exception as exc:
            raise TransportError(f"{self.name}: {exc}") from exc
        if not data:
            raise TransportError(f"{self.name}: device disconnected")
        return data

    def reset_input(self) -> None:
        try:
            if self._fd is not None:
                termios.tcflush(self._fd, termios.TCIFLUSH)
            else:
                self._port.reset_input_buffer()
        except Exception as exc:
            raise TransportError(f"{self.name}: cannot reset input: {exc}") from exc

    def set_dtr(self, asserted: bool) -> bool:
        """Set the DTR modem line (a USB adapter may wire it to a motor, as the RPLIDAR
        A1's does); False if the port has no modem lines (a pty, a URL)."""
        try:
            self._port.dtr = asserted
        except (OSError, ValueError):  # pyserial's SerialException is an OSError
            return False
        return True

    device_lock: DeviceLock | None = None
    """This program's lock on the device (``busarm.bus.device_lock``), let go on close."""

    def close(self) -> None:
        try:
            self._port.close()
        finally:  # after the port: the next program never finds the device still open
            if self.device_lock is not None:
                self.device_lock.release()


def check_baudrate(baudrate: object) -> int:
    """``baudrate``, checked: an integer 1200..4000000 (ConfigError otherwise)."""
    if not isinstance(baudrate, int) or isinstance(baudrate, bool):
        raise ConfigError(f"baudrate must be an integer 1200..4000000, got {baudrate!r}")
    if not 1200 <= baudrate <= 4_000_000:
        raise ConfigError(f"baudrate {baudrate} is out of range 1200..4000000")
    return baudrate


_OPEN_ERRORS = {
    errno.ENOTTY: "it is not a serial device (`busarm ports` lists the serial ports of this "
                  "computer)",
    errno.EACCES: "permission denied: add yourself to the group that owns it (often dialout: "
                  "sudo usermod -aG dialout $USER, then log in again)",
    errno.EBUSY: "it is busy: another program has it open",
}
"""What the OS's errors when opening a device mean for a person."""


def _os_errno(exc: BaseException) -> int:
    """The OS error number behind ``exc`` (pyserial wraps termios errors, which carry it
    as their first argument, in a SerialException without one), or 0."""
    seen: BaseException | None = exc
    while seen is not None:
        number = getattr(seen, "errno", None)
        if number is None and seen.args and isinstance(seen.args[0], int):
            number = seen.args[0]
        if isinstance(number, int) and number:
            return number
        seen = seen.__cause__ or seen.__context__
    return 0


def _device_problem(path: str) -> str | None:
    """Why ``path`` cannot be a serial device (it does not exist, it is a file...), or None.

    Said before opening: the OS's own words ("Inappropriate ioctl for device") do not
    tell a person what is wrong."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "it does not exist (is the adapter plugged in? its name may differ)"
    except OSError:
        return None  # permission and the like: pyserial's message says it
    if stat.S_ISCHR(mode):
        return None
    kind = "a directory" if stat.S_ISDIR(mode) else (
        "a regular file" if stat.S_ISREG(mode) else "not a character device")
    return f"it is {kind}, not a serial device"


def is_pyserial_url(device: str) -> bool:
    """Whether ``device`` is a pyserial URL (``socket://...``), not a device path: pyserial
    reads those itself."""
    return "://" in device


def check_device(device: str) -> None:
    """TransportError if ``device`` is a path that cannot be a serial port (missing, not
    a device), without opening it; pyserial URLs pass."""
    if is_pyserial_url(device) or os.name != "posix":
        return
    problem = _device_problem(device)
    if problem is not None:
        raise TransportError(f"cannot open {device!r}: {problem}; `busarm ports` lists the "
                             "serial ports of this computer")


def open_serial(device: str, baudrate: int, *, name: str, framing: str) -> SerialTransport:
    """Open the serial device (path or pyserial URL) ``device``, its bytes ``framing``."""
    return _open_serial(device, baudrate, name=name, framing=framing)


def _open_serial(port: str, baudrate: int, *, name: str, framing: str) -> SerialTransport:
    import serial  # pyserial; imported here so the protocol-only user never pays for it

    check_device(port)
    # One driver per device: refused before anything (a line setting too) reaches it. A
    # pyserial URL names no device of this computer: nothing to lock.
    lock = None if "://" in port else lock_device(port)
    ser = None
    try:
        if "://" in port:
            ser = serial.serial_for_url(port, baudrate=baudrate, timeout=0, write_timeout=1.0,
                                        do_not_open=True)
        else:
            # The device's own flock as well: a program locking elsewhere (another user's,
            # another $BUSARM_RUNTIME_DIR) is kept out too, if not named.
            ser = serial.Serial(None, baudrate=baudrate, timeout=0, write_timeout=1.0,
                                exclusive=True)
            ser.port = port
        if framing == "board":  # the vendor's board wants RTS and DTR low before it opens
            ser.rts = False
            ser.dtr = False
        ser.open()
        transport = SerialTransport(ser, name, use_fd="://" not in port and os.name == "posix",
                                    framing=framing)
    except BaseException as exc:
        if ser is not None:
            ser.close()  # nothing if it did not open
        if lock is not None:
            lock.release()
        if isinstance(exc, ValueError):
            raise ConfigError(f"cannot open {port!r}: {exc}") from exc
        if isinstance(exc, serial.SerialException | OSError):
            number = _os_errno(exc)
            why = ("it is in use: another program holds its lock" if number == errno.EWOULDBLOCK
                   else _OPEN_ERRORS.get(number, str(exc)))
            raise TransportError(f"cannot open {port!r}: {why}") from exc
        raise
    transport.device_lock = lock
    return transport
