"""The API reference builds from the docstrings with no warning (``make docs`` builds the
same to build/api), and its front page shows the user's names."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

pytestmark = pytest.mark.slow  # imports and renders every module

SCRIPT = Path(__file__).resolve().parents[2] / "docs" / "api_reference.py"


def _script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("api_reference", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_api_reference_builds_without_a_warning(tmp_path: Path) -> None:
    assert _script().build(tmp_path) == []
    front = (tmp_path / "busarm.html").read_text()
    for name in ("Robot", "Arm", "Base", "Pose2D", "Twist", "LaserScan", "build_map",
                 "Navigator", "BusArmError"):
        assert f'id="{name}"' in front or f">{name}<" in front, name
    assert (tmp_path / "busarm" / "base.html").is_file()
    assert (tmp_path / "busarm" / "arm" / "kinematics.html").is_file()
