"""Foxglove's well-known messages from busarm's values: what the 3D, Image and Plot
panels draw.

Builders take busarm's values (frames as 4 x 4 transforms in metres, scans, grids,
sightings in mm) and a stamp in seconds since the epoch, and give the ``foxglove.messages``
object (protobuf on the wire: each channel advertises its schema, so any client decodes
it). Nothing here opens a socket or reads the robot.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from foxglove.messages import (
    CameraCalibration,
    Color,
    CompressedImage,
    CubePrimitive,
    Duration,
    FrameTransform,
    FrameTransforms,
    Grid,
    JointState,
    JointStates,
    LaserScan,
    LinePrimitive,
    LinePrimitiveLineType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    Pose,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector2,
    Vector3,
)

from busarm.lidar.beams import SCAN_BEAMS, even_beams
from busarm.lidar.scan import LaserScan as BusarmScan
from busarm.nav.grid import OccupancyGrid
from busarm.nav.map_files import trinary_cells
from busarm.perception.locate import Sighting
from busarm.robot.frames import Frame
from busarm.rotations import quaternion_wxyz
from busarm.vision.annotate import DRAW_BGR

__all__ = [
    "BLOCK_LIFETIME_S",
    "Point2",
    "block_scene",
    "camera_calibration",
    "compressed_jpeg",
    "frame_transforms",
    "joint_states",
    "laser_scan",
    "map_grid",
    "path_scene",
    "stamp",
]


Point2 = tuple[float, float]
"""(x, y) in metres on the floor."""

BLOCK_LIFETIME_S = 1.0
"""A block drawn goes after this long unless seen again (the camera moved on)."""
PATH_Z_M = 0.02
"""Paths and marks a little above the floor, so that the map's grid does not hide them."""
GREY = (0.6, 0.6, 0.6)


def stamp(t_s: float) -> Timestamp:
    """A Foxglove timestamp of ``t_s`` seconds since the epoch."""
    return Timestamp.from_epoch_secs(t_s)


def _quaternion(rotation: npt.ArrayLike) -> Quaternion:
    w, x, y, z = quaternion_wxyz(rotation)
    return Quaternion(x=x, y=y, z=z, w=w)


def _yaw(yaw_rad: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw_rad / 2), w=math.cos(yaw_rad / 2))


def frame_transforms(t_s: float, frames: Iterable[Frame]) -> FrameTransforms:
    """Each (parent, child, 4 x 4 transform in m) as a FrameTransform (the 3D panel's
    transform tree: the URDF's links move with them)."""
    out = []
    for parent, child, matrix in frames:
        m = np.asarray(matrix, dtype=np.float64)
        out.append(FrameTransform(
            timestamp=stamp(t_s), parent_frame_id=parent, child_frame_id=child,
            translation=Vector3(x=float(m[0, 3]), y=float(m[1, 3]), z=float(m[2, 3])),
            rotation=_quaternion(m[:3, :3])))
    return FrameTransforms(transforms=out)


def joint_states(t_s: float, names: Sequence[str], positions: Sequence[float]
                 ) -> JointStates:
    """Each joint's position (rad, or m for the gripper's gap), for the Plot panel."""
    return JointStates(timestamp=stamp(t_s), joints=[
        JointState(name=n, position=float(p)) for n, p in zip(names, positions, strict=True)])


def laser_scan(t_s: float, scan: BusarmScan, frame_id: str) -> LaserScan:
    """The scan at one beam a degree from -180 deg (no return: +inf, drawn as nothing)."""
    ranges, intensities = even_beams(scan, SCAN_BEAMS)
    end = -math.pi + 2 * math.pi * (SCAN_BEAMS - 1) / SCAN_BEAMS
    return LaserScan(timestamp=stamp(t_s), frame_id=frame_id,
                     pose=Pose(position=Vector3(), orientation=_yaw(0.0)),
                     start_angle=-math.pi, end_angle=end,
                     ranges=[float(r) for r in ranges],
                     intensities=[float(i) for i in intensities])


def map_grid(t_s: float, grid: OccupancyGrid, frame_id: str = "map") -> Grid:
    """The map as a Grid of one int8 field ``occupancy`` (100 occupied, 0 free, -1
    unknown: a ROS OccupancyGrid's values), its first row at the origin."""
    s = grid.spec
    cells = np.ascontiguousarray(trinary_cells(grid))
    return Grid(timestamp=stamp(t_s), frame_id=frame_id,
                pose=Pose(position=Vector3(x=float(s.origin_x_m), y=float(s.origin_y_m)),
                          orientation=_yaw(0.0)),
                column_count=s.width,
                cell_size=Vector2(x=float(s.resolution_m), y=float(s.resolution_m)),
                row_stride=s.width, cell_stride=1,
                fields=[PackedElementField(name="occupancy", offset=0,
                                           type=PackedElementFieldNumericType.Int8)],
                data=cells.tobytes())


def compressed_jpeg(t_s: float, frame_id: str, jpeg: bytes) -> CompressedImage:
    return CompressedImage(timestamp=stamp(t_s), frame_id=frame_id, data=jpeg, format="jpeg")


def camera_calibration(t_s: float, frame_id: str, intrinsics: Any) -> CameraCalibration:
    """The wrist camera's intrinsics (``busarm.vision`` calibration): the 3D panel
    projects the picture into the scene with them."""
    k = np.asarray(intrinsics.camera_matrix, dtype=np.float64).reshape(3, 3)
    p = np.zeros((3, 4))
    p[:, :3] = k
    return CameraCalibration(
        timestamp=stamp(t_s), frame_id=frame_id, width=int(intrinsics.width_px),
        height=int(intrinsics.height_px), distortion_model=str(intrinsics.model),
        D=[float(v) for v in intrinsics.distortion], K=[float(v) for v in k.reshape(-1)],
        R=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        P=[float(v) for v in p.reshape(-1)])


def _color(name: str, alpha: float = 1.0) -> Color:
    bgr = DRAW_BGR.get(name)
    r, g, b = GREY if bgr is None else (bgr[2] / 255, bgr[1] / 255, bgr[0] / 255)
    return Color(r=r, g=g, b=b, a=alpha)


def block_scene(t_s: float, sightings: Sequence[Sighting], frame_id: str = "base_link"
                ) -> SceneUpdate:
    """Each block seen as a cube of its size and colour where it stands (``base_link``,
    the arm's frame), labelled; the blocks drawn before are deleted first."""
    entities = []
    for k, s in enumerate(sightings):
        loc = s.location
        size_m = loc.size_mm / 1000
        x, y, z = loc.x_mm / 1000, loc.y_mm / 1000, loc.z_mm / 1000 - size_m / 2  # centre
        pose = Pose(position=Vector3(x=x, y=y, z=z),
                    orientation=_yaw(math.radians(loc.yaw_deg)))
        label = Pose(position=Vector3(x=x, y=y, z=z + size_m), orientation=_yaw(0.0))
        entities.append(SceneEntity(
            timestamp=stamp(t_s), frame_id=frame_id, id=f"block-{k}",
            lifetime=Duration.from_secs(BLOCK_LIFETIME_S),
            cubes=[CubePrimitive(pose=pose, size=Vector3(x=size_m, y=size_m, z=size_m),
                                 color=_color(s.color))],
            texts=[TextPrimitive(pose=label, billboard=True, font_size=14.0,
                                 scale_invariant=True, color=_color("white"),
                                 text=s.color + ("" if s.reachable else " (out of reach)"))]))
    return SceneUpdate(deletions=[SceneEntityDeletion(timestamp=stamp(t_s),
                                                      type=SceneEntityDeletionType.All)],
                       entities=entities)


def _line(points: Sequence[Point2], rgb: tuple[float, float, float], thickness_px: float
          ) -> LinePrimitive:
    return LinePrimitive(
        type=LinePrimitiveLineType.LineStrip, pose=Pose(position=Vector3(),
                                                        orientation=_yaw(0.0)),
        thickness=thickness_px, scale_invariant=True,
        points=[Point3(x=float(x), y=float(y), z=PATH_Z_M) for x, y in points],
        color=Color(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0))


def path_scene(t_s: float, frame_id: str, planned: Sequence[Point2],
               driven: Sequence[Point2], marks: dict[str, Point2]) -> SceneUpdate:
    """The plan (green), the path driven (blue) and named marks (the job's points, the
    blocks it found) in ``frame_id``, replacing what was drawn before."""
    lines = [line for line in (_line(planned, (0.1, 0.8, 0.3), 4.0) if planned else None,
                               _line(driven, (0.2, 0.5, 1.0), 3.0) if driven else None)
             if line is not None]
    spheres = [SpherePrimitive(pose=Pose(position=Vector3(x=x, y=y, z=PATH_Z_M),
                                         orientation=_yaw(0.0)),
                               size=Vector3(x=0.08, y=0.08, z=0.08),
                               color=_color(name.split()[-1], 0.9))
               for name, (x, y) in marks.items()]
    texts = [TextPrimitive(pose=Pose(position=Vector3(x=x, y=y, z=0.15),
                                     orientation=_yaw(0.0)),
                           billboard=True, font_size=14.0, scale_invariant=True,
                           color=_color("white"), text=name)
             for name, (x, y) in marks.items()]
    entity = SceneEntity(timestamp=stamp(t_s), frame_id=frame_id, id="job",
                         lines=lines, spheres=spheres, texts=texts)
    return SceneUpdate(entities=[entity])
