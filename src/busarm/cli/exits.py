"""The command line's exit codes, and the end of a command whose job was not done.

0: done. 1: a bus error (timeouts, garbled replies, a port that cannot be opened), or a
job not done though the command ran to its end (``JobNotDone``: blocks left unsorted, a
benchmark target missed; its output is printed first). 2: bad input (usage errors,
ConfigError, the input ending at a question). 130: interrupted (Ctrl+C), 143 by SIGTERM,
129 by SIGHUP, each stopping as Ctrl+C does; the servers (``sim serve``, ``twin serve``,
``dashboard``, ``view``), whose way to stop is SIGINT or SIGTERM, end 0 (``ros bridge``
and ``record`` end 0 on Ctrl+C only). 141: stdout's reader went away (``busarm ... |
head``), quietly, as Unix tools do.
"""

from __future__ import annotations

import click

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_FAILED",
    "EXIT_INTERRUPTED",
    "EXIT_OUTPUT_CLOSED",
    "JobNotDone",
]


EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
EXIT_INTERRUPTED = 130
EXIT_OUTPUT_CLOSED = 141
"""128 + SIGPIPE: what a shell reports of a Unix tool whose reader went away."""


class JobNotDone(click.ClickException):
    """The command ran to its end and printed what it did, but did not do its job: one
    ``error:`` line, exit code 1, so that scripts can tell."""

    exit_code = EXIT_FAILED
