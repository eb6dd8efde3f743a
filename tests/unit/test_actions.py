"""Action groups: the vendor's .d6a files (SQLite) read, written and checked.

The vendor samples in tests/data/vendor were written by the vendor's own software;
files we write are checked with plain sqlite3 against them, not only with read_d6a.
"""

from __future__ import annotations

import contextlib
import resource
import signal
import sqlite3
from collections.abc import Iterator, Sequence
from pathlib import Path

import pytest

from busarm.arm.actions import (
    MAX_SERVOS,
    ActionFrame,
    ActionGroup,
    create_table_sql,
    frame_from_targets,
    frame_targets,
    read_d6a,
    write_d6a,
)
from busarm.errors import ConfigError

VENDOR = Path(__file__).resolve().parent.parent / "data" / "vendor"
ACTION_1 = VENDOR / "arm_action_1.d6a"
CALIBRATION_POSE = VENDOR / "arm_calibration_pose.d6a"
JETAUTO_PRO_COLUMNS = (1, 2, 3, 4, 5, 10)
"""Columns Servo1..Servo6 drive these servo IDs on the JetAuto Pro arm."""


def _master(path: Path) -> list[tuple[str, str, str, str | None]]:
    with sqlite3.connect(path) as conn:
        rows = conn.execute(
            "SELECT type, name, tbl_name, sql FROM sqlite_master ORDER BY name"
        ).fetchall()
    conn.close()
    return rows


def _rows(path: Path, table: str) -> list[tuple[object, ...]]:
    conn = sqlite3.connect(path)
    try:
        return conn.execute(f"SELECT * FROM {table} ORDER BY 1").fetchall()
    finally:
        conn.close()


def _make_db(path: Path, *statements: str) -> Path:
    conn = sqlite3.connect(path)
    try:
        for sql in statements:
            conn.execute(sql)
        conn.commit()
    finally:
        conn.close()
    return path


def _vendor_like(path: Path, rows: Sequence[Sequence[object]], servo_count: int = 6) -> Path:
    """A file with the vendor's schema and the given (Time, Servo1..) rows, no checks."""
    marks = ", ".join("?" * (servo_count + 1))
    cols = ", ".join(["Time"] + [f"Servo{k}" for k in range(1, servo_count + 1)])
    conn = sqlite3.connect(path)
    try:
        conn.execute(create_table_sql(servo_count))
        conn.executemany(f"INSERT INTO ActionGroup ({cols}) VALUES ({marks})", rows)
        conn.commit()
    finally:
        conn.close()
    return path


SIX = (500, 500, 500, 500, 500, 500)
GROUP = ActionGroup.from_rows([(1000, (500, 788, 500, 500, 500, 500)), (250, SIX), (0, SIX)])


# --- the vendor's samples ---------------------------------------------------------------


def test_reads_vendor_action_1_exactly() -> None:
    group = read_d6a(ACTION_1)
    assert group == ActionGroup((
        ActionFrame(1000, (500, 788, 500, 500, 500, 500)),
        ActionFrame(1000, (500, 500, 500, 500, 500, 500)),
    ))
    assert group.servo_count == 6
    assert group.total_duration_ms == 2000


def test_reads_vendor_calibration_pose_exactly() -> None:
    group = read_d6a(str(CALIBRATION_POSE))  # a str path works too
    assert group.frames == (ActionFrame(2000, (600, 501, 82, 575, 294, 500)),)


def test_reading_never_modifies_the_file() -> None:
    before = ACTION_1.read_bytes(), ACTION_1.stat().st_mtime_ns
    read_d6a(ACTION_1)
    assert (ACTION_1.read_bytes(), ACTION_1.stat().st_mtime_ns) == before
    # No journal or WAL file left beside the vendor's files.
    assert sorted(p.name for p in VENDOR.iterdir()) == sorted(
        [ACTION_1.name, CALIBRATION_POSE.name, "lab_config.yaml"])


def test_our_schema_text_is_the_vendors() -> None:
    vendor_sql = {name: sql for _, name, _, sql in _master(ACTION_1)}
    assert create_table_sql(6) == vendor_sql["ActionGroup"]


@pytest.mark.parametrize("sample", [ACTION_1, CALIBRATION_POSE], ids=lambda p: p.stem)
def test_rewritten_sample_matches_the_vendor_file_in_plain_sqlite(
    sample: Path, tmp_path: Path
) -> None:
    out = tmp_path / sample.name
    write_d6a(out, read_d6a(sample))
    # Same tables, autoindex and sqlite_sequence, with the same SQL text.
    assert _master(out) == _master(sample)
    # Same rows, Index included, and the same AUTOINCREMENT counter.
    assert _rows(out, "ActionGroup") == _rows(sample, "ActionGroup")
    assert _rows(out, "sqlite_sequence") == _rows(sample, "sqlite_sequence")
    assert read_d6a(out) == read_d6a(sample)


def test_written_file_plays_like_the_vendor_expects(tmp_path: Path) -> None:
    out = tmp_path / "three.d6a"
    write_d6a(out, GROUP)
    assert _rows(out, "ActionGroup") == [
        (1, 1000, 500, 788, 500, 500, 500, 500),
        (2, 250, *SIX),
        (3, 0, *SIX),
    ]
    assert _rows(out, "sqlite_sequence") == [("ActionGroup", 3)]
    assert read_d6a(out) == GROUP
    with out.open("rb") as f:
        assert f.read(16) == b"SQLite format 3\x00"


def test_any_servo_count_round_trips(tmp_path: Path) -> None:
    for count in (1, 2, 7, MAX_SERVOS):
        group = ActionGroup.from_rows([(30000, range(count)), (0, [1000] * count)])
        write_d6a(tmp_path / "g.d6a", group)
        assert read_d6a(tmp_path / "g.d6a") == group


def test_frames_are_ordered_by_index_not_by_storage(tmp_path: Path) -> None:
    path = _make_db(
        tmp_path / "shuffled.d6a",
        create_table_sql(1),
        "INSERT INTO ActionGroup ([Index], Time, Servo1) VALUES (9, 300, 3)",
        "INSERT INTO ActionGroup ([Index], Time, Servo1) VALUES (2, 100, 1)",
        "INSERT INTO ActionGroup ([Index], Time, Servo1) VALUES (5, 200, 2)",
    )
    assert read_d6a(path) == ActionGroup.from_rows([(100, [1]), (200, [2]), (300, [3])])


def test_columns_in_another_order_are_found_by_name(tmp_path: Path) -> None:
    path = _make_db(
        tmp_path / "reordered.d6a",
        "CREATE TABLE ActionGroup(Servo2 INT, Time INT, [Index] INTEGER PRIMARY KEY, Servo1 INT)",
        "INSERT INTO ActionGroup (Servo2, Time, Servo1) VALUES (20, 100, 10)",
    )
    assert read_d6a(path).frames == (ActionFrame(100, (10, 20)),)


@pytest.mark.parametrize("name", ["a?b.d6a", "a#b.d6a", "100%.d6a", "sp ace é.d6a"])
def test_awkward_file_names(name: str, tmp_path: Path) -> None:
    path = tmp_path / "dir?#%" / name
    path.parent.mkdir()
    write_d6a(path, GROUP)
    assert read_d6a(path) == GROUP
    assert sorted(p.name for p in path.parent.iterdir()) == [name]


def test_relative_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    write_d6a("rel.d6a", GROUP)
    assert read_d6a("rel.d6a") == GROUP
    assert (tmp_path / "rel.d6a").is_file()


# --- atomic writes ----------------------------------------------------------------------


def _old_file(tmp_path: Path) -> tuple[Path, bytes]:
    path = tmp_path / "keep.d6a"
    write_d6a(path, read_d6a(CALIBRATION_POSE))
    return path, path.read_bytes()


def test_overwrite_replaces_the_file_whole(tmp_path: Path) -> None:
    path, old = _old_file(tmp_path)
    old_inode = path.stat().st_ino
    with path.open("rb") as old_handle:
        write_d6a(path, GROUP)
        # The old file was not written in place: an open handle still sees the old data.
        assert old_handle.read() == old
    assert path.stat().st_ino != old_inode
    assert read_d6a(path) == GROUP
    assert [p.name for p in tmp_path.iterdir()] == ["keep.d6a"]


def test_overwrite_keeps_the_file_mode(tmp_path: Path) -> None:
    path, _ = _old_file(tmp_path)
    assert path.stat().st_mode & 0o777 == 0o644  # not mkstemp's private 0600
    path.chmod(0o640)
    write_d6a(path, GROUP)
    assert path.stat().st_mode & 0o777 == 0o640


def test_invalid_group_fails_before_the_file_is_touched(tmp_path: Path) -> None:
    path, old = _old_file(tmp_path)
    with pytest.raises(ConfigError, match=r"frame 2: Servo3 = 1001 pulses is out of range"):
        write_d6a(path, ActionGroup.from_rows([(100, SIX), (100, (1, 2, 1001, 4, 5, 6))]))
    with pytest.raises(ConfigError, match="not an ActionGroup"):
        write_d6a(path, [ActionFrame(100, SIX)])  # type: ignore[arg-type]
    assert path.read_bytes() == old
    assert [p.name for p in tmp_path.iterdir()] == ["keep.d6a"]


@contextlib.contextmanager
def _file_size_limit(limit: int) -> Iterator[None]:
    """Limit the size of files this process may write (RLIMIT_FSIZE), like a full disk."""
    old_limits = resource.getrlimit(resource.RLIMIT_FSIZE)
    old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # EFBIG instead of a kill
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, old_limits[1]))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, old_limits)
        signal.signal(signal.SIGXFSZ, old_handler)


def test_a_write_failing_midway_leaves_the_old_file(tmp_path: Path) -> None:
    path, old = _old_file(tmp_path)
    big = ActionGroup.from_rows([(1000, [500] * MAX_SERVOS)] * 400)  # far more than 8 KiB
    with (
        _file_size_limit(8192),
        pytest.raises(ConfigError, match=r"cannot write action group .*keep\.d6a"),
    ):
        write_d6a(path, big)
    assert path.read_bytes() == old
    assert [p.name for p in tmp_path.iterdir()] == ["keep.d6a"]  # no temporary files left
    write_d6a(path, big)  # without the limit it works
    assert read_d6a(path) == big


def test_target_that_is_a_directory_is_left_alone(tmp_path: Path) -> None:
    target = tmp_path / "taken.d6a"
    target.mkdir()
    (target / "inside").write_text("x")
    with pytest.raises(ConfigError, match=r"cannot write action group .*taken\.d6a"):
        write_d6a(target, GROUP)
    assert (target / "inside").read_text() == "x"
    assert [p.name for p in tmp_path.iterdir()] == ["taken.d6a"]


def test_missing_directory(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"cannot write action group .*nowhere"):
        write_d6a(tmp_path / "nowhere" / "g.d6a", GROUP)


# --- bad files --------------------------------------------------------------------------


def _bad(path: Path, *patterns: str) -> str:
    with pytest.raises(ConfigError) as info:
        read_d6a(path)
    message = str(info.value)
    assert str(path) in message, message
    for pattern in patterns:
        assert pattern in message, message
    assert "\n" not in message
    return message


def test_missing_file(tmp_path: Path) -> None:
    _bad(tmp_path / "absent.d6a", "cannot read action group", "No such file")
    assert not (tmp_path / "absent.d6a").exists()  # read-only: never created


def test_directory(tmp_path: Path) -> None:
    _bad(tmp_path, "not a regular file")


def test_garbage_bytes(tmp_path: Path) -> None:
    path = tmp_path / "garbage.d6a"
    path.write_bytes(bytes(range(256)) * 64)
    _bad(path, "is not an SQLite database")


def test_text_file(tmp_path: Path) -> None:
    path = tmp_path / "notes.d6a"
    path.write_text("Time,Servo1\n1000,500\n")
    _bad(path, "is not an SQLite database")


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.d6a"
    path.touch()
    _bad(path, "is empty (0 bytes)")


def test_truncated_file(tmp_path: Path) -> None:
    path = tmp_path / "cut.d6a"
    path.write_bytes(ACTION_1.read_bytes()[:100])
    _bad(path, "action group")


def test_database_without_the_table(tmp_path: Path) -> None:
    path = _make_db(tmp_path / "other.d6a", "CREATE TABLE Poses(a INT)")
    _bad(path, "has no ActionGroup table", "tables: Poses")
    path = _make_db(tmp_path / "bare.d6a", "PRAGMA user_version = 3")
    _bad(path, "has no ActionGroup table", "tables: none")


@pytest.mark.parametrize(
    ("columns", "problem"),
    [
        ("[Index] INTEGER PRIMARY KEY, Time INT", "no Servo<k> columns"),
        ("[Index] INTEGER PRIMARY KEY, Servo1 INT", "no Time column"),
        ("Time INT, Servo1 INT", "no Index column"),
        ("[Index] INTEGER PRIMARY KEY, Time INT, Servo1 INT, Servo3 INT",
         "Servo1, Servo3 are not Servo1..ServoN without gaps"),
        ("[Index] INTEGER PRIMARY KEY, Time INT, Servo2 INT", "are not Servo1..ServoN"),
        ("[Index] INTEGER PRIMARY KEY, Time INT, Servo1 INT, Speed INT",
         "unexpected column(s) Speed"),
        ("[Index] INTEGER PRIMARY KEY, Time INT, Servo0 INT", "unexpected column(s) Servo0"),
        ("[Index] INTEGER PRIMARY KEY, Time INT, "
         + ", ".join(f"Servo{k} INT" for k in range(1, MAX_SERVOS + 2)),
         f"{MAX_SERVOS + 1} servo columns; at most {MAX_SERVOS}"),
    ],
)
def test_wrong_columns(columns: str, problem: str, tmp_path: Path) -> None:
    path = _make_db(tmp_path / "cols.d6a", f"CREATE TABLE ActionGroup({columns})")
    _bad(path, "wrong columns", problem)


def test_no_rows(tmp_path: Path) -> None:
    _bad(_vendor_like(tmp_path / "none.d6a", []), "has no rows")


@pytest.mark.parametrize(
    ("row", "problem"),
    [
        ((1000, 500, 500, 1001, 500, 500, 500), "Servo3 = 1001 pulses is out of range 0..1000"),
        ((1000, -1, 500, 500, 500, 500, 500), "Servo1 = -1 pulses is out of range 0..1000"),
        ((-5, 500, 500, 500, 500, 500, 500), "Time (duration_ms) = -5 ms is out of range 0..30000"),
        ((30001, *SIX), "Time (duration_ms) = 30001 ms is out of range 0..30000"),
        ((1000, 500, 500, 500, 500, 500, None), "Servo6 is NULL"),
        ((None, *SIX), "Time is NULL"),
        ((1000, 500, 500.5, 500, 500, 500, 500),
         "Servo2 must be an integer 0..1000 pulses, got 500.5"),
        ((1000, 500, 500, "abc", 500, 500, 500),
         "Servo3 must be an integer 0..1000 pulses, got 'abc'"),
        ((1000, 500, 500, 500, b"\x01", 500, 500), "Servo4 must be an integer"),
    ],
)
def test_bad_cells_name_frame_column_and_value(
    row: tuple[object, ...], problem: str, tmp_path: Path
) -> None:
    path = _vendor_like(tmp_path / "cells.d6a", [(1000, *SIX), row])
    _bad(path, "frame 2 (Index 2)", problem)


def test_integer_text_is_stored_as_integer_by_sqlite(tmp_path: Path) -> None:
    # INT affinity turns '700' and 700.0 into integers, as the vendor's reader sees them.
    path = _vendor_like(tmp_path / "aff.d6a", [("700", "1", 2.0, 3, 4, 5, 6)])
    assert read_d6a(path).frames == (ActionFrame(700, (1, 2, 3, 4, 5, 6)),)


# --- the data classes -------------------------------------------------------------------


def test_frame_validation_messages() -> None:
    with pytest.raises(ConfigError, match=r"Servo2 = 1001 pulses is out of range 0\.\.1000 pulses"):
        ActionFrame(100, (0, 1001))
    with pytest.raises(ConfigError, match=r"Time \(duration_ms\) = 30001 ms is out of range"):
        ActionFrame(30001, (0,))
    with pytest.raises(ConfigError, match="Servo1 must be an integer 0..1000 pulses, got true"):
        ActionFrame(100, (True,))
    with pytest.raises(ConfigError, match="must be an integer 0..30000 ms, got 1.5"):
        ActionFrame(1.5, (0,))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"0 servo positions; allowed 1\.\.32"):
        ActionFrame(100, ())
    with pytest.raises(ConfigError, match=r"33 servo positions; allowed 1\.\.32"):
        ActionFrame(100, (500,) * 33)
    with pytest.raises(ConfigError, match="must be a sequence of integers"):
        ActionFrame(100, 500)  # type: ignore[arg-type]


def test_frame_accepts_any_sequence_and_stores_a_tuple() -> None:
    frame = ActionFrame(100, [1, 2, 3])  # type: ignore[arg-type]
    assert frame.positions_pulses == (1, 2, 3)
    assert frame == ActionFrame(100, (1, 2, 3))
    assert hash(frame) == hash(ActionFrame(100, (1, 2, 3)))
    assert ActionFrame(0, (0,)).duration_ms == 0
    assert ActionFrame(30000, (1000,)).positions_pulses == (1000,)


def test_group_validation_messages() -> None:
    with pytest.raises(ConfigError, match="at least one frame"):
        ActionGroup(())
    with pytest.raises(
        ConfigError, match="frame 3 has 2 servo positions but frame 1 has 3; every frame"
    ):
        ActionGroup.from_rows([(1, (1, 2, 3)), (1, (1, 2, 3)), (1, (1, 2))])
    with pytest.raises(ConfigError, match="frame 2 is not an ActionFrame"):
        ActionGroup((ActionFrame(1, (1,)), (1, (1,))))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"frame 2: Time \(duration_ms\) = -1 ms"):
        ActionGroup.from_rows([(1, (1,)), (-1, (1,))])
    group = ActionGroup([ActionFrame(1, (1,))])  # type: ignore[arg-type]
    assert group.frames == (ActionFrame(1, (1,)),)


def test_frames_are_immutable() -> None:
    import dataclasses

    with pytest.raises(dataclasses.FrozenInstanceError):
        GROUP.frames[0].duration_ms = 5  # type: ignore[misc]


# --- columns and servo IDs --------------------------------------------------------------


def test_frame_targets_pair_columns_with_servo_ids() -> None:
    frame = read_d6a(CALIBRATION_POSE).frames[0]
    assert frame_targets(frame, JETAUTO_PRO_COLUMNS) == {
        1: 600, 2: 501, 3: 82, 4: 575, 5: 294, 10: 500,
    }
    group = read_d6a(ACTION_1)
    assert group.targets(JETAUTO_PRO_COLUMNS) == (
        {1: 500, 2: 788, 3: 500, 4: 500, 5: 500, 10: 500},
        {1: 500, 2: 500, 3: 500, 4: 500, 5: 500, 10: 500},
    )
    assert group.check_servo_ids([1, 2, 3, 4, 5, 10]) == JETAUTO_PRO_COLUMNS


def test_frame_from_targets_inverts_frame_targets() -> None:
    targets = {10: 500, 1: 600, 2: 501, 3: 82, 4: 575, 5: 294}  # any dict order
    frame = frame_from_targets(2000, targets, JETAUTO_PRO_COLUMNS)
    assert frame == read_d6a(CALIBRATION_POSE).frames[0]
    assert frame_targets(frame, JETAUTO_PRO_COLUMNS) == targets


def test_bad_servo_id_mappings() -> None:
    frame = ActionFrame(100, SIX)
    with pytest.raises(ConfigError, match=r"5 servo IDs .* for 6 columns \(Servo1\.\.Servo6\)"):
        frame_targets(frame, (1, 2, 3, 4, 5))
    with pytest.raises(ConfigError, match=r"repeat 2:"):
        frame_targets(frame, (1, 2, 2, 4, 5, 10))
    with pytest.raises(ConfigError, match="servo ID 254 is out of range 0..253"):
        frame_targets(frame, (1, 2, 3, 4, 5, 254))
    with pytest.raises(ConfigError, match="must be a sequence of servo IDs"):
        frame_targets(frame, "123456")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"missing 10; not a column 6$"):
        frame_from_targets(100, {1: 1, 2: 2, 3: 3, 4: 4, 5: 5, 6: 6}, JETAUTO_PRO_COLUMNS)
    with pytest.raises(ConfigError, match="Servo6 = 1001 pulses"):
        frame_from_targets(100, {1: 1, 2: 2, 3: 3, 4: 4, 5: 5, 10: 1001}, JETAUTO_PRO_COLUMNS)


def test_create_table_sql_bounds() -> None:
    assert "Servo32 INT)" in create_table_sql(32)
    with pytest.raises(ConfigError, match="servo_count = 33"):
        create_table_sql(33)
    with pytest.raises(ConfigError, match="servo_count = 0"):
        create_table_sql(0)
