"""docs/programming.md's Python blocks run as written on the twin (each in a fresh
namespace, in a folder of its own), the clock first, and none of them freezes the twin's
clock (a FrozenClockWarning would fail them)."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
from test_readme_python import python_blocks, run_block

from busarm import FrozenClockWarning

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "programming.md"
BLOCKS = python_blocks(GUIDE)


def test_the_guide_teaches_the_robots_clock_first() -> None:
    assert len(BLOCKS) >= 3
    text = GUIDE.read_text()
    assert text.index("## The clock first") < text.index("## One observation")
    assert "robot.clock.sleep(" in BLOCKS[0]
    assert not any("time.sleep(" in block.replace("clock.sleep(", "") for block in BLOCKS)


@pytest.mark.slow  # each opens the mobile robot's twin
@pytest.mark.parametrize("number", range(len(BLOCKS)), ids=lambda n: f"python{n + 1}")
def test_a_guide_block_runs_as_written(number: int, tmp_path: Path,
                                       monkeypatch: pytest.MonkeyPatch,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FrozenClockWarning)
        run_block(BLOCKS[number], f"docs/programming.md python block {number + 1}")
    assert capsys.readouterr().out.strip(), "it printed nothing"
