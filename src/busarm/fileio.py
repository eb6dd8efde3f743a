"""Atomic file writes (a file is either the old one or the new one, never half of each)
and reading busarm's versioned JSON files.

Every file busarm writes (simulator state, calibration, action groups, pictures) goes
through :func:`atomic_path`: the content is made in a temporary file in the same
directory, synced to disk, renamed over the target (``os.replace``, atomic on POSIX
and Windows) and the directory synced, so a crash or Ctrl+C at any point leaves the
old file or the new one.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError


@contextmanager
def atomic_path(path: Path | str, what: str = "file") -> Iterator[Path]:
    """Yield a temporary path beside ``path``; on a clean exit it replaces ``path``.

    Whatever the body writes to the temporary path becomes ``path`` in one step; if the
    body raises (Ctrl+C included) the temporary file is removed and ``path`` is left as
    it was. OS errors become ConfigError naming ``what`` and the path.
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    try:
        fd, tmp_name = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
    except OSError as exc:
        raise ConfigError(f"cannot write {what} {path}: {exc.strerror or exc}") from exc
    tmp = Path(tmp_name)
    try:
        yield tmp
        # mkstemp makes the file private (0600); keep the old file's mode, or 0644.
        try:
            mode = path.stat().st_mode & 0o777
        except OSError:
            mode = 0o644
        os.chmod(tmp, mode)
        _fsync_file(tmp)  # the data is on disk before the name points at it
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise ConfigError(f"cannot write {what} {path}: {exc.strerror or exc}") from exc
        raise
    _fsync_directory(directory)  # make the rename itself durable


def write_text_atomic(path: Path | str, text: str, what: str = "file") -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_path(path, what) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(path: Path | str, data: bytes, what: str = "file") -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path, what) as tmp:
        tmp.write_bytes(data)


def _fsync_file(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _fsync_directory(directory: Path) -> None:
    try:
        fd = os.open(directory, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return  # a platform that cannot open directories (Windows): rename is all we get
    try:
        os.fsync(fd)
    except OSError:
        pass  # some filesystems refuse fsync on a directory; the data itself is synced
    finally:
        os.close(fd)


__all__ = [
    "RUNTIME_DIR_ENV",
    "atomic_path",
    "config_home",
    "own_dir",
    "pid_alive",
    "read_versioned_json",
    "robot_folder",
    "robot_key",
    "runtime_dir",
    "write_bytes_atomic",
    "write_text_atomic",
]


def read_versioned_json(path: Path | str, what: str, fmt: str, version: int,
                        error: type[Exception] = ConfigError) -> tuple[dict[str, Any], str]:
    """A JSON object whose ``format`` is ``fmt`` and ``version`` is ``version``, and the
    text naming it for messages (``"{what} {path}"``); ``error`` saying what is wrong."""
    path = Path(path)
    where = f"{what} {path}"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise error(f"{where}: no such file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise error(f"{where}: unreadable: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != fmt:
        got = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise error(f"{where}: key 'format' is {got!r}, not {fmt!r}")
    if data.get("version") != version:
        raise error(f"{where}: key 'version' is {data.get('version')!r}; this busarm reads "
                    f"version {version}")
    return data, where


BY_ID = Path("/dev/serial/by-id")


def config_home() -> Path:
    """``$XDG_CONFIG_HOME`` if it is set to an absolute path (the XDG rule), else
    ``~/.config``."""
    given = os.environ.get("XDG_CONFIG_HOME", "")
    return Path(given) if given and Path(given).is_absolute() else Path.home() / ".config"


def _safe(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-.")[:100] or "robot"


def _by_id_name(device: Path) -> str | None:
    """The /dev/serial/by-id name of ``device``, if the system gives it one."""
    try:
        target = device.resolve()
        links = sorted(BY_ID.iterdir())
    except OSError:
        return None
    for link in links:
        try:
            if link.resolve() == target:
                return link.name
        except OSError:
            continue
    return None


def robot_key(device: str) -> str:
    """The folder name of the robot on the serial ``device`` for its kept files
    (calibrations, poses): its /dev/serial/by-id name if it has one (the same whichever
    ttyUSBn it got), else its path under /dev (``pts-7``); a pyserial URL, made safe."""
    path = Path(device)
    if not path.is_absolute():
        return _safe(device)
    name = _by_id_name(path) or (str(path)[len("/dev/"):] if str(path).startswith("/dev/")
                                 else path.name)
    return _safe(name.replace("/", "-"))


def robot_folder(key: str) -> Path:
    """The folder of the robot ``key`` (a port's ``robot_key``: ``twin``, ``sim``, a
    device's name) for its kept files (calibrations, saved poses, recorded action
    groups): ``$XDG_CONFIG_HOME/busarm/KEY``."""
    return config_home() / "busarm" / _safe(key)


RUNTIME_DIR_ENV = "BUSARM_RUNTIME_DIR"
"""Where this user's running busarm programs meet (servers' files, device locks)."""


def runtime_dir() -> Path:
    """The folder of this user's runtime files: running servers, device locks (it may not
    exist yet): ``$BUSARM_RUNTIME_DIR``, else ``$XDG_RUNTIME_DIR/busarm``, else a folder
    of this user's in the temporary folder."""
    given = os.environ.get(RUNTIME_DIR_ENV)
    if given:
        return Path(given)
    xdg = os.environ.get("XDG_RUNTIME_DIR")
    if xdg and Path(xdg).is_dir():
        return Path(xdg) / "busarm"
    user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    return Path(tempfile.gettempdir()) / f"busarm-{user}"


def own_dir(folder: Path, *, create: bool) -> bool:
    """Whether ``folder`` is a directory of this user (made, private, if ``create``).

    In a shared /tmp another user could make the folder first and plant files there
    (runtime files naming their ports, locks keeping us off our devices): a folder that
    is not ours is not trusted."""
    if create:
        with contextlib.suppress(OSError):
            folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    try:
        info = folder.lstat()
    except OSError:
        return False
    if not stat.S_ISDIR(info.st_mode):
        return False
    return not hasattr(os, "getuid") or info.st_uid == os.getuid()


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` runs (this user's or another's)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # it exists, run by someone else
    except OSError:
        return False
    return True
