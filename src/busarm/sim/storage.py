"""Power-off storage of simulated servos: one JSON file, replaced atomically.

A real servo keeps its saved settings (``SimServo.stored_fields()``) in EEPROM, and
its horn stays where it was when the power went off. The simulator keeps both in one
file, one record per servo: the stored fields plus ``position_pulses``, the horn's
*physical* angle (``SimServo.physical_pulses``; POS_READ after power-on reports it
minus the saved offset). Volatile state (mode, torque, a current but unsaved offset,
the alarm mask, the temperature) is not kept, as on the real servo.

File layout::

    {"format": "busarm-sim-servos", "version": 1, "servos": [{"id": 1, ...}, ...]}

``save_state`` writes through ``busarm.fileio.atomic_path`` (temporary file, fsync,
rename, directory fsync), so a crash at any point leaves either the old file or the new
one, never a mix. A temporary file a crash leaves behind is ignored by ``load_state``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path

from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import ServoParams

FORMAT_NAME = "busarm-sim-servos"
FORMAT_VERSION = 1
POSITION_KEY = "position_pulses"
"""The record key of the horn's physical angle, beside the stored fields."""


def record_from_servo(servo: SimServo) -> dict[str, float]:
    """What survives a power-off: the stored fields and the horn's physical angle."""
    return {**servo.stored_fields(), POSITION_KEY: servo.physical_pulses}


def servo_from_record(
    record: Mapping[str, float], *, params: ServoParams | None = None, now: float = 0.0
) -> SimServo:
    """Power a servo on from a record of ``record_from_servo``/``load_state``."""
    if POSITION_KEY not in record:
        raise ConfigError(f"servo record {dict(record)!r} has no {POSITION_KEY}")
    stored = {k: v for k, v in record.items() if k != POSITION_KEY}
    return SimServo.from_stored(
        stored, params=params, position_pulses=float(record[POSITION_KEY]), now=now
    )


def _check_record(record: object, where: str) -> dict[str, float]:
    """A record as a fresh dict, or ConfigError saying what is wrong with it."""
    if not isinstance(record, Mapping):
        raise ConfigError(f"{where}: a servo record must be an object, got {record!r}")
    out: dict[str, float] = {}
    for key, value in record.items():
        if not isinstance(key, str):
            raise ConfigError(f"{where}: record key {key!r} is not a string")
        if (
            isinstance(value, bool) or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise ConfigError(f"{where}: {key} = {value!r} is not a finite number")
        out[key] = value
    return out


def save_state(path: Path, servos: Sequence[Mapping[str, float]]) -> None:
    """Write the servos' records to ``path`` atomically (old or new, never a mix).

    Raises ConfigError naming the file for a bad record or a failed write.
    """
    path = Path(path)
    records = [_check_record(r, f"saving {path}") for r in servos]
    text = json.dumps(
        {"format": FORMAT_NAME, "version": FORMAT_VERSION, "servos": records},
        indent=1, sort_keys=True, allow_nan=False,
    )
    write_text_atomic(path, text + "\n", "simulator state")


def load_state(path: Path) -> list[dict[str, float]] | None:
    """The records saved in ``path``; None if there is no such file.

    Raises ConfigError naming the file if it cannot be read, is not valid JSON, or is
    not this format and version.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise ConfigError(f"cannot read simulator state {path}: {exc}") from exc
    try:
        data = json.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"simulator state {path} is corrupt: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT_NAME:
        raise ConfigError(f"simulator state {path} is not a {FORMAT_NAME} file")
    if data.get("version") != FORMAT_VERSION:
        raise ConfigError(
            f"simulator state {path} has version {data.get('version')!r}; "
            f"this busarm reads version {FORMAT_VERSION}"
        )
    servos = data.get("servos")
    if not isinstance(servos, list):
        raise ConfigError(f"simulator state {path}: 'servos' must be a list")
    return [_check_record(r, f"simulator state {path}") for r in servos]


__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "POSITION_KEY",
    "load_state",
    "record_from_servo",
    "save_state",
    "servo_from_record",
]
