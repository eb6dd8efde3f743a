"""A URDF description of the arm, generated from its config (for RViz, PyBullet, MoveIt...).

Links ``base_link``, ``<joint name>_link`` for the five joints and a fixed ``tool`` link
at the tool point; revolute joints named after the config's joints, each about its z
axis. Joint ``i`` sits at the modified-DH row ``(alpha(i-1), a(i-1), d(i))`` of
:meth:`ArmKinematics.dh_table`: ``Rx(alpha) Tx(a) Rz(theta) Tz(d)`` equals the URDF
``origin xyz = (a, -d sin alpha, d cos alpha)``, ``rpy = (alpha, 0, 0)`` followed by the
rotation ``theta`` about z, so the URDF's forward kinematics is the model's, and its
joint angles are busarm's joint angles (radians instead of degrees).

Lengths are in metres here (the URDF convention), millimetres everywhere else in busarm.
Geometry is boxes and cylinders sized from the link lengths; masses are rough guesses.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from busarm.arm.config import ArmConfig, Geometry, JointConfig
from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.version import __version__

KG_CM_TO_NM = 9.80665 / 100.0
SERVO_TORQUE_KG_CM = 35.0
"""Stall torque of the joint servos (LX 35 kg·cm class): the URDF effort limit."""
JOINT_EFFORT_NM = SERVO_TORQUE_KG_CM * KG_CM_TO_NM  # 3.432 N·m
LINK_WIDTH_M = 0.04
"""Width of the box/cylinder shapes standing in for the links."""
MIN_SHAPE_M = 0.01
"""Shortest shape, for links of zero length (a zero-size shape upsets some viewers)."""
BASE_LINK = "base_link"
TOOL_LINK = "tool"
TOOL_JOINT = "tool_joint"

# Rough masses in kg (a 35 kg·cm LX servo weighs about 65 g; brackets and the gripper add
# to it). Nobody weighed the parts: good enough for a simulator to load the model, not for
# dynamics or gravity compensation.
_MASS_KG = {
    BASE_LINK: 0.60,
    1: 0.15,  # base yaw turret + shoulder servo
    2: 0.15,  # upper arm + elbow servo
    3: 0.12,  # forearm + wrist pitch servo
    4: 0.08,  # wrist bracket + wrist roll servo
    5: 0.15,  # gripper with its servo
    TOOL_LINK: 0.001,
}


def link_names(config: ArmConfig) -> list[str]:
    """The URDF link names: base_link, one per joint, then the tool link."""
    return [BASE_LINK, *(f"{j.name}_link" for j in config.joints), TOOL_LINK]


def urdf_from_config(config: ArmConfig) -> str:
    """The URDF (XML text) of ``config``'s arm: five revolute joints and a tool frame."""
    from busarm.arm.kinematics import ArmKinematics  # numpy stays out of a bare import

    links = link_names(config)
    _check_names(config, links)
    g = config.geometry
    dh = ArmKinematics.from_config(config, check_table=False).dh_table()

    robot = ET.Element("robot", name=_robot_name(config.name))
    material = ET.SubElement(robot, "material", name="busarm_grey")
    ET.SubElement(material, "color", rgba="0.6 0.6 0.65 1")
    robot.append(ET.Comment(
        " Inertial blocks are ROUGH GUESSES (masses guessed, shapes as uniform solids) so "
        "that physics tools load the model; do not use them for dynamics. "
    ))

    # The base: a column from the base plane up to the shoulder axis.
    h = _m(g.base_height_mm)
    _add_link(robot, BASE_LINK, _MASS_KG[BASE_LINK],
              _cylinder(radius=0.05, length=h, xyz=(0.0, 0.0, h / 2)))
    shapes = _joint_shapes(g)
    parent = BASE_LINK
    for i, (joint, row) in enumerate(zip(config.joints, dh, strict=True), 1):
        child = links[i]
        _add_link(robot, child, _MASS_KG[i], shapes[i])
        _add_joint(robot, joint, row, parent, child)
        parent = child

    _add_link(robot, TOOL_LINK, _MASS_KG[TOOL_LINK], None)
    el = ET.SubElement(robot, "joint", name=TOOL_JOINT, type="fixed")
    ET.SubElement(el, "origin", xyz=_vec((0.0, 0.0, _m(g.tool_mm))), rpy="0 0 0")
    ET.SubElement(el, "parent", link=parent)
    ET.SubElement(el, "child", link=TOOL_LINK)

    ET.indent(robot, space="  ")
    body = ET.tostring(robot, encoding="unicode")
    return f'<?xml version="1.0" encoding="utf-8"?>\n<!--{_comment(_header(config))}-->\n{body}\n'


def write_urdf(config: ArmConfig, path: Path | str) -> Path:
    """Write ``config``'s URDF to ``path`` atomically; returns the path."""
    path = Path(path)
    write_text_atomic(path, urdf_from_config(config), "URDF")
    return path


# ---------------------------------------------------------------------- helpers

_Shape = tuple[str, dict[str, str], tuple[float, float, float], tuple[float, float, float],
               tuple[float, float, float]]
"""(geometry tag, its attributes, xyz, rpy, inertia diagonal per kg)."""


def _check_names(config: ArmConfig, links: list[str]) -> None:
    """ConfigError if two links or joints would share a URDF name."""
    joint_names = [j.name for j in config.joints] + [TOOL_JOINT]
    names = links + joint_names
    clash = sorted({n for n in names if names.count(n) > 1})
    if clash:
        raise ConfigError(
            f"arm config {config.source}: joint names {[j.name for j in config.joints]} give "
            f"duplicate URDF link/joint names {clash}; rename the joints"
        )


def _header(config: ArmConfig) -> str:
    """The comment at the top of the file: where it came from and what its limits assume."""
    return (
        f" {config.name}: generated by busarm {__version__} from the arm config "
        f"{config.source}. Edit the config and regenerate rather than editing this file. "
        f"Joint angles are busarm's modified-DH thetas; lengths in metres. Effort limits "
        f"assume {SERVO_TORQUE_KG_CM:g} kg·cm servos ({JOINT_EFFORT_NM:.3f} N·m); "
        f"velocity limits are the config's max_speed_deg_s. "
    )


def _joint_shapes(g: Geometry) -> dict[int, _Shape]:
    """The shape of each joint's link, in that joint's own frame (after its rotation)."""
    return {
        1: _box((0.06, 0.06, 0.04), xyz=(0.0, 0.0, -0.02)),  # turret under the shoulder
        2: _box((_m(g.upper_arm_mm), LINK_WIDTH_M, LINK_WIDTH_M), xyz=(_m(g.upper_arm_mm) / 2,
                                                                       0.0, 0.0)),
        3: _box((_m(g.forearm_mm), LINK_WIDTH_M, LINK_WIDTH_M), xyz=(_m(g.forearm_mm) / 2,
                                                                     0.0, 0.0)),
        # Frame 4 to the wrist roll joint: d5 along frame 4's +y (alpha(4) = -90 deg).
        4: _cylinder(radius=LINK_WIDTH_M / 2, length=_m(g.wrist_mm),
                     xyz=(0.0, _m(g.wrist_mm) / 2, 0.0), rpy=(math.pi / 2, 0.0, 0.0)),
        5: _cylinder(radius=LINK_WIDTH_M / 2, length=_m(g.tool_mm),
                     xyz=(0.0, 0.0, _m(g.tool_mm) / 2)),
    }


def _add_joint(
    robot: ET.Element, joint: JointConfig, dh_row: tuple[float, float, float], parent: str,
    child: str,
) -> None:
    """A revolute joint at its modified-DH row ``(alpha, a mm, d mm)``, with its limits."""
    alpha, a_mm, d_mm = dh_row
    el = ET.SubElement(robot, "joint", name=joint.name, type="revolute")
    a, d = _m(a_mm), _m(d_mm)
    ET.SubElement(el, "origin", xyz=_vec((a, -d * math.sin(alpha), d * math.cos(alpha))),
                  rpy=_vec((alpha, 0.0, 0.0)))
    ET.SubElement(el, "parent", link=parent)
    ET.SubElement(el, "child", link=child)
    ET.SubElement(el, "axis", xyz="0 0 1")
    ET.SubElement(el, "limit", lower=_num(math.radians(joint.min_deg)),
                  upper=_num(math.radians(joint.max_deg)), effort=_num(JOINT_EFFORT_NM),
                  velocity=_num(math.radians(joint.max_speed_deg_s)))


def _m(mm: float) -> float:
    return mm / 1000.0


def _num(v: float) -> str:
    if abs(v) < 1e-15:
        v = 0.0  # cos(pi/2) rounding, and no "-0"
    return repr(float(v))


def _vec(v: tuple[float, float, float]) -> str:
    return " ".join(_num(x) for x in v)


def _comment(text: str) -> str:
    """Text safe inside an XML comment (no ``--``, no trailing ``-``)."""
    while "--" in text:
        text = text.replace("--", "- -")
    return text + " " if text.endswith("-") else text


def _robot_name(name: str) -> str:
    out = re.sub(r"[^0-9a-z]+", "_", name.lower()).strip("_")
    return out or "busarm_arm"


def _box(size: tuple[float, float, float], *, xyz: tuple[float, float, float]) -> _Shape:
    sx, sy, sz = (max(s, MIN_SHAPE_M) for s in size)
    per_kg = ((sy * sy + sz * sz) / 12, (sx * sx + sz * sz) / 12, (sx * sx + sy * sy) / 12)
    return "box", {"size": _vec((sx, sy, sz))}, xyz, (0.0, 0.0, 0.0), per_kg


def _cylinder(
    *, radius: float, length: float, xyz: tuple[float, float, float],
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> _Shape:
    length = max(length, MIN_SHAPE_M)
    side = (3 * radius * radius + length * length) / 12
    attrs = {"radius": _num(radius), "length": _num(length)}
    return "cylinder", attrs, xyz, rpy, (side, side, radius * radius / 2)


def _add_link(robot: ET.Element, name: str, mass: float, shape: _Shape | None) -> None:
    link = ET.SubElement(robot, "link", name=name)
    inertial = ET.SubElement(link, "inertial")
    if shape is None:  # a point mass: tiny, so that simulators do not invent a default
        ET.SubElement(inertial, "origin", xyz="0 0 0", rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_num(mass))
        ET.SubElement(inertial, "inertia", ixx="1e-06", ixy="0", ixz="0", iyy="1e-06",
                      iyz="0", izz="1e-06")
        return
    tag, attrs, xyz, rpy, per_kg = shape
    # The shape's inertia is diagonal in the shape's frame, so the inertial frame is it.
    ET.SubElement(inertial, "origin", xyz=_vec(xyz), rpy=_vec(rpy))
    ET.SubElement(inertial, "mass", value=_num(mass))
    ixx, iyy, izz = (f"{mass * k:.6g}" for k in per_kg)
    ET.SubElement(inertial, "inertia", ixx=ixx, ixy="0", ixz="0", iyy=iyy, iyz="0", izz=izz)
    for kind in ("visual", "collision"):
        el = ET.SubElement(link, kind)
        ET.SubElement(el, "origin", xyz=_vec(xyz), rpy=_vec(rpy))
        geometry = ET.SubElement(el, "geometry")
        ET.SubElement(geometry, tag, attrs)
        if kind == "visual":
            ET.SubElement(el, "material", name="busarm_grey")


__all__ = ["JOINT_EFFORT_NM", "TOOL_LINK", "link_names", "urdf_from_config", "write_urdf"]
