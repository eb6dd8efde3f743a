"""A port string is read once, at the edge: no module below the command line parses a port
URL or builds one (issue 29). The edge is ``busarm.robot.port_url`` (and the interfaces:
the CLI, the dashboard, the ROS bridge, which read what a person typed).

Read from the source (the AST), not by running it: a module that splits ``"?"`` off a
port, tests ``startswith("twin://")``, calls ``urllib.parse`` or writes ``f"board://{x}"``
fails here, wherever it sits, whether or not a test reaches that line. Words inside a
message (an exception's text, a docstring) are not parsing: they tell a person what to
type.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import busarm

SRC = Path(busarm.__file__).parent
EDGE = {"robot/port_url.py"}
"""Where port strings are read."""
INTERFACES = ("cli/", "dashboard/", "ros/", "view/", "__main__.py")
"""Above the robot: they read what a person typed (and hand it to the edge)."""
ADDRESSES = {
    "vision/stream.py": "a network camera's stream URL (http://, rtsp://): a camera address",
    "vision/camera.py": "a camera source's scheme (twin, http): a camera address",
    "twin/camera.py": "a served twin camera's address (twin://127.0.0.1:PORT)",
    "bus/transport.py": "a pyserial URL (socket://...), which pyserial reads itself",
}
"""Modules that read an address that is not a robot's port, and why."""
SCHEMES = ("twin://", "sim://", "board://", "zenoh://", "lidar://")


def _below_the_cli() -> list[Path]:
    return sorted(p for p in SRC.rglob("*.py")
                  if not str(p.relative_to(SRC)).startswith(INTERFACES)
                  and str(p.relative_to(SRC)) not in EDGE)


def _messages(tree: ast.AST) -> set[int]:
    """ids of the string nodes that are text for a person: docstrings, the arguments of
    a raised exception, warnings and progress lines."""
    said: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                said.add(id(body[0].value))
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            said.add(id(node.value))  # an attribute's docstring
        if isinstance(node, ast.Raise) and node.exc is not None:
            said.update(id(n) for n in ast.walk(node.exc))
    return said


def _imports_url_parsing(node: ast.AST) -> bool:
    return ((isinstance(node, ast.ImportFrom) and node.module == "urllib.parse")
            or (isinstance(node, ast.Import)
                and any(a.name == "urllib.parse" for a in node.names)))


def _port_syntax(text: str) -> bool:
    """A scheme of ours, or the ``://`` that splits or builds one."""
    return "://" in text and (text == "://" or text.startswith(SCHEMES) or text.endswith("://"))


def _violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    said = _messages(tree)
    found = []
    for node in ast.walk(tree):
        line = getattr(node, "lineno", 0)
        if _imports_url_parsing(node):
            found.append(f"{line}: imports urllib.parse")
        elif (isinstance(node, ast.Constant) and isinstance(node.value, str)
              and id(node) not in said and _port_syntax(node.value)):
            found.append(f"{line}: port syntax {node.value!r}")
    return found


def test_no_module_below_the_cli_parses_or_builds_a_port_string() -> None:
    bad = {str(p.relative_to(SRC)): v for p in _below_the_cli()
           if (v := _violations(p)) and str(p.relative_to(SRC)) not in ADDRESSES}
    assert not bad, ("port strings are read at the edge (busarm.robot.port_url) only:\n"
                     + "\n".join(f"{m}: {', '.join(v)}" for m, v in bad.items()))


def test_the_allowed_address_readers_are_still_needed() -> None:
    """An allowance that no module needs any more goes (so the list cannot grow stale)."""
    unneeded = [m for m in ADDRESSES if not _violations(SRC / m)]
    assert not unneeded, f"no longer read addresses: {unneeded}; drop them from ADDRESSES"


@pytest.mark.parametrize("code", [
    "from urllib.parse import urlsplit\n",
    "def f(port):\n    return port.startswith('twin://')\n",
    "def f(path):\n    return f'board://{path}'\n",
    "def f(port):\n    return port.split('://', 1)[0]\n",
])
def test_the_check_sees_each_way_of_parsing(tmp_path: Path, code: str) -> None:
    """The check itself can fail: each way of reading or building a port is seen."""
    module = tmp_path / "m.py"
    module.write_text(code, encoding="utf-8")
    assert _violations(module)


def test_a_message_naming_a_port_is_not_parsing(tmp_path: Path) -> None:
    module = tmp_path / "m.py"
    module.write_text('"""Open twin://?seed=3."""\n'
                      "def f():\n"
                      "    raise ValueError('give board:///dev/ttyACM0')\n", encoding="utf-8")
    assert not _violations(module)
