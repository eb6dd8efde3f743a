"""Properties of action groups and .d6a files (hypothesis).

The ranges here are the servo's (move time 0..30000 ms, position 0..1000 pulses,
IDs 0..253) and the format's (1..32 servo columns), written out rather than taken
from busarm, so the properties do not merely restate the implementation.
"""

from __future__ import annotations

import sqlite3
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.arm.actions import (
    ActionFrame,
    ActionGroup,
    frame_from_targets,
    frame_targets,
    read_d6a,
    write_d6a,
)
from busarm.errors import ConfigError

durations = st.integers(0, 30000)
positions = st.integers(0, 1000)


@st.composite
def groups(draw: st.DrawFn) -> ActionGroup:
    servo_count = draw(st.integers(1, 32))
    rows = draw(
        st.lists(
            st.tuples(durations, st.lists(positions, min_size=servo_count, max_size=servo_count)),
            min_size=1, max_size=12,
        )
    )
    return ActionGroup(tuple(ActionFrame(d, tuple(p)) for d, p in rows))


@pytest.fixture(scope="module")
def directory() -> Iterator[Path]:
    with tempfile.TemporaryDirectory(prefix="busarm-d6a-") as name:
        yield Path(name)


@settings(max_examples=60, deadline=None)
@given(group=groups())
def test_any_valid_group_round_trips_exactly(directory: Path, group: ActionGroup) -> None:
    path = directory / "group.d6a"  # reused: every example also overwrites the last one
    write_d6a(path, group)
    assert read_d6a(path) == group
    conn = sqlite3.connect(path)
    try:
        rows = conn.execute("SELECT * FROM ActionGroup ORDER BY [Index]").fetchall()
        sequence = conn.execute("SELECT name, seq FROM sqlite_sequence").fetchall()
    finally:
        conn.close()
    assert rows == [
        (i, f.duration_ms, *f.positions_pulses) for i, f in enumerate(group.frames, start=1)
    ]
    assert sequence == [("ActionGroup", len(group.frames))]
    assert sorted(p.name for p in directory.iterdir()) == ["group.d6a"]


@given(
    duration=st.one_of(st.integers(max_value=-1), st.integers(min_value=30001)),
    servo_count=st.integers(1, 32),
)
def test_durations_outside_the_move_time_range_are_refused(
    duration: int, servo_count: int
) -> None:
    with pytest.raises(ConfigError, match=rf"Time \(duration_ms\) = {duration} ms"):
        ActionFrame(duration, (500,) * servo_count)


@given(
    data=st.data(),
    servo_count=st.integers(1, 32),
    bad=st.one_of(st.integers(max_value=-1), st.integers(min_value=1001)),
)
def test_positions_outside_0_1000_are_refused_naming_the_column(
    data: st.DataObject, servo_count: int, bad: int
) -> None:
    column = data.draw(st.integers(1, servo_count))
    values = [500] * servo_count
    values[column - 1] = bad
    with pytest.raises(ConfigError, match=rf"Servo{column} = {bad} pulses"):
        ActionFrame(100, tuple(values))
    frame_number = data.draw(st.integers(1, 5))
    rows = [(100, [500] * servo_count)] * (frame_number - 1) + [(100, values)]
    with pytest.raises(ConfigError, match=rf"frame {frame_number}: Servo{column} = {bad}"):
        ActionGroup.from_rows(rows)


@given(
    ids=st.lists(st.integers(0, 253), min_size=1, max_size=32, unique=True),
    data=st.data(),
)
def test_targets_and_frames_are_inverse(ids: list[int], data: st.DataObject) -> None:
    frame = ActionFrame(
        data.draw(durations),
        tuple(data.draw(st.lists(positions, min_size=len(ids), max_size=len(ids)))),
    )
    targets = frame_targets(frame, ids)
    assert list(targets) == ids
    assert frame_from_targets(frame.duration_ms, targets, ids) == frame
