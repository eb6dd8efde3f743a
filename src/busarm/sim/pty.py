"""A simulated line (a SimBus, or a SimBoard in front of one) on a pseudo-terminal, so
any serial program can talk to simulated servos.

``PtyServer(bus).start()`` returns a device path such as ``/dev/pts/7``; open it with
any serial library at any baud rate. Replies are written when the simulated wire
would have delivered their last byte.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from types import TracebackType

from busarm.errors import ConfigError, TransportError
from busarm.sim.bus import SimLine

__all__ = [
    "PtyServer",
]


_SPIN_S = 0.00015  # below this, spin instead of sleeping: select() overshoots by ~50-100 us


class PtyServer:
    """Serves ``bus`` on a new pseudo-terminal from a background thread."""

    def __init__(self, bus: SimLine) -> None:
        if bus.clock.is_simulated:
            # Programs at the other end wait in wall seconds; nothing would move the time.
            raise ConfigError("a pty serves a bus on the wall clock, not a simulated one")
        self.bus = bus
        self._master = -1
        self._slave = -1
        self._path = ""
        self._thread: threading.Thread | None = None
        self._stop_r, self._stop_w = -1, -1

    @property
    def path(self) -> str:
        """The device path clients open (valid after start())."""
        return self._path

    def open(self) -> str:
        """Create the pseudo-terminal and return its device path (does not serve yet)."""
        master, slave = os.openpty()
        # Raw mode: no line discipline echo or newline translation on the simulated wire.
        tty.setraw(slave)
        tty.setraw(master)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self._path = os.ttyname(slave)
        self._stop_r, self._stop_w = os.pipe()
        return self._path

    def start(self) -> str:
        """Open the pseudo-terminal and serve it from a daemon thread; return its path."""
        path = self.open()
        self._thread = threading.Thread(target=self.serve_forever, name="busarm-pty", daemon=True)
        self._thread.start()
        return path

    def serve_forever(self) -> None:
        """Shuttle bytes until stop() is called (runs in the caller's thread)."""
        if self._master < 0:
            self.open()
        master, stop_r, bus = self._master, self._stop_r, self.bus
        while True:
            due = bus.next_output_at()
            now = time.monotonic()
            if due is None:
                wait: float | None = 0.5
            else:
                wait = due - now
                if wait <= _SPIN_S:
                    wait = 0.0
                else:
                    wait -= _SPIN_S
            readable, _, _ = select.select((master, stop_r), (), (), wait)
            if stop_r in readable:
                return
            if master in readable:
                try:
                    data = os.read(master, 4096)
                except BlockingIOError:
                    data = b""
                except OSError as exc:  # EIO: no process holds the slave (cannot happen: we do)
                    raise TransportError(f"pty {self._path}: {exc}") from exc
                if data:
                    bus.receive(data)
            due = bus.next_output_at()
            if due is not None:
                while time.monotonic() < due and due - time.monotonic() <= _SPIN_S:
                    pass
                out = bus.pop_output()
                if out:
                    self._write_all(out)

    def _write_all(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                select.select((), (self._master,), (), 0.1)
                continue
            view = view[n:]

    def stop(self) -> None:
        """Stop serving, close the pseudo-terminal and power the servos off (saving
        their state file, if they have one)."""
        if self._stop_w >= 0:
            os.write(self._stop_w, b"x")
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        if self._master >= 0:
            self.bus.power_off()
        for fd in (self._master, self._slave, self._stop_r, self._stop_w):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = self._stop_r = self._stop_w = -1

    def __enter__(self) -> PtyServer:
        if not self._path:
            self.start()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
