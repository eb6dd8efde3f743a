"""The LX servo family's port, whatever carries its commands: the type of a caller that
needs more of LX servos than the ``ServoPort`` contract (the ID scan and renumbering,
motor mode, LEDs and alarm masks, stored limits, raw commands).

Two peers implement it: ``ServoBus`` (busarm.bus.driver: the LX serial line) and
``BoardServoBus`` (busarm.bus.board_bus: behind the vendor's controller board). Neither
is the other's subclass; both share the LX calls (``ServoRegisters``, ``ServoMotion``)
over the carrier seam (``busarm.bus.servo_wire.ServoWire``). What a carrier cannot do
raises UnsupportedError before anything is sent.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Callable, Iterable

from busarm.bus.id_scan import ScanResult
from busarm.bus.servo_motion import ServoMotion
from busarm.protocol import MAX_SERVO_ID

__all__ = ["LxServoPort"]


class LxServoPort(ServoMotion):
    """An LX-family port: every LX call in the user's units (a ``ServoPort``, and more).
    Thread-safe; a context manager that stops on an exception (``ServoWire``)."""

    echo: bool
    """Whether the adapter hands back every byte sent (never, behind a board)."""

    @abstractmethod
    def scan(self, servo_ids: Iterable[int] = range(MAX_SERVO_ID + 1), *,
             margin_s: float = 0.0, progress: Callable[[int], None] | None = None
             ) -> ScanResult:
        """Ask every ID in ``servo_ids`` for itself; who answered (and, on the LX line,
        which IDs two servos share)."""

    @abstractmethod
    def set_id(self, old_id: int, new_id: int) -> None:
        """Renumber the servo at ``old_id``, only when that is safe (never a broadcast)."""
