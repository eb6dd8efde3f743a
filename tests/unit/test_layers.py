"""The layer contract ([tool.importlinter] in pyproject.toml, run by `lint-imports`).

It holds on the package as it is; it breaks when an upward import is planted in a copy of
the package; and the pure arm model loads without the bus driver.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PYPROJECT = REPO / "pyproject.toml"
PACKAGE = REPO / "src" / "busarm"
ANSI = re.compile(r"\x1b\[[0-9;]*m")


def lint_imports(cwd: Path, config: Path, pythonpath: Path | None = None) -> tuple[int, str]:
    """Run `lint-imports` from this interpreter's environment; its exit code and output."""
    env = dict(os.environ, NO_COLOR="1")
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(pythonpath), env.get("PYTHONPATH", "")])
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "from importlinter.cli import lint_imports_command; lint_imports_command()",
            "--config",
            str(config),
            "--no-cache",
        ],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    return proc.returncode, ANSI.sub("", proc.stdout + proc.stderr)


def test_the_package_keeps_its_layer_contract() -> None:
    code, out = lint_imports(REPO, PYPROJECT)
    assert code == 0, out
    assert "busarm layers (lower never imports higher) KEPT" in out, out
    assert "vision never imports the bus or the arm KEPT" in out, out
    assert "0 broken" in out, out


@pytest.mark.parametrize(
    ("target", "planted", "contract"),
    [
        # The lowest layer reaching for the top.
        ("protocol/commands.py", "busarm.apps.pick_sort.sorter", "busarm layers"),
        # The pure arm model reaching up to the twin.
        ("arm/kinematics.py", "busarm.twin", "busarm layers"),
        # Above the arm in the layers, but vision must not need the robot's hardware.
        ("vision/color.py", "busarm.arm.config", "vision never imports the bus or the arm"),
    ],
)
def test_a_planted_upward_import_breaks_the_contract(
    tmp_path: Path, target: str, planted: str, contract: str
) -> None:
    copy = tmp_path / "src" / "busarm"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    module = copy / target
    source = module.read_text(encoding="utf-8")
    module.write_text(f"{source}\nimport {planted}  # planted\n", encoding="utf-8")
    line = source.count("\n") + 2
    config = tmp_path / "pyproject.toml"
    shutil.copyfile(PYPROJECT, config)

    code, out = lint_imports(tmp_path, config, pythonpath=tmp_path / "src")

    assert code != 0, out
    assert f"{contract}" in out and "BROKEN" in out, out
    importer = "busarm." + target.removesuffix(".py").replace("/", ".")
    assert f"{importer} -> {planted} (l.{line})" in out, out


def test_a_top_level_module_outside_every_layer_breaks_the_contract(tmp_path: Path) -> None:
    copy = tmp_path / "src" / "busarm"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "stray.py").write_text('"""Placed in no layer."""\n', encoding="utf-8")
    config = tmp_path / "pyproject.toml"
    shutil.copyfile(PYPROJECT, config)

    code, out = lint_imports(tmp_path, config, pythonpath=tmp_path / "src")

    assert code != 0, out
    assert "- busarm.stray" in out, out


def test_importing_the_arm_model_does_not_load_the_bus() -> None:
    probe = (
        "import sys\n"
        "import busarm.arm.kinematics, busarm.arm.config\n"
        "bus = sorted(m for m in sys.modules if m == 'busarm.bus' or m.startswith('busarm.bus.'))\n"
        "assert not bus, bus\n"
        "from busarm.arm import Arm, ArmKinematics\n"
        "assert 'busarm.bus.driver' in sys.modules\n"
        "assert Arm.__module__ == 'busarm.arm.arm', Arm.__module__\n"
    )
    proc = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_busarm_arm_still_exports_its_names() -> None:
    import busarm.arm as arm

    for name in arm.__all__:
        value = getattr(arm, name)
        assert value.__module__.startswith("busarm.arm."), (name, value)
    assert set(arm.__all__) <= set(dir(arm))
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        arm.nonexistent  # noqa: B018


def cli_imports_of_other_commands(source: str) -> list[str]:
    """The busarm.cli modules other than ``common``, ``text`` (how values are written) and
    ``bench_report`` (how benchmark reports are judged) that a command module imports."""
    import ast

    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module == "busarm.cli":
            names = [f"busarm.cli.{a.name}" for a in node.names]  # from busarm.cli import x
        else:
            names = ([node.module or ""] if isinstance(node, ast.ImportFrom)
                     else [a.name for a in node.names] if isinstance(node, ast.Import) else [])
        found += [n for n in names if n.startswith("busarm.cli")
                  and n not in ("busarm.cli.common", "busarm.cli.text",
                                "busarm.cli.bench_report")]
    return found


def test_cli_command_modules_share_helpers_only_through_common() -> None:
    commands = [p for p in (PACKAGE / "cli").glob("*.py")
                if p.name not in ("__init__.py", "main.py", "common.py", "text.py",
                                  "bench_report.py")]
    assert len(commands) >= 10
    for path in commands:
        assert cli_imports_of_other_commands(path.read_text()) == [], path.name
    # ... and the check sees such an import when there is one.
    planted = ("from busarm.cli.arm_cmds import ArmContext\nimport busarm.cli.pick_cmd\n"
               "from busarm.cli import text, twin_cmds\n")
    assert cli_imports_of_other_commands(planted) == ["busarm.cli.arm_cmds",
                                                      "busarm.cli.pick_cmd",
                                                      "busarm.cli.twin_cmds"]
