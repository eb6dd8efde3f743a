"""``python -m busarm`` (and the ``busarm`` script): the busarm command line."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
from collections.abc import Callable
from types import FrameType
from typing import Any, NoReturn

__all__ = [
    "EXIT_INTERRUPTED",
    "main",
]


EXIT_INTERRUPTED = 130


def main() -> None:
    """Run the command line. A Ctrl+C while it loads (its imports take about 0.4 s, before
    any command can handle one) ends it with one line and exit code 130."""
    came: list[bool] = []
    restore = _note_ctrl_c(came)
    try:
        from busarm.cli.main import main as run

        restore()
    except BaseException as exc:
        if not _by_ctrl_c(exc):
            raise
        _interrupted_loading()
    if came:  # raised where Python drops it (a weakref callback of the import system)
        _interrupted_loading()
    try:
        run()
    except SystemExit as exc:
        if exc.code != EXIT_INTERRUPTED:
            raise
        # The command said so and closed what it opened; but a Ctrl+C inside an extension
        # module's start-up code (a lazy import) leaves the interpreter set to end by SIGINT
        # itself at exit (status -2): 130, as said.
        logging.shutdown()
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(EXIT_INTERRUPTED)


def _note_ctrl_c(came: list[bool]) -> Callable[[], None]:
    """Until the returned function is called: a Ctrl+C is noted in ``came`` (and raised, as
    Python's own handler does), and one Python drops as "Exception ignored" is not
    printed. A Ctrl+C that is ignored (a background job) stays ignored."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        return lambda: None
    hook = sys.unraisablehook

    def on_ctrl_c(signum: int, frame: FrameType | None) -> None:
        came.append(True)
        raise KeyboardInterrupt

    def unraisable(info: Any) -> None:
        if not isinstance(info.exc_value, KeyboardInterrupt):
            hook(info)

    signal.signal(signal.SIGINT, on_ctrl_c)
    sys.unraisablehook = unraisable

    def restore() -> None:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        sys.unraisablehook = hook

    return restore


def _interrupted_loading() -> NoReturn:
    # Nothing was opened yet: no port, no servo, nothing to close or flush but stderr.
    # os._exit, not sys.exit: a Ctrl+C inside an extension module's start-up code
    # leaves the interpreter set to end by SIGINT itself (status -2, not 130).
    sys.stderr.write("interrupted: nothing was written to the servos\n")
    sys.stderr.flush()
    os._exit(EXIT_INTERRUPTED)


def _by_ctrl_c(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl+C, or came of one (a KeyboardInterrupt in the middle of
    an import can surface as the RuntimeError it caused)."""
    seen: BaseException | None = exc
    met: set[int] = set()
    while seen is not None and id(seen) not in met:
        if isinstance(seen, KeyboardInterrupt):
            return True
        met.add(id(seen))
        seen = seen.__cause__ or seen.__context__
    return False


if __name__ == "__main__":
    main()
