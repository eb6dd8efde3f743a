"""Recording a RobotView's channels into an MCAP file that Foxglove replays.

The messages are the ones a live viewer gets (protobuf with each channel's schema, the
URDF as JSON), with their log times: Foxglove opens the file (drag it onto the app) and
plays the run back in the same panels. The file is written under a temporary name
beside it and renamed when it is complete (busarm.fileio.atomic_path), so that a run cut
short never leaves a truncated file under the name asked for.
"""

from __future__ import annotations

import os
from contextlib import AbstractContextManager
from pathlib import Path

import foxglove

from busarm.errors import ConfigError
from busarm.fileio import atomic_path
from busarm.view.live import RobotView

__all__ = [
    "McapRecording",
]


class _Abandoned(Exception):
    """Thrown into the temporary file's context: it is removed, nothing renamed."""


class McapRecording:
    """Writes every message of ``view`` into ``path`` from now until ``close()``."""

    def __init__(self, view: RobotView, path: Path | str) -> None:
        self.path = Path(path)
        folder = self.path.parent
        if not folder.is_dir() or not os.access(folder, os.W_OK):
            raise ConfigError(f"cannot record into {self.path}: its folder {folder} does "
                              "not exist or is not writable")
        if self.path.is_dir():
            raise ConfigError(f"cannot record into {self.path}: it is a folder")
        self.view = view
        self._file: AbstractContextManager[Path] | None = atomic_path(self.path, "recording")
        self.partial = self._file.__enter__()
        """The file being written (renamed to ``path`` when complete)."""
        try:
            self._writer: foxglove.MCAPWriter | None = foxglove.open_mcap(
                self.partial, allow_overwrite=True, context=view.record_context)
        except BaseException as exc:
            self._writer = None
            self._end(exc)
            raise
        if view.started:  # else its start does
            view.publish_latched(live=False)  # the URDF (and a map) at the file's start

    def close(self) -> Path:
        """Finish the file and give it its name; returns its path."""
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.close()
            except BaseException as exc:
                self._end(exc)
                raise
            self._end(None)
        return self.path

    def abandon(self) -> None:
        """Stop and leave no file (a run that failed before it began)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.close()
            finally:
                self._end(_Abandoned())

    def _end(self, exc: BaseException | None) -> None:
        """Leave the temporary file's context: renamed when ``exc`` is None, else
        removed."""
        file, self._file = self._file, None
        if file is not None:
            file.__exit__(None if exc is None else type(exc), exc, None)

    def __enter__(self) -> McapRecording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
