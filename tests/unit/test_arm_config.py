"""The arm's TOML description: the shipped JetAuto Pro arm, an ArmPi-style arm, bad files.

Expected values are the facts in shared/reference/field-notes.md section 1 (servo IDs,
the DH table's joint ranges, link lengths, the vendor's start pose in pulses, 500 pulses
= straight up, 0.24 deg per pulse, pulses flipped), written out here rather than read
back from busarm.
"""

from __future__ import annotations

import copy
import importlib.resources
import json
import math
import re
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from busarm.arm.config import (
    ArmConfig,
    arm_config_from_toml,
    load_arm_config,
)
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, LimitError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

DATA = Path(__file__).resolve().parent.parent / "data"
ARMPI = DATA / "armpi_style.toml"

# Field notes, section 1.
JETAUTO_JOINT_IDS = (1, 2, 3, 4, 5)
JETAUTO_GRIPPER_ID = 10
JETAUTO_LIMITS = ((-120.0, 120.0), (-180.0, 0.0), (-120.0, 120.0), (-200.0, 20.0), (-120.0, 120.0))
VENDOR_START_PULSES = (500, 750, 0, 375, 500)
UPRIGHT_DEG = (0.0, -90.0, 0.0, -90.0, 0.0)


def shipped_text() -> str:
    return (importlib.resources.files("busarm.arm") / "configs" / "jetauto_pro.toml").read_text(
        encoding="utf-8"
    )


# ------------------------------------------------------------------ the shipped arm


@pytest.fixture(scope="module")
def jetauto() -> ArmConfig:
    return load_arm_config("jetauto_pro")


def test_default_arm_is_the_shipped_jetauto(jetauto: ArmConfig) -> None:
    assert load_arm_config() == jetauto
    assert "jetauto_pro" in jetauto.source


def test_jetauto_servo_ids(jetauto: ArmConfig) -> None:
    assert jetauto.joint_ids == JETAUTO_JOINT_IDS
    assert jetauto.gripper.servo_id == JETAUTO_GRIPPER_ID
    assert jetauto.servo_ids == (1, 2, 3, 4, 5, 10)
    assert jetauto.action_columns == (1, 2, 3, 4, 5, 10)


def test_jetauto_limits_are_the_dh_table_ranges(jetauto: ArmConfig) -> None:
    assert jetauto.limits_deg == JETAUTO_LIMITS


def test_jetauto_geometry(jetauto: ArmConfig) -> None:
    g = jetauto.geometry
    assert (g.base_height_mm, g.upper_arm_mm, g.forearm_mm) == (197.4, 130.0, 130.0)
    assert (g.wrist_mm, g.tool_mm) == (55.0, 117.0)
    assert g.wrist_to_tip_mm == 172.0  # "tip 172 mm past joint 4"
    assert g.upper_arm_mm + g.forearm_mm + g.wrist_to_tip_mm == 432.0  # fully stretched
    assert jetauto.table_z_mm == 0.0
    assert jetauto.preferred_pitch_deg == -90.0


def test_jetauto_upright_pose_is_500_pulses_everywhere(jetauto: ArmConfig) -> None:
    assert jetauto.pose("upright") == UPRIGHT_DEG
    for joint, angle in zip(jetauto.joints, UPRIGHT_DEG, strict=True):
        assert joint.pulses_from_angle_deg(angle) == pytest.approx(500.0, abs=1e-9), joint.name


def test_jetauto_home_pose_is_the_vendor_start_pose(jetauto: ArmConfig) -> None:
    home = jetauto.pose("home")
    pulses = [j.pulses_from_angle_deg(a) for j, a in zip(jetauto.joints, home, strict=True)]
    assert pulses == pytest.approx(VENDOR_START_PULSES, abs=1e-9)
    back = [j.angle_deg_from_pulses(p) for j, p in zip(jetauto.joints, VENDOR_START_PULSES,
                                                        strict=True)]
    assert back == pytest.approx(home, abs=1e-9)


def test_jetauto_pulse_map_is_flipped_at_0_24_deg_per_pulse(jetauto: ArmConfig) -> None:
    for joint, angle in zip(jetauto.joints, UPRIGHT_DEG, strict=True):
        # One pulse more is 0.24 deg less: "pulse 1000 is the joint's minimum" side.
        assert joint.angle_deg_from_pulses(501) - angle == pytest.approx(-0.24, abs=1e-12)
        assert joint.pulses_from_angle_deg(angle + 24.0) == pytest.approx(400.0, abs=1e-9)
        assert joint.servo_deg_from_angle_deg(angle + 24.0) == pytest.approx(-24.0, abs=1e-12)
        assert joint.angle_deg_from_servo_deg(-24.0) == pytest.approx(angle + 24.0, abs=1e-12)
    # Base yaw, elbow and roll: the limits are the servo's whole 0..1000 range.
    for number in (1, 3, 5):
        j = jetauto.joint(number)
        assert j.pulses_from_angle_deg(j.min_deg) == pytest.approx(1000.0, abs=1e-9)
        assert j.pulses_from_angle_deg(j.max_deg) == pytest.approx(0.0, abs=1e-9)


def test_jetauto_gripper(jetauto: ArmConfig) -> None:
    g = jetauto.gripper
    assert (g.open_pulses, g.closed_pulses) == (200, 700)
    assert (g.min_pulses, g.max_pulses) == (200, 700)
    g.check_pulses(540)
    with pytest.raises(LimitError, match="outside 200..700"):
        g.check_pulses(701)
    with pytest.raises(ConfigError, match="whole pulses"):
        g.check_pulses(540.0)  # type: ignore[arg-type]


def test_joint_lookup_and_checks(jetauto: ArmConfig) -> None:
    assert jetauto.joint(1).name == "base_yaw"
    assert jetauto.joint("wrist_roll").servo_id == 5
    with pytest.raises(ConfigError, match="out of range 1..5"):
        jetauto.joint(6)
    with pytest.raises(ConfigError, match="no joint named 'elbow'"):
        jetauto.joint("elbow")
    with pytest.raises(ConfigError, match="no pose named 'ready'"):
        jetauto.pose("ready")
    assert jetauto.check_joints([0, -90, 0, -90, 0]) == UPRIGHT_DEG
    with pytest.raises(LimitError, match=r"elbow_pitch = 121\.000 deg .* -120\.\.120"):
        jetauto.check_joints((0, -90, 121, -90, 0))
    with pytest.raises(LimitError, match="wrist_pitch"):
        jetauto.check_joints((0, -90, 0, math.nan, 0))
    with pytest.raises(ConfigError, match="expected 5 joint angles"):
        jetauto.check_joints((0, -90, 0, -90))
    with pytest.raises(ConfigError, match="must be a number"):
        jetauto.check_joints((0, -90, "0", -90, 0))
    with pytest.raises(ConfigError, match="must be 5 numbers"):
        jetauto.check_joints("0,0,0,0,0")


# ------------------------------------------------------------------ an ArmPi-style arm


@pytest.fixture(scope="module")
def armpi() -> ArmConfig:
    return load_arm_config(ARMPI)


def test_armpi_style_arm_loads_from_its_file(armpi: ArmConfig) -> None:
    assert armpi.name == "ArmPi-style test arm"
    assert armpi.source == str(ARMPI)
    assert armpi.joint_ids == (6, 5, 4, 3, 2)
    assert armpi.gripper.servo_id == 1
    assert armpi.servo_ids == (6, 5, 4, 3, 2, 1)
    assert armpi.action_columns == (1, 2, 3, 4, 5, 6)
    g = armpi.geometry
    assert (g.base_height_mm, g.upper_arm_mm, g.forearm_mm, g.wrist_mm, g.tool_mm) == (
        120.0, 101.6, 96.4, 0.0, 166.0
    )
    assert armpi.limits_deg == (
        (-110.0, 110.0), (-175.0, -5.0), (-100.0, 115.0), (-200.0, 30.0), (-100.0, 120.0)
    )
    assert armpi.table_z_mm == -10.0
    assert armpi.preferred_pitch_deg == -80.0
    assert set(armpi.poses_deg) == {"home", "upright", "ready"}
    assert (armpi.gripper.min_pulses, armpi.gripper.max_pulses) == (100, 650)


def test_armpi_style_pulse_map(armpi: ArmConfig) -> None:
    # pulses = 500 + direction * (angle - angle_at_center) / 0.24, with this file's numbers.
    upright = armpi.pose("upright")
    expected = (500.0, 500.0, 500.0, 500.0 - 10.0 / 0.24, 500.0 - 10.0 / 0.24)
    got = [j.pulses_from_angle_deg(a) for j, a in zip(armpi.joints, upright, strict=True)]
    assert got == pytest.approx(expected, abs=1e-9)
    ready = armpi.pose("ready")  # 30, -60, 90, -120, 45
    expected = (
        500 + 30 / 0.24, 500 + 30 / 0.24, 500 - 90 / 0.24, 500 - 40 / 0.24, 500 + 35 / 0.24,
    )
    got = [j.pulses_from_angle_deg(a) for j, a in zip(armpi.joints, ready, strict=True)]
    assert got == pytest.approx(expected, abs=1e-9)
    for j, a in zip(armpi.joints, ready, strict=True):
        assert j.angle_deg_from_pulses(j.pulses_from_angle_deg(a)) == pytest.approx(a, abs=1e-9)


def test_armpi_style_kinematics_use_its_geometry(armpi: ArmConfig) -> None:
    kin = ArmKinematics.from_config(armpi)
    assert kin.max_reach_mm == pytest.approx(101.6 + 96.4 + 166.0)
    up = kin.fk(armpi.pose("upright"))
    assert (up.x_mm, up.y_mm, up.z_mm, up.pitch_deg) == pytest.approx(
        (0.0, 0.0, 120.0 + 101.6 + 96.4 + 166.0, 90.0), abs=1e-9
    )
    assert kin.joint_names == ("yaw", "shoulder", "elbow", "wrist", "roll")
    assert kin.table_z_mm == -10.0


@pytest.mark.parametrize(
    ("arm", "pose"),
    [("jetauto_pro", "home"), ("jetauto_pro", "upright"),
     (str(ARMPI), "home"), (str(ARMPI), "upright"), (str(ARMPI), "ready")],
)
def test_named_poses_round_trip_through_ik(arm: str, pose: str) -> None:
    cfg = load_arm_config(arm)
    q = cfg.pose(pose)
    kin = ArmKinematics.from_config(cfg)
    target = kin.fk_matrix(q)
    sols = kin.ik(*kin.fk(q), current_deg=q)
    assert sols, f"{cfg.name}: no IK solution for its own {pose} pose {q}"
    assert abs(kin.fk_matrix(sols[0]) - target).max() < 1e-6
    assert sols[0] == pytest.approx(q, abs=1e-5)


# ------------------------------------------------------------------ bad files


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(v)


def dump_toml(data: dict[str, Any]) -> str:
    """A minimal TOML writer for the shapes an arm file has."""
    lines: list[str] = []
    tables: list[tuple[str, dict[str, Any]]] = []
    arrays: list[tuple[str, list[dict[str, Any]]]] = []
    for key, value in data.items():
        if isinstance(value, dict):
            tables.append((key, value))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            arrays.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, table in tables:
        lines.append(f"\n[{key}]")
        lines.extend(f"{k} = {_toml_value(v)}" for k, v in table.items())
    for key, items in arrays:
        for item in items:
            lines.append(f"\n[[{key}]]")
            lines.extend(f"{k} = {_toml_value(v)}" for k, v in item.items())
    return "\n".join(lines) + "\n"


def base_data() -> dict[str, Any]:
    return copy.deepcopy(tomllib.loads(shipped_text()))


def test_the_toml_writer_reproduces_the_shipped_arm(tmp_path: Path) -> None:
    path = tmp_path / "copy.toml"
    path.write_text(dump_toml(base_data()), encoding="utf-8")
    copy_ = load_arm_config(path)
    shipped = load_arm_config("jetauto_pro")
    assert copy_.__dict__ | {"source": ""} == shipped.__dict__ | {"source": ""}


Mutation = Callable[[dict[str, Any]], None]


def _set(*path: Any, value: Any) -> Mutation:
    def mutate(d: dict[str, Any]) -> None:
        for p in path[:-1]:
            d = d[p]
        d[path[-1]] = value
    return mutate


def _del(*path: Any) -> Mutation:
    def mutate(d: dict[str, Any]) -> None:
        for p in path[:-1]:
            d = d[p]
        del d[path[-1]]
    return mutate


def _both(*mutations: Mutation) -> Mutation:
    def mutate(d: dict[str, Any]) -> None:
        for m in mutations:
            m(d)
    return mutate


# (id, mutation, fragments the message must contain besides the file's path)
BAD_CONFIGS: list[tuple[str, Mutation, tuple[str, ...]]] = [
    ("missing geometry", _del("geometry"), ("geometry: missing table",)),
    ("missing gripper", _del("gripper"), ("gripper: missing table",)),
    ("geometry not a table", _set("geometry", value=5), ("geometry: must be a table",)),
    ("workspace not a table", _set("workspace", value=[1]), ("workspace: must be a table",)),
    ("missing joints", _del("joints"), ("joints: need exactly 5",)),
    ("four joints", lambda d: d["joints"].pop(), ("joints: need exactly 5",)),
    ("format", _set("format", value="busarm.robot"), ("format: must be 'busarm.arm'",
                                                      "'busarm.robot'")),
    ("no format", _del("format"), ("format:", "None")),
    ("version 2", _set("version", value=2), ("version: 2", "reads version 1")),
    ("version string", _set("version", value="1"), ("version: '1'",)),
    ("empty name", _set("name", value="  "), ("name: must be a non-empty string",)),
    ("unknown top-level key", _set("colour", value="red"), ("top level", "unknown key(s) colour;")),
    ("unknown geometry key", _set("geometry", "elbow_offset_mm", value=3.0),
     ("geometry: unknown key(s) elbow_offset_mm;",)),
    ("unknown workspace key", _set("workspace", "table_height", value=0.0),
     ("workspace: unknown key(s) table_height;",)),
    ("unknown joint key", _set("joints", 1, "speed", value=3),
     ("joints[2] (shoulder pitch): unknown key(s) speed;",)),
    ("unknown gripper key", _set("gripper", "force", value=3),
     ("gripper: unknown key(s) force;",)),
    ("unknown action_groups key", _set("action_groups", "rows", value=3),
     ("action_groups: unknown key(s) rows;",)),
    ("base limit beyond 1000 pulses", _set("joints", 0, "min_deg", value=-125.0),
     ("joints[1] (base yaw)", "-125 deg maps to 1020.8 pulses", "0..1000")),
    ("wrist limit below 0 pulses", _set("joints", 3, "max_deg", value=40.0),
     ("joints[4] (wrist pitch)", "40 deg maps to -41.7 pulses")),
    ("duplicate gripper id", _set("gripper", "servo_id", value=3),
     ("servo_id", "distinct", "[1, 2, 3, 4, 5, 3]")),
    ("duplicate joint id", _set("joints", 4, "servo_id", value=1),
     ("servo_id", "[1, 2, 3, 4, 1, 10]")),
    ("servo id 254", _set("joints", 0, "servo_id", value=254),
     ("joints[1] (base yaw).servo_id", "254 is out of range 0..253")),
    ("servo id float", _set("joints", 0, "servo_id", value=1.0),
     ("joints[1] (base yaw).servo_id", "must be an integer")),
    ("servo id bool", _set("gripper", "servo_id", value=True),
     ("gripper.servo_id", "must be an integer, got true")),
    ("direction 0", _set("joints", 0, "direction", value=0),
     ("joints[1] (base yaw).direction", "must be 1 or -1, got 0")),
    ("direction 2", _set("joints", 2, "direction", value=2),
     ("joints[3] (elbow pitch).direction", "got 2")),
    ("direction bool", _set("joints", 2, "direction", value=True),
     ("joints[3] (elbow pitch).direction", "got true")),
    ("direction missing", _del("joints", 4, "direction"),
     ("joints[5] (wrist roll).direction", "got nothing")),
    ("min == max", _both(_set("joints", 2, "min_deg", value=30.0),
                         _set("joints", 2, "max_deg", value=30.0)),
     ("joints[3] (elbow pitch)", "min_deg 30 must be less than max_deg 30")),
    ("min > max", _both(_set("joints", 1, "min_deg", value=-10.0),
                        _set("joints", 1, "max_deg", value=-20.0)),
     ("joints[2] (shoulder pitch)", "min_deg -10 must be less than max_deg -20")),
    ("missing limit", _del("joints", 1, "max_deg"),
     ("joints[2] (shoulder pitch).max_deg", "missing")),
    ("NaN length", _set("geometry", "base_height_mm", value=math.nan),
     ("geometry.base_height_mm", "must be a number, got nan")),
    ("bool length", _set("geometry", "upper_arm_mm", value=True),
     ("geometry.upper_arm_mm", "must be a number, got true")),
    ("string length", _set("geometry", "forearm_mm", value="130"),
     ("geometry.forearm_mm", "must be a number, got '130'")),
    ("zero length", _set("geometry", "tool_mm", value=0.0), ("geometry.tool_mm", "must be > 0")),
    ("negative length", _set("geometry", "wrist_mm", value=-1.0),
     ("geometry.wrist_mm", "out of range 0..2000")),
    ("NaN angle", _set("joints", 1, "angle_at_center_deg", value=math.nan),
     ("joints[2] (shoulder pitch).angle_at_center_deg", "must be a number")),
    ("string angle", _set("joints", 1, "min_deg", value="-180"),
     ("joints[2] (shoulder pitch).min_deg", "must be a number, got '-180'")),
    ("zero speed", _set("joints", 1, "max_speed_deg_s", value=0),
     ("joints[2] (shoulder pitch).max_speed_deg_s", "out of range 1..1000")),
    ("NaN table", _set("workspace", "table_z_mm", value=math.nan),
     ("workspace.table_z_mm", "must be a number")),
    ("pitch out of range", _set("workspace", "preferred_pitch_deg", value=270.0),
     ("workspace.preferred_pitch_deg", "270.0 is out of range -180..180")),
    ("duplicate joint names", _set("joints", 1, "name", value="base_yaw"),
     ("joints[2] (shoulder pitch).name", "distinct", "'base_yaw'")),
    ("base not above elbow", _set("geometry", "base_height_mm", value=130.0),
     ("geometry.base_height_mm", "must exceed upper_arm_mm 130")),
    ("home pose outside limits", _set("poses", "home_deg", value=[0.0, -150.0, 130.0, -60.0, 0]),
     ("poses.home_deg", "elbow_pitch = 130.000 deg", "-120..120")),
    ("pose NaN", _set("poses", "upright_deg", value=[0.0, -90.0, 0.0, math.nan, 0.0]),
     ("poses.upright_deg", "wrist_pitch")),
    ("pose too short", _set("poses", "upright_deg", value=[0.0, -90.0, 0.0, -90.0]),
     ("poses.upright_deg", "must be 5 numbers")),
    ("pose with a string", _set("poses", "upright_deg", value=[0.0, -90.0, "0", -90.0, 0.0]),
     ("poses.upright_deg", "must be 5 numbers")),
    ("pose with a bool", _set("poses", "upright_deg", value=[0.0, -90.0, True, -90.0, 0.0]),
     ("poses.upright_deg", "must be 5 numbers")),
    ("pose name without _deg", _set("poses", "ready", value=[0.0, -90.0, 0.0, -90.0, 0.0]),
     ("poses.ready", "end in _deg")),
    ("missing home pose", _del("poses", "home_deg"), ("poses.home_deg", "missing")),
    ("missing poses table", _del("poses"), ("poses.home_deg", "missing")),
    ("poses not a table", _set("poses", value=3), ("poses: must be a table",)),
    ("gripper open == closed", _set("gripper", "closed_pulses", value=200),
     ("gripper:", "open_pulses 200 and closed_pulses 200")),
    ("gripper within margin", _set("gripper", "closed_pulses", value=215),
     ("gripper:", "holding_margin_pulses 20")),
    ("gripper beyond 1000", _set("gripper", "open_pulses", value=1200),
     ("gripper.open_pulses", "1200 is out of range 0..1000")),
    ("gripper time NaN", _set("gripper", "grip_time_s", value=math.nan),
     ("gripper.grip_time_s", "must be a number")),
    ("columns: unknown id", _set("action_groups", "columns", value=[1, 2, 3, 4, 5, 7]),
     ("action_groups.columns", "distinct servo IDs of this arm", "[1, 2, 3, 4, 5, 10]")),
    ("columns: duplicate", _set("action_groups", "columns", value=[1, 2, 2]),
     ("action_groups.columns", "[1, 2, 2]")),
    ("columns: empty", _set("action_groups", "columns", value=[]),
     ("action_groups.columns", "must be a list of servo IDs")),
    ("columns: strings", _set("action_groups", "columns", value=["1", "2"]),
     ("action_groups.columns", "must be a list of servo IDs")),
    ("columns: bools", _set("action_groups", "columns", value=[True]),
     ("action_groups.columns", "must be a list of servo IDs")),
    ("columns: not a list", _set("action_groups", "columns", value=10),
     ("action_groups.columns", "must be a list of servo IDs")),
    ("action_groups not a table", _set("action_groups", value=[1, 2]),
     ("action_groups: must be a table",)),
]


@pytest.mark.parametrize(
    ("mutation", "fragments"), [pytest.param(m, f, id=i) for i, m, f in BAD_CONFIGS]
)
def test_bad_config_names_the_file_and_the_key(
    tmp_path: Path, mutation: Mutation, fragments: tuple[str, ...]
) -> None:
    data = base_data()
    mutation(data)
    path = tmp_path / "bad_arm.toml"
    path.write_text(dump_toml(data), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_arm_config(path)
    message = str(info.value)
    assert message.startswith(f"arm config {path}: "), message
    for fragment in fragments:
        assert fragment in message, f"{fragment!r} not in {message!r}"


def test_the_unmutated_base_loads(tmp_path: Path) -> None:
    """The bad-config cases fail because of their mutation, not the writer."""
    path = tmp_path / "good_arm.toml"
    path.write_text(dump_toml(base_data()), encoding="utf-8")
    assert load_arm_config(path).joint_ids == JETAUTO_JOINT_IDS


def test_not_toml(tmp_path: Path) -> None:
    path = tmp_path / "arm.toml"
    path.write_text("format = busarm.arm\n[[joints]\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=rf"arm config {path}: not valid TOML"):
        load_arm_config(path)
    with pytest.raises(ConfigError, match=r"arm config <string>: not valid TOML"):
        arm_config_from_toml("= 1")


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.toml"
    with pytest.raises(ConfigError, match=rf"arm config {path}: no such file.*jetauto_pro"):
        load_arm_config(path)
    with pytest.raises(ConfigError, match="no such file"):
        load_arm_config("jetauto_pro_v2")  # not a shipped name: read as a path


def test_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=rf"arm config {tmp_path}: cannot read it"):
        load_arm_config(tmp_path)  # a directory
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'name = "caf\xe9"\n')
    with pytest.raises(ConfigError, match=rf"arm config {path}: cannot read it"):
        load_arm_config(path)


def test_from_toml_names_the_given_source() -> None:
    text = shipped_text().replace("servo_id = 10", "servo_id = 5")
    with pytest.raises(ConfigError, match=r"^arm config my-arm: servo_id: .*\[1, 2, 3, 4, 5, 5\]"):
        arm_config_from_toml(text, "my-arm")


def test_gripper_gap_maps_to_pulses() -> None:
    g = load_arm_config().gripper
    assert g.gap_mm_per_pulse == 0.1875
    assert g.pulses_for_gap_mm(0.0) == g.closed_pulses
    assert g.pulses_for_gap_mm(30.0) == 540  # field notes: about 540 on a 3 cm block
    assert g.pulses_for_gap_mm(1000.0) == g.open_pulses  # never past open
    with pytest.raises(ConfigError, match="gap"):
        g.pulses_for_gap_mm(-1.0)
    # ... and back: what a reading means.
    assert g.gap_mm_at(540) == pytest.approx(30.0)
    assert g.gap_mm_at(g.closed_pulses) == 0.0
    assert g.gap_mm_at(g.closed_pulses + 20) == 0.0  # squeezed past touching: still 0
    for gap in (0.0, 12.5, 30.0, 50.0):
        assert gap <= g.gap_mm_at(g.pulses_for_gap_mm(gap)) < gap + g.gap_mm_per_pulse


def test_the_camera_mount_is_part_of_the_arm_config() -> None:
    import numpy as np

    from busarm.arm.camera_mount import CameraMount
    from busarm.arm.config import arm_config_from_toml, load_arm_config

    cfg = load_arm_config()
    assert cfg.camera is not None
    assert (cfg.camera.link, cfg.camera.behind_mm, cfg.camera.above_mm) == (
        "wrist_pitch", 51.0, 64.0)
    mount = CameraMount.from_config(cfg.camera)
    # Frame 4: "above" is +x, the tool axis +y; the camera looks along the tool.
    np.testing.assert_allclose(mount.cam2link[:3, 3], [64.0, -51.0, 0.0])
    np.testing.assert_allclose(mount.cam2link[:3, 2], [0.0, 1.0, 0.0], atol=1e-12)
    text = (importlib.resources.files("busarm.arm") / "configs" / "jetauto_pro.toml"
            ).read_text(encoding="utf-8")
    for old, new, message in (
        ('link = "wrist_pitch"', 'link = "elbow_pitch"',
         "camera.link: 'elbow_pitch'; the wrist camera rides the wrist pitch joint's link"),
        ("behind_mm = 51.0", "behind_mm = 510.0", "camera.behind_mm = 510.0 is out of range"),
        ("tilt_deg = 0.0", "tilt_deg = 0.0\nzoom = 2", "camera: unknown key(s) zoom;"),
    ):
        with pytest.raises(ConfigError, match=re.escape(message)):
            arm_config_from_toml(text.replace(old, new))
    without = text[: text.index("[camera]")] + text[text.index("[action_groups]"):]
    assert arm_config_from_toml(without).camera is None
    with pytest.raises(ConfigError, match=r"has no \[camera\]"):
        CameraMount.from_config(None)
