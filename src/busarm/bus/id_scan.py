"""Who is on the bus, and renumbering: the ID scan (with its duplicate-ID check) and
``set_id``.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from busarm.bus.bus_core import NO_ECHO_HINT, BusCore
from busarm.bus.servo_registers import ServoRegisters
from busarm.errors import (
    BusConflictError,
    BusTimeoutError,
    ConfigError,
    EchoMismatchError,
    ProtocolError,
)
from busarm.protocol import MAX_SERVO_ID, Command, FrameParser, check_servo_id, encode_request

__all__ = [
    "CONFLICT_PROBES",
    "LATE_REACH_S",
    "SCAN_MARGIN_S",
    "IdScan",
    "ScanResult",
]


CONFLICT_PROBES = 3
"""Position reads that decide whether a garbled ID is two servos or line noise."""
SCAN_MARGIN_S = 0.0001
"""A scan's margin past the end of an ID's reply. Its window is the request's and the
reply's wire time, the servo's turnaround (the bus's ``turnaround_s``) and the adapter's
latency, plus this: the servo's own jitter, not the computer's. A reply this computer
hears late (a busy CPU, a pty) was on the wire in time, and it is recognised by the ID
inside it in a later window. A servo slower than the bus's turnaround whose reply runs
into the next request garbles that window: the IDs asked up to LATE_REACH_S before
it are then asked again with the bus's own timeouts (see ``scan``). For a line of
slower servos, scan with a larger ``margin_s`` (``set_id`` asks a silent ID again with
the bus's ``timeout_margin_s``), or give the bus their ``turnaround_s``."""
LATE_REACH_S = 0.006
"""How late a reply that garbles a scan's window may be: the IDs asked this long before
the garbled window (plus the adapter's latency; less if the bus's own read deadline is
shorter) are asked again. About the bus's default read deadline at 115200 baud (5.6
ms): a servo later than that fails every plain read too. Bounded so that a bus opened
with a long margin (a pty, a slow adapter) does not probe dozens of absent IDs for one
damaged window."""


@dataclass
class ScanResult:
    """IDs that answered, and IDs whose replies were garbled (two servos on one ID)."""

    found: list[int] = field(default_factory=list)
    conflicts: list[int] = field(default_factory=list)
    duration_s: float = 0.0


class IdScan(BusCore, ServoRegisters):
    """The ID scan and renumbering on the LX line (a part of ``ServoBus``)."""

    def scan(
        self,
        servo_ids: Iterable[int] = range(MAX_SERVO_ID + 1),
        *,
        margin_s: float = SCAN_MARGIN_S,
        progress: Callable[[int], None] | None = None,
    ) -> ScanResult:
        """Ask every ID in ``servo_ids`` for itself (ID_READ); return who answered.

        Each ID gets the shortest window that can hold its reply (``scan_window_s``:
        wire time, turnaround, adapter latency and ``margin_s``, SCAN_MARGIN_S by
        default). A reply that arrives after its window is still recognised by the ID
        inside it, so a servo this computer hears late is not missed; one that answers
        so late that it runs into the next request garbles that window, and then the
        IDs asked up to LATE_REACH_S before it are probed too. Every ID that
        answered or garbled is probed with CONFLICT_PROBES position reads (with the
        bus's own timeouts): an ID whose replies stay garbled is reported in
        ``conflicts`` (two servos sharing it), not in ``found``; one that answers once
        is found. A servo whose every request is lost to noise is not found: scan again
        (slower: a larger ``margin_s``).
        """
        ids = [check_servo_id(s) for s in servo_ids]
        timeout = self.scan_window_s(margin_s)
        started = self._now()
        found, garbled = self._ask_ids(ids, timeout, progress)
        wanted = set(ids)
        found &= wanted
        # A garbled window may be two servos on one ID, or just line noise: ask again.
        # Two servos answering together garble nearly every time; noise rarely twice.
        answered, conflicts = self._probe_ids(sorted((garbled & wanted) | found))
        found |= answered
        return ScanResult(sorted(found - conflicts), sorted(conflicts),
                          self._now() - started)

    def scan_window_s(self, margin_s: float = SCAN_MARGIN_S) -> float:
        """How long a scan waits for one ID's answer: an ID_READ request (6 bytes) and
        its reply (7) on the wire, the servo's turnaround, the adapter's latency and
        ``margin_s`` (at 115200 baud with the default 0.5 ms turnaround: 1.73 ms)."""
        return self.timeout_s(6, 7, margin_s)

    def _ask_ids(
        self, ids: list[int], timeout: float, progress: Callable[[int], None] | None,
    ) -> tuple[set[int], set[int]]:
        """ID_READ to each of ``ids`` in turn, then a wait for stragglers: the IDs that
        answered, and those to probe for a window that held bytes making no valid frame:
        its own ID, and every ID asked within LATE_REACH_S before (a reply that late
        may be what the request ran into)."""
        parser = FrameParser()
        found: set[int] = set()
        garbled: set[int] = set()
        # How long ago a reply may still have been on its way.
        reach_s = min(self.timeout_s(6, 7), LATE_REACH_S + self.transport.latency_s)
        recent: deque[tuple[float, int]] = deque()  # (sent at, ID), newest last

        def collect(chunk: bytes) -> None:
            # Bytes that make no valid frame: two servos answering at once (their bits
            # AND on the open-drain line), or a reply so late the next request hit it.
            noise = parser.checksum_failures + parser.skipped_bytes
            for frame in parser.feed(chunk):
                if frame.command == Command.ID_READ and len(frame.params) == 1:
                    found.add(frame.servo_id)
            if parser.checksum_failures + parser.skipped_bytes > noise:
                since = self._now() - reach_s
                garbled.update(sid for at, sid in recent if at >= since)
                if recent:
                    garbled.add(recent[-1][1])  # the ID whose window this is

        with self._lock:
            self.transport.reset_input()
            for sid in ids:
                request = encode_request(sid, Command.ID_READ)
                self.transport.write(request)
                now = self._now()
                recent.append((now, sid))
                if len(recent) > 1 and recent[0][0] < now - reach_s:
                    recent.popleft()
                deadline = now + timeout
                while sid not in found:
                    remaining = deadline - self._now()
                    chunk = self.transport.read(256, remaining) if remaining > 0 else b""
                    if not chunk:
                        break
                    collect(chunk)
                if progress is not None:
                    progress(sid)
            # Stragglers: anything still on its way.
            tail_deadline = self._now() + 4 * timeout
            while (remaining := tail_deadline - self._now()) > 0:
                chunk = self.transport.read(256, remaining)
                if not chunk:
                    break
                collect(chunk)
        return found, garbled

    def _probe_ids(self, servo_ids: list[int]) -> tuple[set[int], set[int]]:
        """Up to CONFLICT_PROBES position reads of each ID: the IDs that answered once,
        and those whose replies stayed garbled (two servos sharing the ID)."""
        answered: set[int] = set()
        conflicts: set[int] = set()
        for sid in servo_ids:
            probes: list[str] = []
            while len(probes) < CONFLICT_PROBES and "ok" not in probes:
                probes.append(self._probe(sid))
            if "ok" in probes:
                answered.add(sid)
            elif probes.count("no echo") == len(probes):
                raise EchoMismatchError(
                    f"servo {sid} answers, but every reply came without our request's echo "
                    f"before it: {NO_ECHO_HINT}"
                )
            elif probes.count("garbled") >= 2:
                conflicts.add(sid)
        return answered, conflicts

    def _probe(self, servo_id: int) -> str:
        """One POS_READ attempt, no retry: "ok", "garbled" (bytes, no valid reply), "no echo"
        (a valid reply but not our echo before it, though echo is on) or "silent"."""
        plan = self._plans.get((servo_id, Command.POS_READ)) or self._plan(
            servo_id, Command.POS_READ
        )
        with self._lock:
            deadline = self._now() + plan.timeout_s
            first = self.transport.exchange(plan.request, plan.timeout_s)
            try:
                self._scan_reply(plan, servo_id, Command.POS_READ, first, deadline, False)
            except BusTimeoutError:
                return "silent"
            except EchoMismatchError:
                return "no echo"
            except ProtocolError:
                return "garbled"
            return "ok"

    def _forget(self, *servo_ids: int) -> None:
        """Drop what is cached about these IDs' requests (an ID changed hands)."""
        self._plans = {k: v for k, v in self._plans.items() if k[0] not in servo_ids}

    def set_id(self, old_id: int, new_id: int) -> None:
        """Renumber the servo at ``old_id`` to ``new_id``, safely.

        Refuses unless exactly one servo answers at ``old_id`` and none at ``new_id``;
        the ID write is addressed to ``old_id``, never broadcast. Verifies afterwards.
        """
        check_servo_id(old_id)
        check_servo_id(new_id)
        if old_id == new_id:
            raise ConfigError(f"servo already has ID {new_id}")
        result = self.scan([old_id, new_id])
        silent = [s for s in (old_id, new_id) if s not in result.found + result.conflicts]
        if silent:
            # A scan's deadline is short: silence is asked again with the bus's own
            # margin before it is taken as absence (a busy computer hears answers late,
            # and a servo missed at the new ID would end up sharing it).
            again = self.scan(silent, margin_s=self.timeout_margin_s)
            result = ScanResult(sorted({*result.found, *again.found}),
                                sorted({*result.conflicts, *again.conflicts}))
        if old_id in result.conflicts:
            raise BusConflictError(
                f"more than one servo answers at ID {old_id}; disconnect all but one first"
            )
        if old_id not in result.found:
            raise BusTimeoutError(f"no servo answers at ID {old_id}", servo_id=old_id)
        if new_id in result.found or new_id in result.conflicts:
            raise BusConflictError(f"ID {new_id} is already taken by another servo")
        self.send(old_id, Command.ID_WRITE, new_id)
        self.written_ids.discard(old_id)  # it answers at its new ID from now on
        self.written_ids.add(new_id)
        self._forget(old_id, new_id)
        if self.read_id(new_id) != new_id:
            raise ProtocolError(f"servo did not take ID {new_id}")
