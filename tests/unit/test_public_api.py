"""busarm's public face: the user's names import from ``busarm`` (and the base's from
``busarm.base``), each is what its module defines, ``import busarm`` stays light, and
every module says what it exports (``__all__``: each public class and function it
defines, and only names it has)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import busarm
import busarm.base


def test_every_exported_name_is_its_modules() -> None:
    for package in (busarm, busarm.base):
        for name in package.__all__:
            value = getattr(package, name)
            defined_in = getattr(value, "__module__", None)
            assert defined_in is None or defined_in.startswith("busarm."), (name, defined_in)
            assert name in dir(package)


def test_the_new_users_names_import_from_busarm() -> None:
    from busarm import Arm, Base, LaserScan, Pose2D, Robot, Trip, build_map
    from busarm.base import Base as BaseAgain
    from busarm.base import Pose2D as Pose2DAgain
    from busarm.base import Twist

    assert Base is BaseAgain and Pose2D is Pose2DAgain
    assert Robot.__module__ == "busarm.robot.robot" and Arm.__module__ == "busarm.arm.arm"
    assert LaserScan.__module__ == "busarm.lidar.scan"
    assert callable(build_map) and Trip.__module__ == "busarm.apps.navigation.navigator"
    assert Twist(0.1, 0.0, 0.0).vx_m_s == 0.1


def test_an_unknown_name_is_an_attribute_error() -> None:
    with pytest.raises(AttributeError, match="module 'busarm' has no attribute 'Robots'"):
        _ = busarm.Robots  # type: ignore[attr-defined]
    with pytest.raises(ImportError, match="cannot import name 'Robots' from 'busarm'"):
        from busarm import Robots  # type: ignore[attr-defined]  # noqa: F401


def test_import_busarm_loads_no_heavy_module() -> None:
    # A fresh interpreter is the subject: what importing busarm alone loads.
    code = ("import sys, busarm, busarm.base; "
            "print(sorted(m for m in ('mujoco', 'cv2', 'serial', 'numpy', 'scipy', 'zenoh') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == "[]"


SRC = Path(busarm.__file__).parent


def _exports(tree: ast.Module) -> list[str] | None:
    for node in tree.body:
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AnnAssign) else [])
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            value = node.value
            assert isinstance(value, ast.List), "__all__ is not a literal list"
            return [ast.literal_eval(e) for e in value.elts]
    return None


def _top_level(tree: ast.Module) -> tuple[set[str], set[str]]:
    """The names a module has at its top (TYPE_CHECKING imports included), and the
    public classes and functions it defines."""
    have: set[str] = set()
    defined: set[str] = set()
    body = list(tree.body)
    while body:
        node = body.pop(0)
        if isinstance(node, ast.If | ast.Try):
            body[:0] = [*node.body, *getattr(node, "orelse", [])]
        elif isinstance(node, ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            have.add(node.name)
            if not node.name.startswith("_"):
                defined.add(node.name)
        elif isinstance(node, ast.Import | ast.ImportFrom):
            have.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for name in ast.walk(target):
                    if isinstance(name, ast.Name):
                        have.add(name.id)
    return have, defined


def test_every_module_says_what_it_exports() -> None:
    problems = []
    for path in sorted(SRC.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        where = path.relative_to(SRC.parent)
        exports = _exports(tree)
        if exports is None:
            problems.append(f"{where}: no __all__")
            continue
        have, defined = _top_level(tree)
        unknown = [n for n in exports if n not in have]
        unlisted = sorted(defined - set(exports))
        if unknown:
            problems.append(f"{where}: __all__ names what it does not have: {unknown}")
        if unlisted:
            problems.append(f"{where}: public but not in __all__: {unlisted}")
    assert not problems, "\n".join(problems)


def test_reprs_are_short_and_say_what_a_thing_is() -> None:
    import numpy as np

    from busarm.nav.localize import PoseEstimate

    angles = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    ranges = np.where(np.arange(400) % 4 == 0, np.nan, 2.0)
    scan = busarm.LaserScan(angles, ranges, np.full(400, 40.0), 12.3456, 0.15, 12.0, 0.18)
    assert repr(scan) == "LaserScan(400 beams, 300 returns, 0.15..12 m, at 12.346 s, 5.6 Hz)"
    pose = busarm.Pose2D(1 / 3, -2 / 3, 0.123456)
    assert repr(pose) == "Pose2D(x_m=0.3333, y_m=-0.6667, yaw_rad=0.1235)"
    estimate = PoseEstimate(pose, np.diag([1e-4, 1e-4, 1e-4]), True, 0.912)
    assert repr(estimate) == ("PoseEstimate(Pose2D(x_m=0.3333, y_m=-0.6667, yaw_rad=0.1235), "
                              "converged, spread 0.014 m 0.6 deg, matched 0.91)")
    trip = busarm.Trip(pose, ok=False, why="blocked", seconds=3.21,
                       path=[busarm.Pose2D(), busarm.Pose2D(3.0, 4.0, 0.0)])
    assert repr(trip) == ("Trip(to Pose2D(x_m=0.3333, y_m=-0.6667, yaw_rad=0.1235), not "
                          "arrived (blocked), 3.2 s, 5.00 m, 0 plan(s), 0 obstacle stop(s))")


def test_an_arm_moves_to_a_named_pose_and_a_wrong_name_lists_them() -> None:
    from busarm.sim.spec import SimSpec

    with busarm.Arm.open(SimSpec()) as arm:
        arm.move_to_pose("home")
        reached = arm.read_joints_deg()
        assert all(abs(a - b) < 1.5 for a, b in zip(reached, arm.config.pose("home"),
                                                     strict=True))
        with pytest.raises(busarm.ConfigError, match="no pose named 'dance'.*poses: home"):
            arm.move_to_pose("dance")
