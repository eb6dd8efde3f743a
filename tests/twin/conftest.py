"""Shared set-ups for the twin tests."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest


@pytest.fixture
def twin_server() -> Iterator[tuple[str, str]]:
    """``busarm twin serve --seed 2 --blocks 3`` in its own process: (the servos' pty, the
    camera's twin://127.0.0.1:PORT). It must stop cleanly on SIGTERM."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "busarm", "twin", "serve", "--seed", "2", "--blocks", "3"],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
    try:
        assert proc.stdout is not None
        yield proc.stdout.readline().strip(), proc.stdout.readline().strip()
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    assert proc.returncode == 0
