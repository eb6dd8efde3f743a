"""The progress callback long jobs take: called with a line of text as they go along."""

from __future__ import annotations

from collections.abc import Callable

__all__ = [
    "Progress",
    "quiet",
]


Progress = Callable[[str], None]
"""Called with a line of text as a long job goes along (a CLI prints it, a test may not)."""


def quiet(_: str) -> None:
    """A progress callback that says nothing."""
