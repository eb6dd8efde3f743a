"""One driver per device: a lock held while a program has a serial device open.

A robot's line is half-duplex and has no notion of who asks: a second program writing to
it would steal the first one's replies and countermand its moves. So opening a device
takes an exclusive lock first, before a byte (or a line setting) reaches it, and a second
opener is refused at once, told who has it::

    /dev/pts/7 is in use by PID 1234 (busarm arm home)

The lock is ``fcntl.flock`` on a small file per device, named after the device's real
path, in the runtime folder's ``locks`` (``$BUSARM_RUNTIME_DIR``, else
``$XDG_RUNTIME_DIR/busarm``, else ``<tmp>/busarm-UID``: the folder of the running
servers' files). The kernel drops a flock when its holder closes the file or dies, by
SIGKILL too, so a lock is never stale; the file's content (the holder's PID and command
line) is only the refusal's message. Locks are per open, not per process: the same
program opening a device twice is refused too.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import re
import shlex
import sys
import time
from pathlib import Path
from types import TracebackType

from busarm.errors import DeviceInUseError, TransportError
from busarm.fileio import RUNTIME_DIR_ENV, own_dir, pid_alive, runtime_dir

__all__ = [
    "DeviceInUseError",
    "DeviceLock",
    "command_line",
    "lock_device",
    "locks_dir",
]


_COMMAND_MAX = 200
_READ_TRIES = 20  # x _READ_PAUSE_S: how long a refusal waits for the holder's name
_READ_PAUSE_S = 0.005


def locks_dir() -> Path:
    """The folder of the lock files (it may not exist yet).

    In the runtime folder (busarm.fileio.runtime_dir): the programs that share servers
    share locks, and a test run's own runtime folder keeps its locks from the
    developer's."""
    return runtime_dir() / "locks"


def command_line() -> str:
    """This program's command line as a person would type it (``busarm arm home``): the
    program's name, not its path; ``python -m busarm`` shows as ``busarm``."""
    argv = sys.argv or [""]
    first = argv[0]
    if os.path.basename(first) == "__main__.py":
        first = os.path.basename(os.path.dirname(first))
    elif first in ("", "-", "-c", "-m"):  # code given on the command line: the interpreter's
        first = f"{os.path.basename(sys.executable)} {first}".strip()
    else:
        first = os.path.basename(first)
    text = " ".join([first, shlex.join(argv[1:])]).strip()
    return text if len(text) <= _COMMAND_MAX else text[:_COMMAND_MAX - 3] + "..."


class DeviceLock:
    """The lock on one device, held until ``release()`` (or the process ends)."""

    def __init__(self, device: str, path: Path, fd: int) -> None:
        self.device = device
        """The device's real path (the lock's key)."""
        self.path = path
        """The lock file."""
        self._fd = fd

    @property
    def held(self) -> bool:
        """Whether this program holds it still."""
        return self._fd >= 0

    def release(self) -> None:
        """Let the device go (a second call does nothing)."""
        fd, self._fd = self._fd, -1
        if fd < 0:
            return
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)  # no holder's name left behind, while it is still ours
        os.close(fd)  # the flock goes with the file

    def __repr__(self) -> str:
        return f"DeviceLock({self.device!r}, {'held' if self.held else 'released'})"

    def __enter__(self) -> DeviceLock:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.release()


def lock_device(port: str) -> DeviceLock:
    """Lock the device at path ``port`` for this program, before opening it.

    DeviceInUseError (a TransportError) naming the holder if another open holds it;
    TransportError if the lock folder cannot be used."""
    device = os.path.realpath(port)
    folder = locks_dir()
    _check_folder(folder, port)
    path = folder / (_file_name(device.lstrip("/")) + ".lock")
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o600)
    except OSError as exc:
        raise TransportError(f"cannot lock {port}: lock file {path}: "
                             f"{exc.strerror or exc}") from exc
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        pid, command = _holder(fd)
        os.close(fd)
        raise DeviceInUseError(port, device, pid, command) from None
    except OSError as exc:
        os.close(fd)
        raise TransportError(f"cannot lock {port}: lock file {path}: "
                             f"{exc.strerror or exc}") from exc
    _write_holder(fd)
    return DeviceLock(device, path, fd)


def _check_folder(folder: Path, port: str) -> None:
    """Make ``folder`` (private) if need be; TransportError unless it is this user's
    (busarm.fileio.own_dir: another user's could hold locks that keep us off our own
    devices)."""
    if not own_dir(folder, create=True):
        raise TransportError(f"cannot lock {port}: no lock folder {folder} of yours (it "
                             "cannot be made, or it is not yours); set "
                             f"${RUNTIME_DIR_ENV} to a folder of yours")


def _write_holder(fd: int) -> None:
    """Name this program in the lock file (for the refusals of others)."""
    data = json.dumps({"pid": os.getpid(), "command": command_line()}).encode()
    with contextlib.suppress(OSError):  # the lock holds all the same; only the name is lost
        os.ftruncate(fd, 0)
        os.pwrite(fd, data, 0)


def _holder(fd: int) -> tuple[int | None, str]:
    """The PID and command line in a held lock file (None, "": unknown). The holder
    writes them just after taking the lock, and a file a killed holder left names that
    one: a name missing, or of a process gone, is read again, briefly."""
    for attempt in range(_READ_TRIES):
        if attempt:
            time.sleep(_READ_PAUSE_S)
        try:
            data = json.loads(os.pread(fd, 4096, 0))
        except (OSError, ValueError):
            continue
        pid, command = (data.get("pid"), data.get("command")) if isinstance(
            data, dict) else (None, None)
        if isinstance(pid, int) and not isinstance(pid, bool) and pid > 0 and isinstance(
                command, str) and pid_alive(pid):
            return pid, command
    return None, ""


def _file_name(device: str) -> str:
    """``device`` as one file name, every character kept apart (``/`` is ``%2F``)."""
    return re.sub(r"[^A-Za-z0-9._-]", lambda m: f"%{ord(m.group()):02X}", device)
