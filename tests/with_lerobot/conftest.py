"""The LeRobot tests run in LeRobot's own environment (``make lerobot``: .venv-lerobot,
where ``make test`` runs them beside the rest): offline, LeRobot's home in a folder of the
run's own."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent
"""LeRobot's scripts (lerobot-record, -replay, -train, -eval) and busarm's, beside this
Python."""


@pytest.fixture(autouse=True)
def offline_lerobot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """No hub, no downloads; LeRobot's home and cache in the test's folder."""
    for key, value in (("HF_HUB_OFFLINE", "1"), ("HF_DATASETS_OFFLINE", "1"),
                       ("HF_LEROBOT_HOME", str(tmp_path / "hf")),
                       ("HF_HOME", str(tmp_path / "hf-home")),
                       ("WANDB_MODE", "disabled")):
        monkeypatch.setenv(key, value)
    yield


def lerobot_env() -> dict[str, str]:
    """The environment a LeRobot script runs in (the test's, as set above)."""
    return dict(os.environ)
