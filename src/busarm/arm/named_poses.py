"""Named joint poses a person saves (``busarm arm pose --save NAME``) and moves back to.

They are kept in one JSON file, ``poses.json``, in a folder the caller chooses (the
command line keeps one folder per robot); every function here takes that folder. The
arm config's own poses (``home``, ``upright``, ``look``...) are built in: listed with the
saved ones, and never overwritten or deleted. File (written atomically)::

    {"format": "busarm.poses", "version": 1, "arm": "JetAuto Pro arm",
     "joints": ["base_yaw", "shoulder_pitch", "elbow_pitch", "wrist_pitch", "wrist_roll"],
     "poses": {"over_bin": [30.0, -120.5, 95.0, -64.5, 0.0]}}

Angles are joint degrees (the model's, as ``busarm arm pose`` prints them). Reading checks
that the file was written for joints of the same names and that every pose is within
this arm's joint limits; errors name the file and the pose.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from busarm.arm.config import ArmConfig
from busarm.errors import ConfigError
from busarm.fileio import read_versioned_json, write_text_atomic

FORMAT_NAME = "busarm.poses"
FORMAT_VERSION = 1
FILE_NAME = "poses.json"
NAME_MAX_CHARS = 32
_NAME = re.compile(r"[a-z][a-z0-9_-]*")
NAME_RULE = (f"1..{NAME_MAX_CHARS} characters: lowercase letters, digits, '-' and '_', "
             "starting with a letter")


@dataclass(frozen=True)
class NamedPose:
    """A pose by name: five joint angles in degrees; ``builtin`` if from the arm config."""

    name: str
    joints_deg: tuple[float, ...]
    builtin: bool


def poses_file(folder: Path) -> Path:
    """Where the saved poses of the robot whose folder is ``folder`` are kept."""
    return Path(folder) / FILE_NAME


def check_pose_name(name: str) -> str:
    """``name`` if it is a valid pose name, else ConfigError saying the rule."""
    if not (isinstance(name, str) and len(name) <= NAME_MAX_CHARS and _NAME.fullmatch(name)):
        raise ConfigError(f"pose name {name!r} is not valid: {NAME_RULE}")
    return name


def load_saved_poses(folder: Path, config: ArmConfig) -> dict[str, tuple[float, ...]]:
    """The poses saved in ``folder`` (none if there is no file yet)."""
    path = poses_file(folder)
    if not path.exists():
        return {}
    data, where = read_versioned_json(path, "pose file", FORMAT_NAME, FORMAT_VERSION)
    names = [j.name for j in config.joints]
    if data.get("joints") != names:
        raise ConfigError(f"{where} was saved for joints {data.get('joints')!r}; this arm "
                          f"({config.name}) has {names}: move it aside to start a new one")
    poses = data.get("poses")
    if not isinstance(poses, dict):
        raise ConfigError(f"{where}: key 'poses' must be an object of name: [5 angles in deg]")
    out: dict[str, tuple[float, ...]] = {}
    for name, angles in poses.items():
        try:
            check_pose_name(name)
            out[name] = config.check_joints(angles)
        except ConfigError as exc:
            raise ConfigError(f"{where}: pose {name!r}: {exc}") from None
    return out


def list_poses(folder: Path, config: ArmConfig) -> list[NamedPose]:
    """Every pose: the arm config's built-in ones first, then the saved ones by name."""
    builtin = [NamedPose(n, q, True) for n, q in config.poses_deg.items()]
    saved = load_saved_poses(folder, config)
    return builtin + [NamedPose(n, saved[n], False) for n in sorted(saved)]


def find_pose(folder: Path, config: ArmConfig, name: str) -> NamedPose:
    """The pose called ``name`` (built-in or saved); ConfigError listing them if none."""
    poses = list_poses(folder, config)
    for p in poses:
        if p.name == name:
            return p
    raise ConfigError(f"no pose named {name!r}; poses: {', '.join(p.name for p in poses)} "
                      "(`busarm arm poses` lists them)")


def save_pose(folder: Path, config: ArmConfig, name: str, joints_deg: Sequence[float]) -> bool:
    """Save ``joints_deg`` as ``name`` (creating ``folder``); True if it replaced one.

    A built-in name, an invalid name or angles outside the joint limits raise
    ConfigError and leave the file as it was.
    """
    check_savable_name(config, name)
    joints = config.check_joints(joints_deg)
    saved = load_saved_poses(folder, config)
    replaced = name in saved
    saved[name] = joints
    _write(folder, config, saved)
    return replaced


def check_savable_name(config: ArmConfig, name: str) -> str:
    """``name`` if a pose may be saved under it: valid, and not one of the arm config's."""
    _check_not_builtin(config, check_pose_name(name), "overwritten")
    return name


def delete_pose(folder: Path, config: ArmConfig, name: str) -> None:
    """Forget the saved pose ``name``; ConfigError for a built-in or unknown one."""
    _check_not_builtin(config, name, "deleted")
    saved = load_saved_poses(folder, config)
    if name not in saved:
        raise ConfigError(f"no saved pose named {name!r}; saved: "
                          f"{', '.join(sorted(saved)) or 'none'}")
    del saved[name]
    _write(folder, config, saved)


def _check_not_builtin(config: ArmConfig, name: str, what: str) -> None:
    if name in config.poses_deg:
        raise ConfigError(f"pose {name!r} is built into the arm config ({config.source}) and "
                          f"cannot be {what}"
                          + (": choose another name" if what == "overwritten" else ""))


def _write(folder: Path, config: ArmConfig, poses: dict[str, tuple[float, ...]]) -> None:
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(
            f"cannot create the pose folder {folder}: {exc.strerror or exc}"
        ) from None
    head = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "arm": config.name,
            "joints": [j.name for j in config.joints]}
    # One line per pose, so that the file reads (and diffs) as a table.
    rows = ",\n".join(f"    {json.dumps(n)}: {json.dumps([round(a, 3) for a in poses[n]])}"
                      for n in sorted(poses))
    text = json.dumps(head)[:-1] + ', "poses": {\n' + rows + ("\n" if rows else "") + "}}\n"
    write_text_atomic(poses_file(folder), text, "pose file")


__all__ = [
    "FILE_NAME",
    "NamedPose",
    "check_pose_name",
    "check_savable_name",
    "delete_pose",
    "find_pose",
    "list_poses",
    "load_saved_poses",
    "poses_file",
    "save_pose",
]
