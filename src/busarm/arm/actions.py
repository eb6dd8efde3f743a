"""Action groups: the vendor's ``.d6a`` files of timed arm poses, read and written.

A ``.d6a`` file is an SQLite 3 database with one user table (plus SQLite's own
``sqlite_sequence``, which its AUTOINCREMENT keeps)::

    CREATE TABLE ActionGroup([Index] INTEGER PRIMARY KEY AUTOINCREMENT ...,
                             Time INT, Servo1 INT, ..., ServoN INT)

One row per frame, in ``Index`` order: ``Time`` is the move time of the frame in ms,
``ServoK`` the target position in pulses (0..1000) of the servo mapped to column K.
Which servo a column drives is the caller's mapping (a tuple of servo IDs, e.g.
``(1, 2, 3, 4, 5, 10)`` on the JetAuto Pro arm); see :func:`frame_targets`. The vendor
plays a group by sending every servo its target with move time ``Time``, waiting
``Time`` and checking a stop flag between rows.

This module is pure file I/O: no bus, no arm. Every bad value or bad file raises
:class:`~busarm.errors.ConfigError` with one message naming the file, frame, column,
value and allowed range. A group has at least one frame (an empty group cannot be
played, and a ``.d6a`` file without rows is refused as truncated or unfinished).
:func:`write_d6a` writes the vendor's exact schema atomically (old file or new file,
never a mix).
"""

from __future__ import annotations

import contextlib
import re
import sqlite3
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from busarm.errors import ConfigError
from busarm.fileio import atomic_path
from busarm.protocol import check_servo_id
from busarm.protocol.lx_units import MOVE_TIME_MAX_MS, POSITION_MAX_PULSES, POSITION_MIN_PULSES
from busarm.units import check_int_range, listing

TABLE_NAME = "ActionGroup"
"""The vendor's table of frames."""
MAX_SERVOS = 32
"""Most servo columns (``Servo1..Servo32``) a group may have."""
DURATION_MIN_MS = 0
DURATION_MAX_MS = MOVE_TIME_MAX_MS
"""A frame's move time is the servo's: 0..30000 ms."""

_SERVO_COLUMN = re.compile(r"servo([1-9][0-9]*)", re.IGNORECASE)
_INDENT = " " * 20  # the vendor's continuation-line indent, kept so sqlite_master matches


@dataclass(frozen=True)
class ActionFrame:
    """One row: every servo moves to its position in ``duration_ms``.

    ``positions_pulses[k - 1]`` is column ``Servo<k>``. Durations are 0..30000 ms,
    positions 0..1000 pulses, 1..32 servos; any integer-like values are stored as
    plain ints and any sequence as a tuple.
    """

    duration_ms: int
    positions_pulses: tuple[int, ...]

    def __post_init__(self) -> None:
        duration = check_int_range(
            "Time (duration_ms)", self.duration_ms, DURATION_MIN_MS, DURATION_MAX_MS, "ms"
        )
        raw: object = self.positions_pulses  # callers may pass a list; checked here
        if isinstance(raw, str | bytes) or not isinstance(raw, Iterable):
            raise ConfigError(f"positions_pulses must be a sequence of integers, got {raw!r}")
        values = tuple(raw)
        if not 1 <= len(values) <= MAX_SERVOS:
            raise ConfigError(
                f"a frame has {len(values)} servo positions; allowed 1..{MAX_SERVOS}"
            )
        positions = tuple(
            check_int_range(f"Servo{k}", v, POSITION_MIN_PULSES, POSITION_MAX_PULSES, "pulses")
            for k, v in enumerate(values, start=1)
        )
        object.__setattr__(self, "duration_ms", duration)
        object.__setattr__(self, "positions_pulses", positions)

    @property
    def servo_count(self) -> int:
        return len(self.positions_pulses)


@dataclass(frozen=True)
class ActionGroup:
    """Frames played in order; every frame moves the same servos (columns).

    At least one frame. Frame numbers in messages count from 1, as the vendor's
    ``Index`` does in the files it writes.
    """

    frames: tuple[ActionFrame, ...]

    def __post_init__(self) -> None:
        raw: object = self.frames
        if not isinstance(raw, Iterable):
            raise ConfigError(f"frames must be a sequence of ActionFrame, got {raw!r}")
        frames = tuple(raw)
        if not frames:
            raise ConfigError("an action group needs at least one frame; got none")
        for n, frame in enumerate(frames, start=1):
            if not isinstance(frame, ActionFrame):
                raise ConfigError(f"frame {n} is not an ActionFrame: {frame!r}")
            if frame.servo_count != frames[0].servo_count:
                raise ConfigError(
                    f"frame {n} has {frame.servo_count} servo positions but frame 1 has "
                    f"{frames[0].servo_count}; every frame must have the same servos"
                )
        object.__setattr__(self, "frames", frames)

    @classmethod
    def from_rows(cls, rows: Iterable[tuple[int, Sequence[int]]]) -> ActionGroup:
        """A group from ``(duration_ms, positions_pulses)`` rows; errors name the frame."""
        frames = []
        for n, (duration_ms, positions) in enumerate(rows, start=1):
            try:
                frames.append(ActionFrame(duration_ms, tuple(positions)))
            except ConfigError as exc:
                raise ConfigError(f"frame {n}: {exc}") from None
        return cls(tuple(frames))

    @property
    def servo_count(self) -> int:
        """The number of ``Servo<k>`` columns."""
        return self.frames[0].servo_count

    @property
    def total_duration_ms(self) -> int:
        """The playback time: the sum of the frames' move times."""
        return sum(f.duration_ms for f in self.frames)

    def check_servo_ids(self, servo_ids: Sequence[int]) -> tuple[int, ...]:
        """Return ``servo_ids`` (column 1's servo first) if it fits this group's columns."""
        return _check_servo_ids(servo_ids, self.servo_count)

    def targets(self, servo_ids: Sequence[int]) -> tuple[dict[int, int], ...]:
        """One ``{servo_id: position_pulses}`` per frame, columns paired with ``servo_ids``."""
        ids = self.check_servo_ids(servo_ids)
        return tuple(dict(zip(ids, f.positions_pulses, strict=True)) for f in self.frames)


def _check_servo_ids(servo_ids: Sequence[int], servo_count: int | None) -> tuple[int, ...]:
    if isinstance(servo_ids, str | bytes) or not isinstance(servo_ids, Iterable):
        raise ConfigError(f"servo_ids must be a sequence of servo IDs, got {servo_ids!r}")
    ids = tuple(servo_ids)
    if servo_count is not None and len(ids) != servo_count:
        raise ConfigError(
            f"{len(ids)} servo IDs {listing(ids)} for {servo_count} columns "
            f"(Servo1..Servo{servo_count}): "
            "give one servo ID per column"
        )
    for servo_id in ids:
        check_servo_id(servo_id)
    duplicates = sorted({i for i in ids if ids.count(i) > 1})
    if duplicates:
        raise ConfigError(f"servo IDs {listing(ids)} repeat {listing(duplicates)}: each column "
                          "needs its own servo")
    return ids


def frame_targets(frame: ActionFrame, servo_ids: Sequence[int]) -> dict[int, int]:
    """``{servo_id: position_pulses}`` for one frame; column K drives ``servo_ids[K - 1]``.

    Raises ConfigError if the counts differ, an ID repeats or is outside 0..253.
    """
    ids = _check_servo_ids(servo_ids, frame.servo_count)
    return dict(zip(ids, frame.positions_pulses, strict=True))


def frame_from_targets(
    duration_ms: int, targets: Mapping[int, int], servo_ids: Sequence[int]
) -> ActionFrame:
    """The frame that moves each of ``servo_ids`` (in column order) to ``targets[id]``.

    The inverse of :func:`frame_targets`; ``targets`` must hold exactly ``servo_ids``.
    """
    ids = _check_servo_ids(servo_ids, None)
    missing = [i for i in ids if i not in targets]
    extra = sorted(set(targets) - set(ids))
    if missing or extra:
        raise ConfigError(
            f"targets for servos {listing(sorted(targets))} do not match the columns' servo "
            f"IDs {listing(ids)}"
            + (f"; missing {listing(missing)}" if missing else "")
            + (f"; not a column {listing(extra)}" if extra else "")
        )
    return ActionFrame(duration_ms, tuple(targets[i] for i in ids))


def create_table_sql(servo_count: int) -> str:
    """The vendor's exact CREATE TABLE text for ``servo_count`` servo columns."""
    check_int_range("servo_count", servo_count, 1, MAX_SERVOS, "columns")
    columns = [f"{_INDENT}Time INT"] + [f"{_INDENT}Servo{k} INT" for k in range(1, servo_count + 1)]
    return (
        f"CREATE TABLE {TABLE_NAME}([Index] INTEGER PRIMARY KEY AUTOINCREMENT\n"
        f"{_INDENT}NOT NULL ON CONFLICT FAIL\n"
        f"{_INDENT}UNIQUE ON CONFLICT ABORT,\n" + ",\n".join(columns) + ")"
    )


def read_d6a(path: Path | str) -> ActionGroup:
    """Read a vendor action-group file (opened read-only; never modified).

    Accepts any number of ``Servo<k>`` columns (k = 1..N, contiguous, at most 32) and
    orders frames by ``Index``. Raises ConfigError naming the file for a missing or
    unreadable file, a file that is not SQLite, no ``ActionGroup`` table, wrong
    columns, no rows, or a NULL, non-integer or out-of-range cell.
    """
    path = Path(path)
    where = f"action group {path}"
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise ConfigError(f"cannot read {where}: {exc.strerror or exc}") from None
    if not path.is_file():
        raise ConfigError(f"cannot read {where}: not a regular file")
    if size == 0:
        raise ConfigError(f"{where} is empty (0 bytes), not an SQLite action-group file")
    # A URI so that the file is opened read-only; as_uri() percent-encodes ? # % etc.
    uri = path.absolute().as_uri() + "?mode=ro"
    try:
        conn = sqlite3.connect(uri, uri=True)
    except sqlite3.Error as exc:
        raise ConfigError(f"cannot open {where}: {exc}") from None
    try:
        with contextlib.closing(conn):
            return _read_group(conn, where)
    except sqlite3.DatabaseError as exc:
        if "not a database" in str(exc):
            raise ConfigError(f"{where} is not an SQLite database ({exc})") from None
        raise ConfigError(f"cannot read {where}: {exc}") from None
    except sqlite3.Error as exc:
        raise ConfigError(f"cannot read {where}: {exc}") from None


def _read_group(conn: sqlite3.Connection, where: str) -> ActionGroup:
    tables = [
        str(name)
        for (name,) in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
    ]
    table = next((t for t in tables if t.lower() == TABLE_NAME.lower()), None)
    if table is None:
        found = ", ".join(tables) or "none"
        raise ConfigError(f"{where} has no {TABLE_NAME} table (tables: {found})")
    columns = [str(row[1]) for row in conn.execute(f'PRAGMA table_info("{table}")')]
    servo_columns: dict[int, str] = {}
    unknown = []
    for column in columns:
        match = _SERVO_COLUMN.fullmatch(column)
        if match:
            servo_columns[int(match.group(1))] = column
        elif column.lower() not in ("index", "time"):
            unknown.append(column)
    lower = [c.lower() for c in columns]
    problems = []
    if "index" not in lower:
        problems.append("no Index column")
    if "time" not in lower:
        problems.append("no Time column")
    if unknown:
        problems.append(f"unexpected column(s) {', '.join(unknown)}")
    count = len(servo_columns)
    if count == 0:
        problems.append("no Servo<k> columns")
    elif sorted(servo_columns) != list(range(1, count + 1)):
        problems.append(
            f"servo columns {', '.join(servo_columns[k] for k in sorted(servo_columns))} "
            "are not Servo1..ServoN without gaps"
        )
    elif count > MAX_SERVOS:
        problems.append(f"{count} servo columns; at most {MAX_SERVOS} allowed")
    if problems:
        raise ConfigError(
            f"{where}: table {table} has the wrong columns ({'; '.join(problems)}); "
            f"expected Index, Time, Servo1..ServoN; found {', '.join(columns)}"
        )
    names = ['"Index"', '"Time"'] + [f'"{servo_columns[k]}"' for k in range(1, count + 1)]
    query = f'SELECT {", ".join(names)} FROM "{table}" ORDER BY "Index"'
    frames = []
    for n, row in enumerate(conn.execute(query), start=1):
        index, cells = row[0], row[1:]
        cell_names = ["Time", *(f"Servo{k}" for k in range(1, count + 1))]
        at = f"{where}: frame {n} (Index {index})"
        for name, value in zip(cell_names, cells, strict=True):
            if value is None:
                raise ConfigError(f"{at}: {name} is NULL; every cell must hold an integer")
        try:
            frames.append(ActionFrame(cells[0], tuple(cells[1:])))
        except ConfigError as exc:
            raise ConfigError(f"{at}: {exc}") from None
    if not frames:
        raise ConfigError(f"{where}: table {table} has no rows; an action group needs a frame")
    return ActionGroup(tuple(frames))


def write_d6a(path: Path | str, group: ActionGroup) -> None:
    """Write ``group`` as a vendor action-group file, atomically.

    The table has the vendor's exact schema text (so ``sqlite_master`` matches the
    vendor's files), rows get ``Index`` 1..N from the AUTOINCREMENT, which also fills
    ``sqlite_sequence`` as the vendor's files have it. The database is built in a
    temporary file beside ``path``, synced, and renamed over ``path``: an existing
    file is replaced whole or left untouched. Raises ConfigError naming the file.
    """
    path = Path(path)
    if not isinstance(group, ActionGroup):
        raise ConfigError(f"cannot write action group {path}: not an ActionGroup: {group!r}")
    what = "action group"
    with atomic_path(path, what) as tmp:
        try:
            _build_database(tmp, group)
        except sqlite3.Error as exc:
            raise ConfigError(f"cannot write {what} {path}: {exc}") from None
        finally:
            # SQLite removes its rollback journal itself; this is for a crash mid-build.
            Path(f"{tmp}-journal").unlink(missing_ok=True)


def _build_database(db_path: Path, group: ActionGroup) -> None:
    conn = sqlite3.connect(str(db_path), isolation_level=None)
    with contextlib.closing(conn):
        conn.execute("PRAGMA journal_mode = DELETE")
        conn.execute("PRAGMA synchronous = FULL")
        conn.execute("BEGIN")
        conn.execute(create_table_sql(group.servo_count))
        columns = ", ".join(["Time"] + [f"Servo{k}" for k in range(1, group.servo_count + 1)])
        marks = ", ".join("?" * (group.servo_count + 1))
        conn.executemany(
            f"INSERT INTO {TABLE_NAME} ({columns}) VALUES ({marks})",
            ((f.duration_ms, *f.positions_pulses) for f in group.frames),
        )
        conn.execute("COMMIT")


__all__ = [
    "DURATION_MAX_MS",
    "DURATION_MIN_MS",
    "MAX_SERVOS",
    "TABLE_NAME",
    "ActionFrame",
    "ActionGroup",
    "create_table_sql",
    "frame_from_targets",
    "frame_targets",
    "read_d6a",
    "write_d6a",
]
