"""What the arm commands take from a person, checked before any port is opened: the
robot's folder (where its named poses are kept), joints as JSON, the gripper in mm.

This module imports nothing from the command line (busarm.cli.common re-exports it).
Saved poses live per robot in ``$XDG_CONFIG_HOME/busarm/<robot>/poses.json``
(``~/.config`` without it): the robot's folder of ``busarm.robot.calibration_store``,
whose key rules are repeated here so that the arm commands do not load the twin.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Any

from busarm.arm.config import ArmConfig
from busarm.arm.named_poses import find_pose
from busarm.errors import ConfigError
from busarm.fileio import robot_folder
from busarm.units import check_range


def joints_to_move(config: ArmConfig, port: str, joints: tuple[float, ...],
                   pose_name: str | None, json_source: str | None) -> tuple[float, ...]:
    """The joints ``arm move-joints`` was given: five angles, a named pose (of the robot
    on ``port``) or JSON; checked against the joint limits."""
    if sum((bool(joints), pose_name is not None, json_source is not None)) != 1:
        raise ConfigError("give five joint angles in deg, --pose NAME or --json FILE (one of "
                          f"them); got {len(joints)} angle(s)"
                          + (" and --pose" if pose_name is not None else "")
                          + (" and --json" if json_source is not None else ""))
    if pose_name is not None:
        joints = find_pose(robot_folder(port), config, pose_name).joints_deg
    elif json_source is not None:
        joints = joints_from_json(json_source, config)
    return config.check_joints(joints)


def joints_from_json(source: str, config: ArmConfig) -> tuple[float, ...]:
    """Joint angles from a JSON file (``-``: stdin): what ``arm pose --json`` or ``arm fk
    --json`` prints (``{"joints_deg": {name: deg} or [deg x 5]}``), or a bare list."""
    where = "stdin" if source == "-" else source
    try:
        raw = sys.stdin.read() if source == "-" else Path(source).read_text(encoding="utf-8")
        data: Any = json.loads(raw)
    except OSError as exc:
        raise ConfigError(f"cannot read joints from {where}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise ConfigError(f"joints from {where}: not JSON ({exc})") from None
    if isinstance(data, dict):
        data = data.get("joints_deg")
    if isinstance(data, dict):
        names = [j.name for j in config.joints]
        if sorted(data) != sorted(names):
            raise ConfigError(f"joints from {where}: joint names {', '.join(sorted(data))} "
                              f"are not this arm's {', '.join(names)}")
        data = [data[n] for n in names]
    if not isinstance(data, list):
        raise ConfigError(f"joints from {where}: expected {{\"joints_deg\": ...}} as `busarm "
                          "arm pose --json` prints it, or a list of 5 angles in deg")
    try:
        return config.check_joints(data)
    except ConfigError as exc:
        raise ConfigError(f"joints from {where}: {exc}") from None


# ---------------------------------------------------------------------- the gripper in mm


def parse_gripper_target(text: str) -> str | float:
    """``open``, ``close``, or the gap between the fingers in mm (``25mm``) as a float."""
    word = text.strip().lower()
    if word in ("open", "close"):
        return word
    match = re.fullmatch(r"(-?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+))\s*mm", word)
    if match is None:
        raise ConfigError(f"{text!r} is not open, close or a gap between the fingers in mm "
                          "such as 25mm")
    return float(match.group(1))


def check_gap_mm(config: ArmConfig, gap_mm: float) -> float:
    """``gap_mm`` if the gripper can open that wide (0 = fingers touching), else
    ConfigError with the range."""
    g = config.gripper
    widest = g.gap_mm_at(g.open_pulses)
    return check_range("gripper gap", gap_mm, 0.0, widest, "mm")


def gap_report(config: ArmConfig, gap_mm: float, position_pulses: int) -> str:
    """What the gripper did when asked for ``gap_mm``: where it stopped, and whether it
    stopped short (something in the way)."""
    g = config.gripper
    at = g.gap_mm_at(position_pulses)
    target = g.pulses_for_gap_mm(gap_mm)
    where = f"{at:.1f} mm apart ({position_pulses} pulses)"
    if abs(position_pulses - target) > g.holding_margin_pulses:
        return (f"gripper stopped at {where}, short of the {gap_mm:.1f} mm asked: something "
                "is in the way of the fingers")
    return f"gripper at {where}"
