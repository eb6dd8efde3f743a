"""Parameter types: servo IDs, angles, times and lists checked while argv is parsed, so
that bad input fails before any port is opened and nothing reaches the bus (re-exported
by busarm.cli.common)."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import click

from busarm.errors import ConfigError
from busarm.protocol import MAX_SERVO_ID, check_servo_id
from busarm.protocol.lx_units import MOVE_TIME_MAX_MS, POSITION_MAX_DEG, POSITION_MIN_DEG
from busarm.units import check_range, parse_ids, range_text

if TYPE_CHECKING:
    from busarm.base.odometry import Pose2D

__all__ = [
    "ANGLE",
    "ID_LIST",
    "MOVE_TIME",
    "NUMBER_ARGS",
    "POSE",
    "SERVO_ID",
    "SPEED",
    "AngleType",
    "CheckedType",
    "IdListType",
    "PoseType",
    "RangeType",
    "ServoIdType",
    "angle_list",
    "parse_float_list",
    "parse_int",
    "parse_pose",
]


NUMBER_ARGS = {"ignore_unknown_options": True}
"""Context settings that let negative numbers through as arguments (``arm fk 0 -90 0``)."""


class CheckedType(click.ParamType):
    """A parameter type whose converter raises ConfigError; shown as a usage error."""

    def parse(self, text: str) -> Any:
        raise NotImplementedError

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> Any:
        if not isinstance(value, str):
            return value
        try:
            return self.parse(value)
        except ConfigError as exc:
            self.fail(str(exc), param, ctx)


def _number(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ConfigError(f"{text!r} is not a number ({what})") from None
    if not math.isfinite(value):
        raise ConfigError(f"{text!r} is not a finite number ({what})")
    return value


def parse_float_list(text: str, what: str) -> list[float]:
    """Finite numbers separated by commas or spaces (``0,60,0`` or ``"0 60 0"``: lists are
    written either way everywhere); ConfigError naming ``what`` and the bad one."""
    return [_number(t, what) for t in re.split(r"[,\s]+", text.strip())]


def parse_pose(text: str, option: str) -> Pose2D:
    """``X,Y,YAW`` (m, m, deg) -> a Pose2D; ConfigError naming ``option`` otherwise."""
    from busarm.base.odometry import Pose2D

    values = parse_float_list(text, f"{option} X,Y,YAW (m, m, deg)")
    if len(values) != 3:
        raise ConfigError(f"{option} {text!r}: expected X,Y,YAW (m, m, deg), e.g. 0.5,-1.2,90")
    return Pose2D(values[0], values[1], math.radians(values[2]))


def angle_list(kind: RangeType) -> Callable[[click.Context, click.Parameter, tuple[str, ...]],
                                            tuple[float, ...]]:
    """A callback for an ``nargs=-1`` argument of angles: ``0 60 0`` or ``0,60,0``, each
    checked as ``kind``."""
    def convert(ctx: click.Context, param: click.Parameter,
                values: tuple[str, ...]) -> tuple[float, ...]:
        text = " ".join(values).strip()
        return tuple(kind.parse(str(v)) for v in parse_float_list(text, kind.name)) if text \
            else ()
    return convert


def parse_int(text: str, what: str) -> int:
    """An integer from decimal (or 0x/0b/0o) text; ConfigError naming ``what`` if not."""
    t = text.strip()
    try:
        return int(t, 0) if t[:2].lower() in ("0x", "0b", "0o") else int(t)
    except ValueError:
        raise ConfigError(f"{text!r} is not an integer ({what})") from None


class ServoIdType(CheckedType):
    """A servo ID, 0..253 (or 254, broadcast, where allowed)."""

    name = "id"

    def __init__(self, allow_broadcast: bool = False) -> None:
        self.allow_broadcast = allow_broadcast

    def get_metavar(self, param: click.Parameter) -> str:
        return "ID"

    def parse(self, text: str) -> int:
        hi = MAX_SERVO_ID + 1 if self.allow_broadcast else MAX_SERVO_ID
        return check_servo_id(parse_int(text, f"servo ID 0..{hi}"),
                              allow_broadcast=self.allow_broadcast)


class AngleType(CheckedType):
    """An angle in degrees from the servo's mid-point, within ``lo..hi``."""

    name = "deg"

    def __init__(self, lo: float = POSITION_MIN_DEG, hi: float = POSITION_MAX_DEG) -> None:
        self.lo, self.hi = lo, hi

    def parse(self, text: str) -> float:
        value = _number(text, f"an angle in deg, {range_text(self.lo, self.hi)}")
        return check_range("angle", value, self.lo, self.hi, "deg")


class RangeType(CheckedType):
    """A number within ``lo..hi`` of the given unit."""

    def __init__(self, name: str, lo: float, hi: float, unit: str) -> None:
        self.name, self.lo, self.hi, self.unit = name, lo, hi, unit

    def get_metavar(self, param: click.Parameter) -> str | None:
        if isinstance(param, click.Argument):
            return None  # an argument is shown by its own name (X Y Z)
        from busarm.cli.common import unit_metavar  # common re-exports cli.help_style

        # One word (it is one argument): its unit, as for every number option.
        return unit_metavar(self.unit) or self.name.upper().replace(" ", "_")

    def parse(self, text: str) -> float:
        value = _number(text, f"{self.name} in {self.unit}, {range_text(self.lo, self.hi)}")
        return check_range(self.name, value, self.lo, self.hi, self.unit)


class IdListType(CheckedType):
    """Servo IDs such as ``1,2,3`` or ``0-20,100``."""

    name = "ids"

    def parse(self, text: str) -> list[int]:
        return list(dict.fromkeys(parse_ids(text)))


class PoseType(CheckedType):
    """Targets such as ``1=0,2=-30,3=45`` (servo ID = angle in deg)."""

    name = "pose"

    def parse(self, text: str) -> dict[int, float]:
        pose: dict[int, float] = {}
        for part in text.split(","):
            if not part.strip():
                continue
            sid_text, sep, angle_text = part.partition("=")
            if not sep:
                raise ConfigError(f"pose {text!r}: {part.strip()!r} is not ID=ANGLE")
            sid = ServoIdType().parse(sid_text)
            if sid in pose:
                raise ConfigError(f"pose {text!r}: servo {sid} is given twice")
            pose[sid] = AngleType().parse(angle_text)
        if not pose:
            raise ConfigError(f"pose {text!r}: no ID=ANGLE given")
        return pose


SERVO_ID = ServoIdType()
ANGLE = AngleType()
MOVE_TIME = RangeType("time", 0.0, MOVE_TIME_MAX_MS / 1000.0, "s")
SPEED = RangeType("speed", 0.1, 10000.0, "deg/s")
ID_LIST = IdListType()
POSE = PoseType()
