"""What the arm commands take from a person, checked before any port is opened: the
robot's folder (where its named poses are kept), joints as JSON, the gripper in mm.

This module imports nothing from the command line (busarm.cli.common re-exports it).
Saved poses live per robot in ``$XDG_CONFIG_HOME/busarm/<robot>/poses.json``
(``~/.config`` without it): the robot's folder of ``busarm.robot.calibration_store``,
whose key rules are repeated here so that the arm commands do not load the twin.
"""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path
from typing import Any

from busarm.arm.config import ArmConfig
from busarm.arm.gripper import gripper_state
from busarm.arm.named_poses import find_pose
from busarm.errors import ConfigError
from busarm.fileio import robot_folder
from busarm.units import check_range, fixed_number, listing, shown

__all__ = [
    "JOINTS_KEYS",
    "TARGET_KEYS",
    "check_gap_mm",
    "gap_report",
    "joints_from_json",
    "joints_in",
    "joints_to_move",
    "parse_gripper_target",
    "target_in",
]


def joints_to_move(config: ArmConfig, robot_key: str, joints: tuple[float, ...],
                   pose_name: str | None, json_source: str | None) -> tuple[float, ...]:
    """The joints ``arm move-joints`` was given: five angles, a named pose (of the robot
    whose kept files are ``robot_key``) or JSON; checked against the joint limits."""
    if sum((bool(joints), pose_name is not None, json_source is not None)) != 1:
        raise ConfigError("give five joint angles in deg, --pose NAME or --json FILE (one of "
                          f"them); got {len(joints)} angle(s)"
                          + (" and --pose" if pose_name is not None else "")
                          + (" and --json" if json_source is not None else ""))
    if pose_name is not None:
        joints = find_pose(robot_folder(robot_key), config, pose_name).joints_deg
    elif json_source is not None:
        joints = joints_from_json(json_source, config)
    return config.check_joints(joints)


def joints_from_json(source: str, config: ArmConfig) -> tuple[float, ...]:
    """Joint angles from a JSON file (``-``: stdin): what ``arm pose``, ``arm fk`` or
    ``arm ik`` print with ``--json`` (``joints_in``), or a bare list."""
    where = "stdin" if source == "-" else source
    try:
        raw = sys.stdin.read() if source == "-" else Path(source).read_text(encoding="utf-8")
        data: Any = json.loads(raw)
    except OSError as exc:
        raise ConfigError(f"cannot read joints from {where}: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        what = "empty" if not raw.strip() else (
            f"not JSON (line {exc.lineno}, column {exc.colno}: {exc.msg.lower()})")
        raise ConfigError(f"joints from {where}: {what}; expected the JSON of `busarm arm "
                          "pose --json`, `arm ik --json` or a list of angles") from None
    except ValueError as exc:  # not UTF-8 text
        raise ConfigError(f"joints from {where}: not text ({exc})") from None
    try:
        return joints_in(data, config)
    except ConfigError as exc:
        raise ConfigError(f"joints from {where}: {exc}") from None


JOINTS_KEYS = ("joints_deg", "joints")
"""Where busarm's JSON keeps joint angles (``joints`` is the older name)."""


def joints_in(data: object, config: ArmConfig) -> tuple[float, ...]:
    """Five joint angles (deg) from JSON as busarm's own outputs write them, checked
    against the limits: a list of five; ``{"joints_deg": {name: deg} or [...]}`` (``arm
    pose --json``, ``arm fk --json``; or ``joints``); ``{"solutions": [...]}`` (``arm ik
    --json``: the first, best one); or ``{name: deg}``."""
    if isinstance(data, dict) and not set(JOINTS_KEYS) & set(data) and "solutions" in data:
        solutions = data["solutions"]
        if not isinstance(solutions, list) or not solutions:
            raise ConfigError("no IK solution in it (\"solutions\" is empty)")
        data = solutions[0]
    names = [j.name for j in config.joints]
    if isinstance(data, dict) and not set(names) <= set(data):
        key = next((k for k in JOINTS_KEYS if k in data), None)
        if key is None:
            raise ConfigError(
                f"expected \"joints_deg\" as `busarm arm pose --json` prints it, or a list "
                f"of {len(names)} angles in deg; got an object with keys {listing(data)}")
        data = data[key]
    if isinstance(data, dict):
        if sorted(data) != sorted(names):
            raise ConfigError(f"joint names {listing(sorted(data))} are not this arm's "
                              f"{listing(names)}")
        data = [data[n] for n in names]
    return config.check_joints(data)


TARGET_KEYS = {"x": "x_mm", "y": "y_mm", "z": "z_mm", "pitch": "pitch_deg", "roll": "roll_deg"}
"""The keys of an IK target: the short ones, or the ones with units that busarm's JSON
outputs use (``arm fk --json``'s ``pose``)."""


def target_in(item: object) -> tuple[float, float, float, float | None, float | None]:
    """An IK target (x, y, z mm, pitch, roll deg or None) from one JSON line: ``[x, y, z[,
    pitch[, roll]]]``, ``{"x": .., "y": .., "z": ..[, "pitch"][, "roll"]}``, the same with
    ``x_mm``... keys, or a line of ``arm fk --json`` (its ``pose``) or ``arm ik --json``
    (its ``target``). Each value checked; ConfigError naming what is wrong."""
    if isinstance(item, list) and 3 <= len(item) <= 5:
        item = dict(zip(TARGET_KEYS, item, strict=False))
    if isinstance(item, dict):
        inner = next((item[k] for k in ("pose", "target") if isinstance(item.get(k), dict)),
                     None)
        item = inner if inner is not None else item
    if not isinstance(item, dict):
        raise ConfigError("expected a target: x, y, z (mm) and maybe pitch, roll (deg), as an "
                          f"object or a list; got {shown(item)}")
    unknown = set(item) - set(TARGET_KEYS) - set(TARGET_KEYS.values())
    if unknown or any(k not in item and TARGET_KEYS[k] not in item for k in ("x", "y", "z")):
        raise ConfigError("a target needs x, y, z (mm) and may have pitch, roll (deg) (or "
                          f"x_mm ... roll_deg); got keys {listing(item) or 'none'}")
    values = {k: item[k] if k in item else item.get(long) for k, long in TARGET_KEYS.items()}
    x, y, z = (check_range(k, values[k], -2000.0, 2000.0, "mm") for k in ("x", "y", "z"))
    pitch, roll = (None if values[k] is None else check_range(k, values[k], -360.0, 360.0, "deg")
                   for k in ("pitch", "roll"))
    return x, y, z, pitch, roll


# ---------------------------------------------------------------------- the gripper in mm


def parse_gripper_target(text: str) -> str | float:
    """``open``, ``close``, or the gap between the fingers in mm (``25mm``, or ``25``: mm
    is the arm commands' unit of length) as a float."""
    word = text.strip().lower()
    if word in ("open", "close"):
        return word
    match = re.fullmatch(r"(-?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+))\s*(?:mm)?", word)
    if match is None:
        raise ConfigError(f"{text!r} is not open, close or a gap between the fingers in mm "
                          "such as 25 or 25mm")
    return float(match.group(1))


def check_gap_mm(config: ArmConfig, gap_mm: float) -> float:
    """``gap_mm`` if the gripper can open that wide (0 = fingers touching), else
    ConfigError with the range."""
    # The range as the gripper is reported (0.1 mm): its widest gap, rounded up, so that
    # the width `arm gripper open` reports may be asked for (the pulses are clamped).
    widest = math.ceil(config.gripper.widest_gap_mm * 10.0 - 1e-9) / 10.0
    return check_range("gripper gap", gap_mm, 0.0, widest, "mm")


def gap_report(config: ArmConfig, gap_mm: float, position_pulses: int) -> str:
    """What the gripper did when asked for ``gap_mm``: where it stopped, and whether it
    stopped short: holding something (closing) or something in the way (opening)."""
    g = config.gripper
    state = gripper_state(g, position_pulses, g.pulses_for_gap_mm(gap_mm))
    where = f"{fixed_number(state.gap_mm, 1)} mm apart ({position_pulses} pulses)"
    asked = f"{fixed_number(gap_mm, 1)} mm"
    if state.is_holding:
        return f"gripper holding something: stopped at {where}, short of the {asked} asked"
    if state.short_of_target_pulses > g.holding_margin_pulses:
        return (f"gripper stopped at {where}, short of the {asked} asked: something "
                "is in the way of the fingers")
    return f"gripper at {where}"
