"""Power-off storage: atomic JSON state files and servos rebuilt from them."""

from __future__ import annotations

import contextlib
import json
import os
import random
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from busarm.errors import ConfigError
from busarm.protocol import (
    AlarmFlag,
    AngleOffsetReply,
    Command,
    LedErrorReply,
    LoadReply,
    ModeReply,
    PositionReply,
    Request,
    ServoMode,
)
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import ServoParams
from busarm.sim.storage import (
    FORMAT_NAME,
    FORMAT_VERSION,
    load_state,
    record_from_servo,
    save_state,
    servo_from_record,
)

C = Command


def _records(n: int, base: float) -> list[dict[str, float]]:
    return [
        {**SimServo(i % 254).stored_fields(), "position_pulses": base + i * 0.5}
        for i in range(n)
    ]


def test_missing_file_loads_as_none(tmp_path: Path) -> None:
    assert load_state(tmp_path / "absent.json") is None


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "servos.json"
    records = _records(6, 100.25)
    save_state(path, records)
    assert load_state(path) == records
    data = json.loads(path.read_text())
    assert data["format"] == FORMAT_NAME and data["version"] == FORMAT_VERSION
    # Saving again replaces the file; no temporary files are left behind.
    save_state(path, records[:2])
    assert load_state(path) == records[:2]
    assert [p.name for p in tmp_path.iterdir()] == ["servos.json"]


def test_save_keeps_the_file_mode(tmp_path: Path) -> None:
    path = tmp_path / "servos.json"
    save_state(path, [])
    assert path.stat().st_mode & 0o777 == 0o644  # not mkstemp's private 0600
    path.chmod(0o640)
    save_state(path, _records(1, 0.0))
    assert path.stat().st_mode & 0o777 == 0o640


def test_servo_round_trip_keeps_stored_fields_and_drops_volatile_state(tmp_path: Path) -> None:
    s = SimServo(1)

    def send(command: Command, *args: int) -> None:
        s.handle(Request(s.servo_id, command, args), 1.0)  # at 1.0 s or the latest advance

    send(C.ID_WRITE, 4)
    send(C.ANGLE_LIMIT_WRITE, 100, 900)
    send(C.VIN_LIMIT_WRITE, 7000, 12000)
    send(C.TEMP_MAX_LIMIT_WRITE, 75)
    send(C.LED_CTRL_WRITE, 1)
    send(C.ANGLE_OFFSET_ADJUST, 30)
    send(C.ANGLE_OFFSET_WRITE)
    send(C.MOVE_TIME_WRITE, 600, 0)  # horn to 630 physically
    s.advance(2.0)
    send(C.ANGLE_OFFSET_ADJUST, -10)  # adjusted but never written: lost at power-off
    s.advance(3.0)  # the horn turns to keep logical 600
    send(C.LED_ERROR_WRITE, 2)
    send(C.OR_MOTOR_MODE_WRITE, 1, 0, 0)
    assert s.is_loaded
    physical = s.physical_pulses
    assert physical == pytest.approx(590.0)  # logical 600 kept, with the offset -10

    path = tmp_path / "servos.json"
    save_state(path, [record_from_servo(s)])
    loaded = load_state(path)
    assert loaded is not None
    t = servo_from_record(loaded[0], now=10.0)

    assert t.servo_id == 4
    assert t.stored_fields() == s.stored_fields()
    assert t.stored_fields()["offset_pulses"] == 30
    assert t.physical_pulses == pytest.approx(physical)  # the horn stayed where it was
    assert t.handle(Request(4, C.ANGLE_OFFSET_READ), 10.0) == AngleOffsetReply(30)
    assert t.handle(Request(4, C.POS_READ), 10.0) == PositionReply(560)  # 590 - 30
    assert t.handle(Request(4, C.OR_MOTOR_MODE_READ), 10.0) == ModeReply(ServoMode.POSITION, 0)
    assert t.handle(Request(4, C.LOAD_OR_UNLOAD_READ), 10.0) == LoadReply(False)
    assert t.handle(Request(4, C.LED_ERROR_READ), 10.0) == LedErrorReply(AlarmFlag(7))
    assert t.temperature_c == ServoParams().ambient_c


def test_servo_from_record_needs_a_position() -> None:
    with pytest.raises(ConfigError, match="position_pulses"):
        servo_from_record(SimServo(1).stored_fields())


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b'{"format": "busarm-sim-servos", "version": 1, "serv', "corrupt"),
        (b"", "corrupt"),
        (b"\xff\xfe\x00", "corrupt"),
        (b"[1, 2]", "not a busarm-sim-servos file"),
        (b'{"format": "busarm-sim-servos", "version": 99, "servos": []}', "version 99"),
        (b'{"format": "busarm-sim-servos", "version": 1, "servos": {}}', "must be a list"),
        (b'{"format": "busarm-sim-servos", "version": 1, "servos": [{"id": "x"}]}', "id"),
        (b'{"format": "busarm-sim-servos", "version": 1, "servos": [3]}', "object"),
    ],
)
def test_bad_files_raise_config_error_naming_the_file(
    tmp_path: Path, content: bytes, match: str
) -> None:
    path = tmp_path / "state.json"
    path.write_bytes(content)
    with pytest.raises(ConfigError, match=match) as info:
        load_state(path)
    assert str(path) in str(info.value)


def test_a_truncated_file_is_reported_not_half_read(tmp_path: Path) -> None:
    path = tmp_path / "state.json"
    save_state(path, _records(3, 500.0))
    full = path.read_bytes()
    for cut in (1, len(full) // 2, len(full) - 3):
        path.write_bytes(full[:cut])
        with pytest.raises(ConfigError, match="state.json"):
            load_state(path)


@pytest.mark.parametrize(
    "record",
    [{"id": float("nan")}, {"id": True}, {"id": "1"}, {1: 2}],
)
def test_save_rejects_records_that_are_not_numbers(tmp_path: Path, record: object) -> None:
    path = tmp_path / "state.json"
    with pytest.raises(ConfigError):
        save_state(path, [record])  # type: ignore[list-item]
    assert not path.exists()
    assert list(tmp_path.iterdir()) == []


def test_a_crash_before_the_rename_leaves_the_old_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "state.json"
    old = _records(4, 100.0)
    save_state(path, old)

    # A crash between writing the temporary file and renaming it: the process dies
    # (SystemExit stands in for the power going) after the new data is written.
    def die(src: object, dst: object) -> None:
        raise SystemExit("power gone")

    monkeypatch.setattr(os, "replace", die)
    with pytest.raises(SystemExit):
        save_state(path, _records(4, 900.0))
    monkeypatch.undo()
    assert load_state(path) == old

    # What a real crash leaves: a partly written temporary file beside the state file.
    (tmp_path / ".state.json.abc123.tmp").write_text('{"format": "busarm-sim-serv')
    assert load_state(path) == old


def test_a_failed_write_is_a_config_error_and_keeps_the_old_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "state.json"
    old = _records(2, 100.0)
    save_state(path, old)

    def disk_full(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    with pytest.raises(ConfigError, match="No space left") as info:
        save_state(path, _records(2, 900.0))
    assert str(path) in str(info.value)
    monkeypatch.undo()
    assert load_state(path) == old
    assert [p.name for p in tmp_path.iterdir()] == ["state.json"]


def test_save_into_a_missing_directory_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="nowhere"):
        save_state(tmp_path / "nowhere" / "state.json", [])


_SAVER = """
import json, sys
from pathlib import Path
from busarm.sim.storage import save_state

path, states = Path(sys.argv[1]), json.loads(Path(sys.argv[2]).read_text())
i = 0
while True:
    save_state(path, states[i % 2])
    if i == 0:
        print("saving", flush=True)
    i += 1
"""


def test_sigkill_during_repeated_saves_leaves_old_or_new_state(tmp_path: Path) -> None:
    state_a = _records(300, 100.0)
    state_b = _records(300, 700.0)
    states_file = tmp_path / "states.json"
    states_file.write_text(json.dumps([state_a, state_b]))
    path = tmp_path / "state.json"
    rng = random.Random(7)
    seen: set[float] = set()
    for _ in range(12):
        proc = subprocess.Popen(
            [sys.executable, "-c", _SAVER, str(path), str(states_file)],
            stdout=subprocess.PIPE, text=True,
        )
        try:
            assert proc.stdout is not None
            assert proc.stdout.readline().strip() == "saving"
            # Let it run a varying while, so the kill lands at varying points of a save.
            # Correctness does not depend on this delay; only the spread of cases does.
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=rng.uniform(0.0, 0.05))
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            if proc.stdout is not None:
                proc.stdout.close()
        assert proc.returncode == -signal.SIGKILL
        loaded = load_state(path)
        assert loaded in (state_a, state_b)
        assert loaded is not None
        seen.add(loaded[0]["position_pulses"])
    assert seen <= {100.0, 700.0}
