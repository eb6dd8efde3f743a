"""What a command that ends early says about the servos: only what is true, read back.

A bus that wrote nothing leaves the servos as they were (a ``ServoPort`` then sends no
stop on its way out), so the message says nothing about stopping. A bus that wrote
something is stopped (MOVE_STOP), then each servo's torque is read back: with torque on
it holds its position, with torque off it is limp (it was never holding), and one that
does not answer is named as such.
"""

from __future__ import annotations

import functools
import signal
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import AbstractContextManager, contextmanager
from types import FrameType
from typing import Any, TypeVar, cast

from busarm.bus.lx_port import LxServoPort
from busarm.bus.servo_port import ServoPort
from busarm.errors import BusArmError
from busarm.protocol import ServoMode

__all__ = [
    "DONE_WITH_THEM",
    "HOLDING",
    "LIMP",
    "NOTHING_WRITTEN",
    "SILENT",
    "STOP_SENT",
    "TERMINATING",
    "Terminated",
    "add_detail",
    "details",
    "halt_motor",
    "id_text",
    "marking_the_stop",
    "new_command",
    "no_servos",
    "note_the_stop",
    "report_line",
    "servos_note",
    "stop_and_read_back",
    "stop_motors",
    "stop_on_termination",
    "torque_text",
    "unwritten_text",
]


NOTHING_WRITTEN = "nothing was written to the servos"
DONE_WITH_THEM = ("after the command was done with the servos (nothing was sent to them "
                  "since; they do what it left them doing)")
_wrote_before: list[bool] = []
"""Holds True once a bus this process closed had written to its servos."""
_without_servos: list[bool] = []
"""Holds True once a command that has no servos (``no_servos``) has started."""
F = TypeVar("F", bound=Callable[..., Any])


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP (what ``timeout``, systemd, container runtimes and a closed
    terminal send), handled as a Ctrl+C is: the arm held, the wheels stopped, the report
    so far written; the program then exits with 128 + the signal's number."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(f"stopped by {signal.Signals(signum).name}")


TERMINATING = (signal.SIGTERM, signal.SIGHUP)


def stop_on_termination() -> Callable[[], None]:
    """Make SIGTERM and SIGHUP raise ``Terminated`` in the main thread (as Ctrl+C raises
    KeyboardInterrupt); return a function restoring the handlers there were."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, frame: FrameType | None) -> None:
        raise Terminated(signum)

    previous = {sig: signal.signal(sig, handler) for sig in TERMINATING}

    def restore() -> None:
        for sig, old in previous.items():
            signal.signal(sig, old)

    return restore


def new_command() -> None:
    """A command line starts: nothing written by it yet, its servos not yet known (so a
    command run in the same process after another, as a test or a program does, says
    only what is true of itself)."""
    _wrote_before.clear()
    _without_servos.clear()


def no_servos(command: F) -> F:
    """Mark a command's function as one that has no servos (``vision detect``, the twin's
    benchmarks): a stop of it then says nothing of servos."""
    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        _without_servos.append(True)
        return command(*args, **kwargs)
    return cast(F, run)


def unwritten_text() -> str:
    """What a stop outside any bus says of the servos: nothing written, or nothing since
    the command let them go (a Ctrl+C as a finished job prints its summary); nothing of a
    command that has none."""
    if _without_servos:
        return ""
    return DONE_WITH_THEM if _wrote_before else NOTHING_WRITTEN
HOLDING = "holding position (torque on)"
LIMP = "limp (torque off)"
SILENT = "not answering (torque unknown)"
STOP_SENT = "all servos stopped (MOVE_STOP)"

_NOTE = "busarm_servos"
_DETAILS = "busarm_details"


def id_text(ids: Iterable[int]) -> str:
    """``servo 3``, ``servos 1-5, 10``: IDs with runs of three or more as ranges."""
    ordered = sorted(set(ids))
    runs: list[list[int]] = []
    for sid in ordered:
        if runs and sid == runs[-1][-1] + 1:
            runs[-1].append(sid)
        else:
            runs.append([sid])
    parts = [f"{r[0]}-{r[-1]}" if len(r) >= 3 else ", ".join(map(str, r)) for r in runs]
    return ("servo " if len(ordered) == 1 else "servos ") + ", ".join(parts)


def torque_text(bus: ServoPort, ids: Iterable[int]) -> str:
    """The torque of each servo as read back now, grouped: ``servos 1-4 holding position
    (torque on); servo 10 limp (torque off)``."""
    groups: dict[str, list[int]] = {}
    for sid in sorted(set(ids)):
        try:
            state = HOLDING if bus.read_torque(sid) else LIMP
        except BusArmError:  # a timeout, a garbled reply, a port that is gone
            state = SILENT
        groups.setdefault(state, []).append(sid)
    return "; ".join(f"{id_text(group)} {state}" for state, group in groups.items())


def halt_motor(bus: LxServoPort, sid: int) -> None:
    """Take servo ``sid`` out of motor mode, holding where it is, without energising one
    that is limp: with torque on, speed 0 then position mode; with torque off, only
    position mode (which also sets speed 0), as a motor-mode write would load the motor."""
    if bus.read_torque(sid):
        bus.stop_motor(sid)
    bus.set_position_mode(sid)


def stop_motors(bus: ServoPort, ids: Iterable[int]) -> str:
    """Stop each of ``ids`` found turning in motor mode (MOVE_STOP does not:
    ``halt_motor``); what was done, or "" if none was turning (or the port has no motor
    mode: it is the LX servos')."""
    if not isinstance(bus, LxServoPort):
        return ""
    turning = []
    for sid in sorted(set(ids)):
        try:
            if bus.read_mode(sid).mode == ServoMode.MOTOR:
                halt_motor(bus, sid)
                turning.append(sid)
        except BusArmError:  # silent or garbled: the torque read-back says so
            continue
    return (f"{id_text(turning)} turning in motor mode: stopped (speed 0, position mode)"
            if turning else "")


def stop_and_read_back(bus: ServoPort, ids: Iterable[int]) -> str:
    """Send the emergency stop (and stop any motor turning), then say what the servos
    ``ids`` (and any this bus wrote to) do now."""
    bus.emergency_stop()
    known = set(ids) | bus.written_ids
    if not known:
        return STOP_SENT
    motors = stop_motors(bus, known)
    return "; ".join(t for t in (STOP_SENT, motors, torque_text(bus, known)) if t)


@contextmanager
def marking_the_stop(owner: AbstractContextManager[object], bus: ServoPort,
                     ids: Iterable[int] = ()) -> Iterator[None]:
    """``with owner`` (the bus, or the robot holding it); an exception that leaves is
    marked with what the servos were left doing (``servos_note``), read back before the
    bus closes. If nothing was written, nothing is sent and nothing is said."""
    with owner:
        try:
            yield
            if bus.wrote:
                _wrote_before.append(True)
        except BaseException as exc:
            if bus.wrote and getattr(exc, _NOTE, None) is None:
                note_the_stop(exc, bus, ids)
            raise


def note_the_stop(exc: BaseException, bus: ServoPort, ids: Iterable[int] = ()) -> None:
    """Stop the servos (MOVE_STOP) and mark ``exc`` with what they do now, read back (a
    live interface's stop: the arm held whether or not this process moved it)."""
    # Said if a second Ctrl+C cuts the read-back short (the bus's exit stops).
    setattr(exc, _NOTE, f"{STOP_SENT}; torque not read back")
    setattr(exc, _NOTE, stop_and_read_back(bus, ids))


def _chain(exc: BaseException) -> Iterator[BaseException]:
    """``exc`` and what caused it (a Ctrl+C at a prompt arrives as click's Abort)."""
    seen: BaseException | None = exc
    met: set[int] = set()
    while seen is not None and id(seen) not in met:
        met.add(id(seen))
        yield seen
        seen = seen.__cause__ or seen.__context__


def servos_note(exc: BaseException) -> str | None:
    """What ``exc`` (or what caused it) left the servos doing; None if nothing was written."""
    for seen in _chain(exc):
        note = getattr(seen, _NOTE, None)
        if isinstance(note, str):
            return note
    return None


def add_detail(exc: BaseException, text: str) -> None:
    """Add ``text`` to the one line that reports ``exc`` (after the servos' state)."""
    setattr(exc, _DETAILS, [*getattr(exc, _DETAILS, []), text])


def details(exc: BaseException) -> list[str]:
    """What was added with ``add_detail`` to ``exc`` or what caused it."""
    return [text for seen in _chain(exc) for text in getattr(seen, _DETAILS, [])]


def report_line(exc: BaseException | None, message: str, *, unwritten: str = "") -> str:
    """``message``, what the servos were left doing and the details, as one line; if
    nothing was written to them, ``unwritten`` is said of them (if anything)."""
    if exc is None:
        return message
    note = servos_note(exc) or unwritten
    return "; ".join([f"{message}: {note}" if note else message, *details(exc)])
