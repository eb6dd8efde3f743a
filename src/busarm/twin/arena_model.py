"""The mobile twin's MJCF: an arena, and the robot (chassis, wheels, Lidar, arm) in it.

The chassis is a kinematic planar base (MuJoCo Menagerie's tidybot does the same): slide
joints ``chassis_x``, ``chassis_y`` and a hinge ``chassis_yaw`` in the arena's frame, each driven
by a velocity actuator with a force limit, so the base goes where its wheels take it but
stops against a wall instead of passing through it. Modelled rollers would cost 9-14
times more per step and drift sideways for reasons of their own (field notes, section 5);
the wheels' slip is modelled in software instead (busarm.twin.mobile).

Collision bits: the floor and things on it are ``object`` (contype 1); things the chassis
can hit (walls, tables, boxes, blocks) also carry bit 8, which only the chassis listens
to, so the chassis slides over the floor without touching it and hits everything else;
boxes listen only to the chassis, the arm and blocks (``BOX_HIT``).
Tape is printed on the floor's texture (no geoms: a frame costs no more). Body
names: ``chassis``, ``box<i>`` (mocap: the twin can move it), ``block<i>``; geoms
``wall0``..``wall3``, ``table<i>``, ``box<i>``; the site ``lidar``; cameras ``overview``
(following the robot), ``arena`` (orthographic, straight down).
"""

from __future__ import annotations

import math

import numpy as np

from busarm.arm.config import ArmConfig
from busarm.base.config import ChassisConfig
from busarm.twin.arena import (
    FLOOR_COLORS,
    LINE_COLORS,
    WALL_HEIGHT_M,
    WALL_THICKNESS_M,
    Arena,
    Solid,
)
from busarm.twin.model import (
    ROBOT_GROUP,
    TwinModelSpec,
    _fmt,
    _head,
    arm_actuators,
    arm_bodies,
    light_tint,
)
from busarm.twin.scene import Scene

__all__ = [
    "BASE_FORCE_N",
    "BASE_KV",
    "BASE_TORQUE_NM",
    "BLOCK_HIT",
    "BOX_HIT",
    "CHASSIS_CLEARANCE_M",
    "CHASSIS_MASS_KG",
    "CHASSIS_SIZE_M",
    "FLOOR_MAX_PX",
    "FLOOR_M_PER_PX",
    "FLOOR_RGB",
    "HIT",
    "arena_view_extent_m",
    "build_arena_mjcf",
    "floor_texture",
]


CHASSIS_MASS_KG = 4.5
CHASSIS_SIZE_M = (0.30, 0.22, 0.10)
"""The JetAuto's body (without its wheels): length, width, height."""
CHASSIS_CLEARANCE_M = 0.03
BASE_KV = 400.0
"""Velocity actuators' gain (N per m/s): the base follows its wheels within about 10 ms."""
BASE_FORCE_N = 40.0
"""The most the base pushes with (four small gear motors): a wall stops it."""
BASE_TORQUE_NM = 8.0
FLOOR_RGB = FLOOR_COLORS["light"]
FLOOR_M_PER_PX = 0.0025
FLOOR_MAX_PX = 4096
HIT = 'contype="9" conaffinity="1"'
"""Static things the chassis collides with (see the module docstring)."""
BLOCK_HIT = 'contype="25" conaffinity="1"'
"""Blocks: also bit 16, which the boxes listen to."""
BOX_HIT = 'contype="8" conaffinity="18"'
"""Boxes (moved by the twin): hit by the chassis (8), the arm (2) and blocks (16), never
paired with the floor or the walls (a box is placed, not simulated: pairs that never
matter cost a third of a step)."""


def arena_view_extent_m(arena: Arena) -> float:
    """The arena camera's field, top to bottom (m): the room and its walls in a 4:3 view."""
    w, h = arena.room.size_m
    return max(h, w * 3 / 4) + 2 * WALL_THICKNESS_M + 0.1


def _assets(arena: Arena) -> list[str]:
    out = ['  <asset>',
           '    <texture name="floor" type="2d" file="floor.png"/>',
           '    <material name="floor" texture="floor" specular="0" shininess="0"/>',
           '    <material name="wall" rgba="0.88 0.88 0.86 1" specular="0"/>',
           '    <material name="box" rgba="0.62 0.46 0.30 1" specular="0"/>',
           '    <material name="chassis" rgba="0.15 0.16 0.18 1" specular="0.2"/>',
           '    <material name="wheel" rgba="0.08 0.08 0.08 1" specular="0"/>']
    out.append('  </asset>')
    return out


def _yaw_quat(yaw_rad: float) -> tuple[float, float, float, float]:
    return math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)


def _solid_geom(name: str, solid: Solid, material: str, pos_z: float | None = None,
                hit: str = HIT) -> str:
    half = (solid.size_x_m / 2, solid.size_y_m / 2, solid.height_m / 2)
    yaw = math.radians(solid.yaw_deg)
    pos = (solid.x_m, solid.y_m, solid.height_m / 2) if pos_z is None else (0, 0, pos_z)
    quat = "" if pos_z is not None else f' quat="{_fmt(_yaw_quat(yaw))}"'
    return (f'    <geom name="{name}" class="object" {hit} type="box" material="{material}" '
            f'pos="{_fmt(pos)}"{quat} size="{_fmt(half)}"/>')


def _room(arena: Arena) -> list[str]:
    r = arena.room
    cx, cy = (r.x_min_m + r.x_max_m) / 2, (r.y_min_m + r.y_max_m) / 2
    w, h = r.size_m
    t, wh = WALL_THICKNESS_M, WALL_HEIGHT_M
    x0, x1, y0, y1 = _floor_extent(arena)
    # One quad (a plane's third size is its render grid): the lights are directional.
    size = ((x1 - x0) / 2, (y1 - y0) / 2, max(x1 - x0, y1 - y0))
    out = [f'    <geom name="floor" class="object" type="plane" material="floor" '
           f'pos="{_fmt((cx, cy, 0))}" size="{_fmt(size)}"/>']
    walls = (((cx, r.y_max_m + t / 2), (w / 2 + t, t / 2)),
             ((cx, r.y_min_m - t / 2), (w / 2 + t, t / 2)),
             ((r.x_max_m + t / 2, cy), (t / 2, h / 2)),
             ((r.x_min_m - t / 2, cy), (t / 2, h / 2)))
    for i, ((x, y), (hx, hy)) in enumerate(walls):
        out.append(f'    <geom name="wall{i}" class="object" {HIT} type="box" material="wall" '
                   f'pos="{_fmt((x, y, wh / 2))}" size="{_fmt((hx, hy, wh / 2))}"/>')
    side = arena_view_extent_m(arena)
    out.append(f'    <camera name="arena" pos="{_fmt((cx, cy, 6.0))}" projection="orthographic" '
               f'fovy="{side:.6g}" xyaxes="1 0 0 0 1 0"/>')
    return out


def floor_texture(arena: Arena) -> tuple[str, bytes]:
    """The floor's print (file name, PNG bytes): a plain floor with the tape drawn on it,
    covering the floor plane (MuJoCo lays its first row at the plane's +y edge)."""
    import cv2

    x0, x1, y0, y1 = _floor_extent(arena)
    m_per_px = max(FLOOR_M_PER_PX, max(x1 - x0, y1 - y0) / FLOOR_MAX_PX)
    width, height = round((x1 - x0) / m_per_px), round((y1 - y0) / m_per_px)
    rng = np.random.default_rng(arena.seed or 0)
    base = np.array(FLOOR_COLORS[arena.floor][::-1]) * 255
    image = np.clip(base + rng.normal(0.0, 3.0, (height, width, 1)), 0, 255).astype(np.uint8)
    shift = 4  # sub-pixel precision of the drawing (cv2's fixed point)
    for line in arena.lines:
        pts = np.array([((x - x0) / m_per_px * (1 << shift), (y1 - y) / m_per_px * (1 << shift))
                        for x, y in line.points_m], dtype=np.int32)
        bgr = tuple(int(c * 255) for c in LINE_COLORS[line.color][::-1])
        cv2.polylines(image, [pts], line.closed, bgr, max(1, round(line.width_m / m_per_px)),
                      cv2.LINE_AA, shift)
    ok, png = cv2.imencode(".png", image)
    assert ok
    return "floor.png", png.tobytes()


def _floor_extent(arena: Arena) -> tuple[float, float, float, float]:
    r, t = arena.room, WALL_THICKNESS_M
    return r.x_min_m - t, r.x_max_m + t, r.y_min_m - t, r.y_max_m + t


def _things(arena: Arena) -> list[str]:
    out = [_solid_geom(f"table{i}", t, "table") for i, t in enumerate(arena.tables)]
    out += [_solid_geom(f"inner_wall{i}", w, "wall") for i, w in enumerate(arena.walls)]
    for i, box in enumerate(arena.boxes):
        yaw = math.radians(box.yaw_deg)
        out += [f'    <body name="box{i}" mocap="true" pos="{_fmt((box.x_m, box.y_m, 0))}" '
                f'quat="{_fmt(_yaw_quat(yaw))}">',
                "  " + _solid_geom(f"box{i}", box, "box", box.height_m / 2, BOX_HIT),
                '    </body>']
    for i, block in enumerate(arena.blocks):
        half = block.size_mm / 2000
        yaw = math.radians(block.yaw_deg)
        pos = (block.x_m, block.y_m, arena.block_z_m(i))
        out += [f'    <body name="block{i}" pos="{_fmt(pos)}" '
                f'quat="{_fmt(_yaw_quat(yaw))}">',
                f'      <freejoint name="block{i}"/>',
                f'      <geom name="block{i}" class="object" {BLOCK_HIT} type="box" '
                f'material="{block.color}" size="{_fmt((half, half, half))}" '
                f'mass="{0.74 * (block.size_mm / 10) ** 3 / 1000:.6g}"/>',
                '    </body>']
    return out


def _chassis(config: ArmConfig, chassis: ChassisConfig, spec: TwinModelSpec) -> list[str]:
    sx, sy, sz = CHASSIS_SIZE_M
    z_mid = CHASSIS_CLEARANCE_M + sz / 2
    robot = f'group="{ROBOT_GROUP}"'
    out = ['    <body name="chassis">',
           '      <joint name="chassis_x" type="slide" axis="1 0 0"/>',
           '      <joint name="chassis_y" type="slide" axis="0 1 0"/>',
           '      <joint name="chassis_yaw" type="hinge" axis="0 0 1"/>',
           f'      <inertial pos="0 0 {z_mid:.6g}" mass="{CHASSIS_MASS_KG}" '
           'diaginertia="0.05 0.05 0.08"/>',
           f'      <geom name="chassis" type="box" contype="4" conaffinity="8" {robot} '
           f'material="chassis" pos="0 0 {z_mid:.6g}" size="{_fmt((sx / 2, sy / 2, sz / 2))}"/>',
           f'      <geom type="box" contype="0" conaffinity="0" {robot} material="chassis" '
           f'pos="0 0 {chassis.arm.z_m - 0.005:.6g}" size="{_fmt((sx / 2, sy / 2, 0.005))}"/>']
    r = chassis.wheel_diameter_m / 2
    for fx in (1, -1):
        for fy in (1, -1):
            pos = (fx * chassis.wheelbase_m / 2, fy * chassis.track_m / 2, r)
            out.append(f'      <geom type="cylinder" contype="0" conaffinity="0" {robot} '
                       f'material="wheel" pos="{_fmt(pos)}" quat="0.7071068 0.7071068 0 0" '
                       f'size="{_fmt((r, 0.02))}"/>')
    lid = chassis.lidar
    out += [f'      <site name="lidar" pos="{_fmt((lid.x_m, lid.y_m, lid.z_m))}" '
            f'euler="0 0 {lid.yaw_rad:.9g}" size="0.01"/>',
            f'      <geom type="cylinder" contype="0" conaffinity="0" {robot} material="wheel" '
            f'pos="{_fmt((lid.x_m, lid.y_m, lid.z_m - 0.012))}" size="0.035 0.015"/>',
            '      <camera name="overview" pos="-1.1 0 0.95" xyaxes="0 -1 0 0.6 0 0.8" '
            'fovy="60"/>']
    arm = chassis.arm
    out.append(f'      <body name="arm_mount" pos="{_fmt((arm.x_m, arm.y_m, arm.z_m))}" '
               f'euler="0 0 {arm.yaw_rad:.9g}">')
    out += ["    " + line for line in arm_bodies(config, spec)]
    out += ['      </body>', '    </body>']
    return out


def _lights(scene: Scene, arena: Arena) -> list[str]:
    tint = light_tint(scene.lighting.color_temp_k) * scene.lighting.intensity
    r = arena.room
    centre = ((r.x_min_m + r.x_max_m) / 2, (r.y_min_m + r.y_max_m) / 2, 3.0)
    out = [f'    <light name="top" directional="true" pos="{_fmt(centre)}" dir="0 0 -1" '
           f'diffuse="{_fmt(0.55 * tint)}" specular="0 0 0" castshadow="false"/>']
    for k, (dx, dy) in enumerate(((1, 0), (-1, 0), (0, 1), (0, -1))):
        out.append(f'    <light name="side{k}" directional="true" dir="{-dx} {-dy} -0.6" '
                   f'diffuse="{_fmt(0.2 * tint)}" specular="0 0 0" castshadow="false"/>')
    return out


def build_arena_mjcf(config: ArmConfig, chassis: ChassisConfig, arena: Arena,
                     spec: TwinModelSpec) -> str:
    """The arena with the robot in it, as MJCF text."""
    scene = Scene()
    out = _head(scene, spec)
    out[out.index('  <asset>'):out.index('  <asset>')] = _assets(arena)
    out.append('  <worldbody>')
    out += _lights(scene, arena)
    out += _room(arena)
    out += _things(arena)
    out += _chassis(config, chassis, spec)
    out.append('  </worldbody>')
    out += arm_actuators(config)
    for axis, kv, limit in (("x", BASE_KV, BASE_FORCE_N), ("y", BASE_KV, BASE_FORCE_N),
                            ("yaw", BASE_KV / 10, BASE_TORQUE_NM)):
        out.insert(len(out) - 1, f'    <velocity name="chassis_{axis}" joint="chassis_{axis}" '
                   f'kv="{kv:g}" forcerange="{-limit:g} {limit:g}" ctrllimited="false"/>')
    out.append('</mujoco>')
    return "\n".join(line for line in out if line)
