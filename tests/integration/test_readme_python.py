"""The README's Python examples run as written (each in a fresh namespace, in a folder of
its own, on the simulated arm or twin they name)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[2] / "README.md"


def python_blocks(path: Path) -> list[str]:
    """The ```python blocks of a Markdown file, as written."""
    return re.findall(r"```python\n(.*?)```", path.read_text(), re.DOTALL)


def run_block(block: str, where: str) -> None:
    """Run one block as written, in a fresh namespace (in the current folder)."""
    exec(compile(block, where, "exec"), {})


BLOCKS = python_blocks(README)


def test_the_readme_has_python_examples() -> None:
    assert len(BLOCKS) >= 3
    assert all("from busarm import " in block for block in BLOCKS)


@pytest.mark.slow  # the first one sorts a table on the twin
@pytest.mark.parametrize("number", range(len(BLOCKS)), ids=lambda n: f"python{n + 1}")
def test_a_readme_python_block_runs_as_written(number: int, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    run_block(BLOCKS[number], f"README.md python block {number + 1}")
    assert capsys.readouterr().out.strip(), "it printed nothing"
