"""What every command shares: the global settings, parameter types, consoles.

Parameter types check values (IDs, angles, times) while argv is parsed, so bad
input fails before any port is opened and nothing reaches the bus.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, TypeVar

import click
from rich.console import Console

from busarm.bus.driver import DEFAULT_RETRIES, DEFAULT_TIMEOUT_MARGIN_S, ServoBus
from busarm.bus.transport import DEFAULT_BAUDRATE
from busarm.errors import BusTimeoutError, ConfigError, ProtocolError
from busarm.protocol import MAX_SERVO_ID, check_servo_id
from busarm.units import (
    MOVE_TIME_MAX_MS,
    POSITION_MAX_DEG,
    POSITION_MIN_DEG,
    check_range,
    parse_ids,
)

T = TypeVar("T")

NO_REPLY = "no reply"

SIM_NOTE = "note: no --port given: using the in-process simulated arm (sim)"
STOPPED = "all servos stopped (holding position)"
"""What the bus did on its way out of an error: MOVE_STOP to all (ServoBus.__exit__)."""


def servos_stopped(exc: BaseException) -> bool:
    """Whether ``exc`` (or what caused it) left a bus that sent the emergency stop."""
    seen: BaseException | None = exc
    while seen is not None:
        if getattr(seen, "busarm_servos_stopped", False):
            return True
        seen = seen.__cause__ or seen.__context__
    return False


@dataclass
class Settings:
    """The global options, and the consoles commands print to."""

    port: str = "sim"
    baudrate: int = DEFAULT_BAUDRATE
    echo: str = "auto"
    timeout_margin_ms: float = DEFAULT_TIMEOUT_MARGIN_S * 1000.0
    retries: int = DEFAULT_RETRIES
    out: Console = field(default_factory=Console)
    err: Console = field(default_factory=lambda: Console(stderr=True))
    port_given: bool = True
    """False when neither --port nor BUSARM_PORT was given (the default simulator)."""

    @contextmanager
    def open_bus(
        self, port: str | None = None, check_ids: Iterable[int] = (),
        check: Callable[[ServoBus, int], object] | None = None,
    ) -> Iterator[ServoBus]:
        """Open the bus on ``port`` (default: ``--port``): ``with settings.open_bus() as bus``.

        Each of ``check_ids`` must answer ``check(bus, sid)`` (default: ID_READ) before
        the body runs; if one does not (or ``check`` raises), the bus is closed with
        nothing written. An exception leaving the body stops every servo
        (ServoBus.__exit__), and is marked so that the error message says so.
        """
        if port is None and not self.port_given:
            self.err.print(SIM_NOTE, highlight=False, markup=False)
        bus = ServoBus.open(
            self.port if port is None else port,
            baudrate=self.baudrate,
            echo=self.echo,
            timeout_margin_s=self.timeout_margin_ms / 1000.0,
            retries=self.retries,
        )
        try:
            for sid in check_ids:
                try:
                    (check or _ping)(bus, sid)
                except BusTimeoutError:
                    raise BusTimeoutError(f"no servo answers at ID {sid}", servo_id=sid) from None
        except BaseException:
            bus.close()  # nothing was written: no emergency stop
            raise
        with bus:
            try:
                yield bus
            except BaseException as exc:
                exc.busarm_servos_stopped = True  # type: ignore[attr-defined]
                raise


def _ping(bus: ServoBus, sid: int) -> None:
    bus.read_id(sid)


pass_settings = click.make_pass_decorator(Settings, ensure=True)


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
    """Comma-separated finite numbers; ConfigError naming ``what`` and the bad one."""
    return [_number(t.strip(), what) for t in text.split(",")]


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
        value = _number(text, f"an angle in deg, {self.lo:g}..{self.hi:g}")
        check_range("angle", value, self.lo, self.hi, "deg")
        return value


class RangeType(CheckedType):
    """A number within ``lo..hi`` of the given unit."""

    def __init__(self, name: str, lo: float, hi: float, unit: str) -> None:
        self.name, self.lo, self.hi, self.unit = name, lo, hi, unit

    def parse(self, text: str) -> float:
        value = _number(text, f"{self.name} in {self.unit}, {self.lo:g}..{self.hi:g}")
        check_range(self.name, value, self.lo, self.hi, self.unit)
        return value


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


def try_read(read: Callable[[], T]) -> T | str:
    """``read()``, or ``"no reply"`` if the servo did not answer (or ``"bad reply"``)."""
    try:
        return read()
    except BusTimeoutError:
        return NO_REPLY
    except ProtocolError:
        return "bad reply"
