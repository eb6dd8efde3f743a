"""The twin's MJCF model, generated from the arm config and a scene.

Nothing here is typed twice: link lengths and joint limits come from ``ArmConfig``,
the modified-DH frames from its geometry (body i sits at RotX(alpha) TransX(a)
TransZ(d) in its parent and turns about its own z, so MuJoCo's joint angle is the DH
theta), blocks and bins from the ``Scene``. MuJoCo works in metres and radians; only
this module and ``twin.py`` see them.

Provenance and grade (MuJoCo Menagerie style) of the numbers that are not in the arm
config, all "C: plausible, not identified on hardware":

=========================== ============ =================================================
servo stall torque          3.43 N m     35 kg cm joints (vendor); gripper 1.96 N m (20 kg cm)
servo stiffness kp          410 N m/rad  full torque at 2 pulses (0.48 deg) of error
gripper stiffness kp        22.5 N m/rad full torque at 5 deg of error (a P band, so a
                                         gentle squeeze exists: busarm.arm.gripper's hold)
servo damping kv            2.0 N m s/rad on the error's rate (PD), within the stall torque
no-load speed               300 deg/s    0.2 s/60 deg, typical of 35 kg bus servos
joint damping / armature    0.66 / 0.01  stall torque / no-load speed (the motor's torque
                                         falls linearly with speed); reflected rotor inertia
link masses                 0.10-0.25 kg a servo and a bracket per link (guess)
gripper gap                 config       the arm config's gap_mm_per_pulse (0.1875: 30 mm at 540)
block                       30 mm, 20 g  a wooden toy cube (density 0.74)
block tag                   massless     a printed label, seen, never touching
friction finger pad         1.2          rubber pad on wood (guess), rules its contacts
friction everything else    0.5          wood on wood, desk laminate, plastic trays
room light                  5 x 0.25     diffuse, one above and four from the sides
=========================== ============ =================================================

Body names a test may look up: ``block<i>`` and ``distractor<i>`` (each a free body whose
free joint and geom have the same name; i is the index in ``scene.blocks`` or
``scene.distractors``), ``bin<i>``; the lights are ``top`` (the key light, which
``Lighting`` aims) and ``side0``..``side3``. A block with a ``tag_id`` carries its tag's
label and cells as geoms of its body (``busarm.twin.block_tags``). A distractor in a block
colour (a look-alike) has the block's material: the same paint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import ArmConfig
from busarm.rotations import quaternion_wxyz
from busarm.twin.block_tags import TAG_BLACK_RGB, TAG_WHITE_RGB, tag_geoms
from busarm.twin.scene import COLORS, DISTRACTOR_COLORS, Block, Distractor, Lighting, Scene

__all__ = [
    "ARM_RGBA",
    "AS_BUILT_MOUNT_ERROR",
    "FINGER_PAD_MM",
    "GRIPPER_FULL_TORQUE_DEG",
    "GRIPPER_KP_NM_PER_RAD",
    "GRIPPER_TORQUE_NM",
    "JOINT_ARMATURE",
    "JOINT_DAMPING",
    "JOINT_TORQUE_NM",
    "LINK_MASS_KG",
    "MJ_FROM_CV",
    "M_PER_MM",
    "NEUTRAL_TEMP_K",
    "NO_LOAD_SPEED_DEG_S",
    "OBJECT_FRICTION",
    "PAD_FRICTION",
    "ROBOT_GROUP",
    "ROOM_LIGHT",
    "SERVO_KP_NM_PER_RAD",
    "SERVO_KV_NM_S_PER_RAD",
    "TABLE_RGB",
    "TABLE_THICKNESS_MM",
    "TIMESTEP_S",
    "FloatArray",
    "TwinModelSpec",
    "arm_actuators",
    "arm_bodies",
    "build_mjcf",
    "light_tint",
    "quat_from_matrix",
]


FloatArray = npt.NDArray[np.float64]

M_PER_MM = 0.001
TIMESTEP_S = 0.002
JOINT_TORQUE_NM = 35 * 0.0980665   # 35 kg cm
GRIPPER_TORQUE_NM = 20 * 0.0980665  # 20 kg cm
SERVO_KP_NM_PER_RAD = 410.0
SERVO_KV_NM_S_PER_RAD = 2.0
GRIPPER_FULL_TORQUE_DEG = 5.0
"""The gripper servo's torque rises in proportion to its position error up to its stall
torque at this error (a P band, as bus servos of its kind publish: docs/twin.md); the
joints keep the stiff 2-pulse band, which their accuracy was measured with."""
GRIPPER_KP_NM_PER_RAD = GRIPPER_TORQUE_NM / math.radians(GRIPPER_FULL_TORQUE_DEG)
NO_LOAD_SPEED_DEG_S = 300.0
# A saturated servo's torque falls linearly from stall at rest to nothing at the no-load
# speed: joint damping of stall torque / no-load speed on top of a capped actuator.
JOINT_DAMPING = JOINT_TORQUE_NM / math.radians(NO_LOAD_SPEED_DEG_S)
JOINT_ARMATURE = 0.01
FINGER_PAD_MM = (10.0, 16.0, 36.0)
PAD_FRICTION = 1.2
"""Rubber finger pads on wood or plastic (a guess); it rules every contact of a pad."""
OBJECT_FRICTION = 0.5
"""Wood on wood, a desk's laminate or a plastic tray: blocks, the table, bins and other
things on it (about 0.3-0.6 measured for dry wood; a pad dragging on a block's top moves
it only because the rubber grips harder than the table does)."""
"""One finger pad's thickness (along the closing axis), width and length."""
ARM_RGBA = "0.13 0.13 0.14 1"
TABLE_RGB = (0.78, 0.76, 0.72)
TABLE_THICKNESS_MM = 20.0
LINK_MASS_KG = (0.25, 0.15, 0.12, 0.10, 0.15)
ROBOT_GROUP = 2
"""The robot's own geoms are in this geom group (drawn; a Lidar's rays skip them)."""


AS_BUILT_MOUNT_ERROR = ((1.8, -2.4, 1.1), (1.3, -0.9, 0.6))
"""How far the twin's camera sits from the drawing's position (mm, and a rotation
vector in degrees, in camera axes): a real bracket is never exactly where the drawing
says, so hand-eye calibration has something to find."""


def _fmt(values: npt.ArrayLike) -> str:
    return " ".join(f"{v:.9g}" for v in np.asarray(values, dtype=float).ravel())


def quat_from_matrix(r: FloatArray) -> FloatArray:
    """MuJoCo's (w, x, y, z) quaternion of a rotation matrix."""
    return np.array(quaternion_wxyz(r))


def _link_geom(radius_m: float, end_m: tuple[float, float, float]) -> str:
    """A capsule from the link's origin to ``end_m``, or a ball where the link has no length."""
    if float(np.linalg.norm(end_m)) < 1e-3:
        return f'<geom class="arm" type="sphere" size="{radius_m}"/>'
    return (f'<geom class="arm" type="capsule" size="{radius_m}" '
            f'fromto="0 0 0 {_fmt(end_m)}"/>')


def _rot_x(angle_rad: float) -> FloatArray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


MJ_FROM_CV = np.diag([1.0, -1.0, -1.0])
"""A MuJoCo camera looks along its -z with +y up; OpenCV's along +z with +y down."""


ROOM_LIGHT = 0.25
"""Diffuse light of each of the room's five lights at the usual ``Lighting``."""
NEUTRAL_TEMP_K = 5000.0
"""The colour temperature the twin's lights are white at (the usual ``Lighting``)."""


def _blackbody_rgb(temp_k: float) -> FloatArray:
    """A black body's colour at ``temp_k`` (Tanner Helland's fit to CIE data, 0..1)."""
    t = temp_k / 100.0
    r = 1.0 if t <= 66 else 1.2929361861 * (t - 60) ** -0.1332047592
    g = (0.3900815787 * math.log(t) - 0.6318414438 if t <= 66
         else 1.1298908609 * (t - 60) ** -0.0755148492)
    b = 1.0 if t >= 66 else 0.5432067891 * math.log(t - 10) - 1.1962540892
    return np.clip(np.array([r, g, b]), 0.0, 1.0)


def light_tint(color_temp_k: float) -> FloatArray:
    """The lights' colour at ``color_temp_k``: white at ``NEUTRAL_TEMP_K``, as bright to
    the eye (Rec. 709 luminance 1) at every temperature, warmer or cooler."""
    if color_temp_k == NEUTRAL_TEMP_K:
        return np.ones(3)
    rgb = _blackbody_rgb(color_temp_k) / _blackbody_rgb(NEUTRAL_TEMP_K)
    out: FloatArray = rgb / float(np.dot(rgb, (0.2126, 0.7152, 0.0722)))
    return out


def _lights(lighting: Lighting) -> list[str]:
    """The room's lights: a key light (``top``) and four softer ones from the sides.

    At the usual ``Lighting``: the key light straight down from above, every light as
    bright, so the side faces of a block are shaded but keep their colour (as under
    ceiling lights). ``key_share`` moves light from the sides to the key light (the
    total stays), which comes from where a desk lamp or a window would stand.
    """
    tint = light_tint(lighting.color_temp_k) * lighting.intensity
    key = 5 * ROOM_LIGHT * lighting.key_share * tint
    side = 5 * ROOM_LIGHT * (1 - lighting.key_share) / 4 * tint
    az, el = math.radians(lighting.key_azimuth_deg), math.radians(lighting.key_elevation_deg)
    # From 1.6 m away, aimed at the middle of the arm's work area (0.1, 0, 0).
    towards = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    towards = np.round(towards, 9) + 0.0  # straight down is "0 0 1", not 6e-17
    pos = np.array([0.1, 0.0, 0.0]) + 1.6 * towards
    out = [f'    <light name="top" pos="{_fmt(pos)}" dir="{_fmt(-towards + 0.0)}" '
           f'diffuse="{_fmt(key)}" specular="0 0 0" castshadow="false"/>']
    for k, (dx, dy) in enumerate(((1, 0), (-1, 0), (0, 1), (0, -1))):
        out.append(f'    <light name="side{k}" directional="true" dir="{-dx} {-dy} -0.6" '
                   f'diffuse="{_fmt(side)}" specular="0 0 0" castshadow="false"/>')
    return out


def _distractor_body(i: int, thing: Distractor, table_z_m: float) -> list[str]:
    """A free body ``distractor<i>`` standing (a cylinder, a disc) or lying (a bar) on the
    table: physics may push it, as a real one would be."""
    m = M_PER_MM
    half_h = thing.height_mm / 2 * m
    if thing.is_round:
        geom = f'type="cylinder" size="{_fmt((thing.length_mm / 2 * m, half_h))}"'
    else:
        geom = (f'type="box" size="'
                f'{_fmt((thing.length_mm / 2 * m, thing.width_mm / 2 * m, half_h))}"')
    yaw = math.radians(thing.yaw_deg)
    quat = (math.cos(yaw / 2), 0, 0, math.sin(yaw / 2))
    pos = (thing.x_mm * m, thing.y_mm * m, table_z_m + half_h)
    material = thing.color if thing.color in COLORS else f"distractor_{thing.color}"
    return [f'    <body name="distractor{i}" pos="{_fmt(pos)}" quat="{_fmt(quat)}">',
            f'      <freejoint name="distractor{i}"/>',
            f'      <geom name="distractor{i}" class="object" {geom} '
            f'material="{material}" mass="{thing.mass_g / 1000:.6g}"/>',
            '    </body>']


def _block_body(i: int, block: Block, table_z_m: float) -> list[str]:
    """A free body ``block<i>``: the cube, and its tag on top if it has one."""
    m = M_PER_MM
    half = block.size_mm / 2 * m
    yaw = math.radians(block.yaw_deg)
    quat = (math.cos(yaw / 2), 0, 0, math.sin(yaw / 2))
    pos = (block.x_mm * m, block.y_mm * m, table_z_m + half)
    out = [f'    <body name="block{i}" pos="{_fmt(pos)}" quat="{_fmt(quat)}">',
           f'      <freejoint name="block{i}"/>',
           f'      <geom name="block{i}" class="object" type="box" material="{block.color}" '
           f'size="{_fmt((half, half, half))}" mass="{block.mass_g / 1000:.6g}"/>']
    if block.tag_id is not None:
        out += tag_geoms(block.tag_id, block.size_mm, '      ')
    return [*out, '    </body>']


@dataclass(frozen=True)
class TwinModelSpec:
    """What the generated model needs besides the arm config and the scene."""

    mount: CameraMount
    camera_fovy_deg: float
    """Vertical field of view of the arm camera's ideal (undistorted) render."""
    render_size_px: tuple[int, int]
    """(width, height) the arm camera is rendered at, before the lens is applied."""
    overview_size_px: tuple[int, int] = (640, 480)
    textures: tuple[tuple[str, bytes, float, float, FloatArray], ...] = ()
    """Board prints: (file name, PNG bytes, width mm, height mm, image2base), one per scene
    board (see busarm.twin.boards)."""


def _head(scene: Scene, spec: TwinModelSpec) -> list[str]:
    """Options, the headlight, materials and default classes: all before the world."""
    width = max(spec.render_size_px[0], spec.overview_size_px[0])
    height = max(spec.render_size_px[1], spec.overview_size_px[1])
    out: list[str] = []
    w = out.append
    w('<mujoco model="busarm twin">')
    w('  <compiler angle="radian" autolimits="true"/>')
    w(f'  <option timestep="{TIMESTEP_S}" integrator="implicitfast" cone="elliptic" '
      'impratio="10"/>')
    tint = light_tint(scene.lighting.color_temp_k) * scene.lighting.intensity
    w(f'  <visual><global offwidth="{width}" offheight="{height}"/>'
      '<quality shadowsize="2048" offsamples="4"/>'
      f'<headlight ambient="{_fmt(0.12 * tint)}" diffuse="{_fmt(0.1 * tint)}" '
      'specular="0 0 0"/></visual>')
    w('  <asset>')
    r, gg, b = TABLE_RGB
    w(f'    <material name="table" rgba="{r} {gg} {b} 1" specular="0" shininess="0"/>')
    for color, (cr, cg, cb) in COLORS.items():
        w(f'    <material name="{color}" rgba="{cr} {cg} {cb} 1" specular="0.05" '
          'shininess="0.1"/>')
    w('    <material name="tray" rgba="0.55 0.55 0.57 1" specular="0"/>')
    if any(b.tag_id is not None for b in scene.blocks):  # else the model it always was
        w(f'    <material name="tag_white" rgba="{_fmt(TAG_WHITE_RGB)} 1" specular="0" '
          'shininess="0"/>')
        w(f'    <material name="tag_black" rgba="{_fmt(TAG_BLACK_RGB)} 1" specular="0" '
          'shininess="0"/>')
    for color, rgb in DISTRACTOR_COLORS.items():
        if all(d.color != color for d in scene.distractors):
            continue  # a scene without distractors builds the model it always did
        w(f'    <material name="distractor_{color}" rgba="{_fmt(rgb)} 1" specular="0.1" '
          'shininess="0.2"/>')
    for i, (fname, _data, _w, _h, _pose) in enumerate(spec.textures):
        w(f'    <texture name="board{i}" type="2d" file="{fname}"/>')
        w(f'    <material name="board{i}" texture="board{i}" specular="0" shininess="0"/>')
    w('  </asset>')
    w('  <default>')
    w(f'    <default class="arm"><joint damping="{JOINT_DAMPING:.6g}" armature="{JOINT_ARMATURE}" '
      'frictionloss="0.05"/>')
    w(f'      <geom contype="2" conaffinity="1" group="{ROBOT_GROUP}" rgba="{ARM_RGBA}" '
      'density="0"/></default>')
    w('    <default class="object"><geom contype="1" conaffinity="1" condim="4" '
      f'friction="{OBJECT_FRICTION} 0.01 0.001" solref="0.004 1"/></default>')
    w('  </default>')
    return out


def _table_and_things(scene: Scene, spec: TwinModelSpec, table_z: float) -> list[str]:
    """The table, the overview camera, and everything on the table (metres)."""
    m, t = M_PER_MM, scene.table
    out: list[str] = []
    w = out.append
    tx, ty = (t.x_min_mm + t.x_max_mm) / 2 * m, (t.y_min_mm + t.y_max_mm) / 2 * m
    hx, hy = (t.x_max_mm - t.x_min_mm) / 2 * m, (t.y_max_mm - t.y_min_mm) / 2 * m
    th = TABLE_THICKNESS_MM / 2 * m
    w(f'    <geom name="table" class="object" type="box" material="table" '
      f'pos="{_fmt((tx, ty, table_z - th))}" size="{_fmt((hx, hy, th))}"/>')
    # Overview camera: high above the front edge, looking down at the whole table.
    w('    <camera name="overview" pos="0.62 0 0.75" xyaxes="0 1 0 -0.8 0 0.6" fovy="60"/>')
    for i, (_f, _d, bw, bh, image2base) in enumerate(spec.textures):
        board_pos = image2base[:3, 3] * m + (0.0, 0.0, 0.0004)  # just above the table top
        board_quat = quat_from_matrix(image2base[:3, :3])
        w(f'    <geom name="board{i}" type="plane" material="board{i}" contype="0" '
          f'conaffinity="0" pos="{_fmt(board_pos)}" quat="{_fmt(board_quat)}" '
          f'size="{_fmt((bw / 2 * m, bh / 2 * m, 0.01))}"/>')
    for i, tray in enumerate(scene.bins):
        out += _bin_body(i, tray.x_mm, tray.y_mm, tray.size_mm, tray.wall_mm, table_z)
    for i, block in enumerate(scene.blocks):
        out += _block_body(i, block, table_z)
    for i, thing in enumerate(scene.distractors):
        out += _distractor_body(i, thing, table_z)
    return out


def _bin_body(i: int, x_mm: float, y_mm: float, size_mm: float, wall_mm: float,
              table_z: float) -> list[str]:
    """An open tray: a thin floor and four walls of 2 mm inside its outer square."""
    m = M_PER_MM
    s, wall = size_mm / 2 * m, wall_mm * m
    t_w = 0.002  # wall thickness, m
    out = [f'    <body name="bin{i}" pos="{_fmt((x_mm * m, y_mm * m, table_z))}">',
           f'      <geom class="object" type="box" material="tray" pos="0 0 0.001" '
           f'size="{_fmt((s, s, 0.001))}"/>']
    walls = ((s - t_w, 0.0, t_w, s), (-s + t_w, 0.0, t_w, s), (0.0, s - t_w, s, t_w),
             (0.0, -s + t_w, s, t_w))
    for px, py, sx, sy in walls:
        out.append(f'      <geom class="object" type="box" material="tray" '
                   f'pos="{_fmt((px, py, wall / 2))}" size="{_fmt((sx, sy, wall / 2))}"/>')
    out.append('    </body>')
    return out


def build_mjcf(config: ArmConfig, scene: Scene, spec: TwinModelSpec) -> str:
    """The whole world as MJCF text (assets, if any, are passed to MuJoCo separately)."""
    out = _head(scene, spec)
    out.append('  <worldbody>')
    out += _lights(scene.lighting)
    out += _table_and_things(scene, spec, config.table_z_mm * M_PER_MM)
    out += arm_bodies(config, spec)
    out.append('  </worldbody>')
    out += arm_actuators(config)
    out.append('</mujoco>')
    return "\n".join(line for line in out if line)


def arm_bodies(config: ArmConfig, spec: TwinModelSpec) -> list[str]:
    """The arm's base, links, camera and gripper, in the frame of whatever holds it (the
    world for an arm on a table, the chassis for the mobile robot)."""
    g = config.geometry
    m = M_PER_MM
    table_z = config.table_z_mm * m
    out = [f'    <geom name="base" class="arm" type="cylinder" contype="0" conaffinity="0" '
           f'pos="0 0 {table_z + 0.02:.9g}" size="0.045 0.02"/>',
           f'    <geom name="column" class="arm" type="cylinder" contype="0" conaffinity="0" '
           f'pos="0 0 {table_z + g.base_height_mm * m / 2:.9g}" '
           f'size="0.022 {g.base_height_mm * m / 2 - 0.01:.9g}"/>']
    # The arm: modified DH, body i at RotX(alpha) TransX(a) TransZ(d), turning about z.
    dh = [(0.0, 0.0, g.base_height_mm), (-math.pi / 2, 0.0, 0.0), (0.0, g.upper_arm_mm, 0.0),
          (0.0, g.forearm_mm, 0.0), (-math.pi / 2, 0.0, g.wrist_mm)]
    link_geoms = [
        # link1: the shoulder bracket on top of the column.
        '<geom class="arm" type="box" size="0.03 0.03 0.02" contype="0" conaffinity="0"/>',
        _link_geom(0.018, (g.upper_arm_mm * m, 0, 0)),
        _link_geom(0.016, (g.forearm_mm * m, 0, 0)),
        _link_geom(0.016, (0, g.wrist_mm * m, 0)),
        '<geom class="arm" type="box" size="0.03 0.018 0.015" pos="0 0 0.0"/>',
    ]
    coms = [(0, 0, 0), (g.upper_arm_mm * m / 2, 0, 0), (g.forearm_mm * m / 2, 0, 0),
            (0, g.wrist_mm * m / 2, 0), (0, 0, 0.04)]
    indent = "    "
    for i, ((alpha, a, d), joint) in enumerate(zip(dh, config.joints, strict=True)):
        rot = _rot_x(alpha)
        pos = np.array([a, 0.0, 0.0]) + rot @ np.array([0.0, 0.0, d])
        pos_m = pos * m  # the base frame is MuJoCo's world frame (the table may be offset)
        mass = LINK_MASS_KG[i]
        lo, hi = math.radians(joint.min_deg), math.radians(joint.max_deg)
        out += [f'{indent}<body name="link{i + 1}" childclass="arm" pos="{_fmt(pos_m)}" '
                f'quat="{_fmt(quat_from_matrix(rot))}">',
                f'{indent}  <inertial pos="{_fmt(coms[i])}" mass="{mass}" '
                f'diaginertia="{_fmt((mass * 0.0006,) * 3)}"/>',
                f'{indent}  <joint name="{joint.name}" axis="0 0 1" range="{lo:.9g} {hi:.9g}"/>',
                f'{indent}  {link_geoms[i]}']
        if i == 3:
            out += _camera_geoms(spec, indent + "  ")
        indent += "  "
    out += _gripper(config, indent)
    for _ in range(5):
        indent = indent[:-2]
        out.append(f'{indent}</body>')
    return out


def _camera_geoms(spec: TwinModelSpec, indent: str) -> list[str]:
    """The arm camera on its link (the wrist's): the MuJoCo camera, the camera's body
    and the bracket holding it."""
    m = M_PER_MM
    cam = spec.mount.cam2link
    cam_quat = quat_from_matrix(cam[:3, :3] @ MJ_FROM_CV)
    cam_pos = cam[:3, 3] * m
    # The bracket holding it: a bar from the wrist joint to the camera body.
    bracket_end = cam_pos + cam[:3, :3] @ np.array([0, 0, -0.02])
    return [f'{indent}<camera name="arm_camera" pos="{_fmt(cam_pos)}" '
            f'quat="{_fmt(cam_quat)}" fovy="{spec.camera_fovy_deg:.9g}"/>',
            f'{indent}<geom class="arm" type="box" size="0.02 0.012 0.012" '
            f'pos="{_fmt(cam_pos + cam[:3, :3] @ np.array([0, 0, -0.014]))}" '
            f'quat="{_fmt(quat_from_matrix(cam[:3, :3]))}" contype="0" conaffinity="0"/>',
            f'{indent}<geom class="arm" type="capsule" size="0.006" contype="0" '
            f'conaffinity="0" fromto="0 0 0 {_fmt(bracket_end)}"/>']


def _gripper(config: ArmConfig, indent: str) -> list[str]:
    """The gripper on link 5 (tool axis z5): a palm, then two fingers sliding along y5."""
    m = M_PER_MM
    pad_t, pad_w, pad_l = (v * m for v in FINGER_PAD_MM)
    max_half_gap = (config.gripper.max_pulses - config.gripper.min_pulses) \
        * config.gripper.gap_mm_per_pulse / 2 * m
    tool = config.geometry.tool_mm * m
    palm_len = tool - pad_l - 0.004
    out = [f'{indent}<geom class="arm" type="box" size="0.014 0.028 {palm_len / 2:.9g}" '
           f'pos="0 0 {palm_len / 2:.9g}"/>',
           f'{indent}<site name="tool" pos="0 0 {tool:.9g}" size="0.004"/>']
    for side, sign in (("left", 1.0), ("right", -1.0)):
        out += [
            f'{indent}<body name="finger_{side}" pos="0 0 {tool - pad_l / 2:.9g}">',
            f'{indent}  <inertial pos="0 {sign * pad_t:.9g} 0" mass="0.02" '
            'diaginertia="2e-6 2e-6 2e-6"/>',
            f'{indent}  <joint name="finger_{side}" type="slide" axis="0 {sign:g} 0" '
            f'range="0 {max_half_gap:.9g}" damping="20" armature="2" frictionloss="0"/>',
            # The finger's blade from its pad back to the palm (seen, never touching).
            f'{indent}  <geom type="box" contype="0" conaffinity="0" '
            f'pos="0 {sign * pad_t * 0.25:.9g} {-pad_l / 2 - 0.01:.9g}" '
            f'size="{_fmt((pad_w / 2, pad_t / 4, 0.012))}"/>',
            # Priority: the rubber pad's friction rules every contact it makes.
            f'{indent}  <geom name="finger_{side}" type="box" condim="4" priority="1" '
            f'friction="{PAD_FRICTION} 0.02 0.002" solref="0.004 1" '
            'solimp="0.95 0.99 0.001" '
            f'pos="0 {sign * pad_t / 2:.9g} 0" size="{_fmt((pad_w / 2, pad_t / 2, pad_l / 2))}"/>',
            f'{indent}</body>']
    return out


def arm_actuators(config: ArmConfig) -> list[str]:
    """The finger coupling and the servos' actuators."""
    names = [j.name for j in config.joints]
    lim = [(math.radians(j.min_deg), math.radians(j.max_deg)) for j in config.joints]
    m = M_PER_MM
    # Servo angle per metre of one finger's travel (the gripper actuator's gear).
    finger_gear = -1.0 / (config.gripper.gap_mm_per_pulse / 2 * m / math.radians(0.24))
    out: list[str] = []
    w = out.append
    w('  <equality><joint joint1="finger_right" joint2="finger_left" polycoef="0 1 0 0 0" '
      'solref="0.004 1"/></equality>')
    w('  <actuator>')
    for name, (lo, hi) in zip(names, lim, strict=True):
        w(f'    <position name="{name}" joint="{name}" kp="{SERVO_KP_NM_PER_RAD}" '
          f'kv="{SERVO_KV_NM_S_PER_RAD}" ctrlrange="{lo - 0.2:.9g} {hi + 0.2:.9g}" '
          f'forcerange="{-JOINT_TORQUE_NM:.6g} {JOINT_TORQUE_NM:.6g}"/>')
    w(f'    <position name="gripper" joint="finger_left" gear="{finger_gear:.9g}" '
      f'kp="{GRIPPER_KP_NM_PER_RAD:.9g}" ctrllimited="false" '
      f'forcerange="{-GRIPPER_TORQUE_NM:.6g} {GRIPPER_TORQUE_NM:.6g}"/>')
    w('  </actuator>')
    return out
