"""``python -m busarm`` (and the ``busarm`` script): the busarm command line."""

from __future__ import annotations

import os
import sys

EXIT_INTERRUPTED = 130


def main() -> None:
    """Run the command line. A Ctrl+C while it loads (its imports take about 0.4 s, before
    any command can handle one) ends it with one line and exit code 130."""
    try:
        from busarm.cli.main import main as run
    except BaseException as exc:
        if not _by_ctrl_c(exc):
            raise
        # Nothing was opened yet: no port, no servo, nothing to close or flush but stderr.
        # os._exit, not sys.exit: a Ctrl+C inside an extension module's start-up code
        # leaves the interpreter set to end by SIGINT itself (status -2, not 130).
        sys.stderr.write("interrupted: nothing was written to the servos\n")
        sys.stderr.flush()
        os._exit(EXIT_INTERRUPTED)
    run()


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
