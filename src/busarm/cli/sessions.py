"""Running ``busarm sim serve`` / ``busarm twin serve`` servers, found through runtime files.

A server writes one small JSON file while it runs (``sim-PID.json`` or ``twin-PID.json``)
in the runtime folder: ``$BUSARM_RUNTIME_DIR``, else ``$XDG_RUNTIME_DIR/busarm``, else
``<tmp>/busarm-UID``. The file is written atomically and removed when the server stops.
A command without ``--port`` uses the newest running server, so that commands build on
each other (``arm move-to`` then ``arm pose``). A file whose process is gone (a server
killed with SIGKILL) or whose port vanished is stale: ignored and removed.

File layout::

    {"format": "busarm-session", "version": 1, "kind": "sim", "pid": 1234,
     "port": "/dev/pts/7", "camera": null, "started": 1700000000.0}

(a twin with an arena adds ``"lidar": "/dev/pts/9"``, its Lidar's port).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path

from busarm.bus.ports import PortSpec, SerialPort
from busarm.errors import ConfigError
from busarm.fileio import (
    RUNTIME_DIR_ENV,
    own_dir,
    pid_alive,
    runtime_dir,
    write_text_atomic,
)

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "KINDS",
    "RUNTIME_DIR_ENV",
    "Session",
    "announced",
    "find_session",
    "running_sessions",
    "runtime_dir",
]


FORMAT_NAME = "busarm-session"
FORMAT_VERSION = 1
KINDS = ("sim", "twin")


@dataclass(frozen=True)
class Session:
    """One running server: what it serves (``sim`` or ``twin``) and where."""

    kind: str
    pid: int
    port: str
    """The servos' serial port (a pty path)."""
    camera: str | None
    """The camera source (``twin://127.0.0.1:PORT``) of a twin; None for the simulator."""
    started: float
    """When it started (seconds since the epoch)."""
    path: Path
    """Its runtime file."""
    lidar: str | None = None
    """The Lidar's serial port (a pty path) of a twin with an arena; else None."""

    def describe(self) -> str:
        """``the arm of `busarm sim serve` (pid 1234) on /dev/pts/7`` (``the robot of``
        a twin with an arena: it has a base and a Lidar too)."""
        what = "robot" if self.lidar else "arm"
        return f"the {what} of `busarm {self.kind} serve` (pid {self.pid}) on {self.port}"


@contextmanager
def announced(kind: str, port: str, camera: str | None = None,
              lidar: str | None = None) -> Iterator[Path | None]:
    """Write this process's runtime file for the body's duration (None: no folder for it).

    The file is removed when the body ends, by an exception or SIGTERM too (the caller
    turns SIGTERM into KeyboardInterrupt); a SIGKILL leaves it, and readers clean it."""
    folder = runtime_dir()
    if kind not in KINDS or not own_dir(folder, create=True):
        yield None
        return
    path = folder / f"{kind}-{os.getpid()}.json"
    data = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "kind": kind,
            "pid": os.getpid(), "port": port, "camera": camera, "started": time.time()}
    if lidar is not None:
        data["lidar"] = lidar
    try:
        write_text_atomic(path, json.dumps(data) + "\n", "runtime file")
    except ConfigError:  # the server runs all the same; commands just cannot find it
        written = None
    else:
        written = path
    try:
        yield written
    finally:
        if written is not None:
            written.unlink(missing_ok=True)


def _read(path: Path) -> Session | None:
    """The session of a runtime file; None if the file is not one (or unreadable)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME or \
            data.get("version") != FORMAT_VERSION:
        return None
    kind, pid, port = data.get("kind"), data.get("pid"), data.get("port")
    camera, started, lidar = data.get("camera"), data.get("started", 0.0), data.get("lidar")
    if kind not in KINDS or not isinstance(pid, int) or not isinstance(port, str) or \
            not all(v is None or isinstance(v, str) for v in (camera, lidar)) or \
            not isinstance(started, int | float):
        return None
    return Session(kind, pid, port, camera, float(started), path, lidar)


def running_sessions() -> list[Session]:
    """The servers running now, newest first; stale runtime files are removed."""
    folder = runtime_dir()
    if not own_dir(folder, create=False):
        return []
    found = []
    for path in folder.glob("*.json"):
        session = _read(path)
        if session is None:
            continue  # not ours to judge or remove
        world = _world(session.port)
        device = world.device if isinstance(world, SerialPort) else session.port
        if not pid_alive(session.pid) or not Path(device).exists():
            with suppress(OSError):
                path.unlink()
            continue
        found.append(session)
    return sorted(found, key=lambda s: s.started, reverse=True)


def find_session() -> Session | None:
    """The newest running server, or None."""
    sessions = running_sessions()
    return sessions[0] if sessions else None


def _world(port: str) -> PortSpec | None:
    """A session's port, read (None if it is not one: a file from another version)."""
    from busarm.robot.port_url import parse_port

    try:
        return parse_port(port)
    except ConfigError:
        return None
