"""Calibration flows for the wrist camera: intrinsics, then hand-eye.

Both move the arm through views of a board lying on the table, take a picture at each,
and hand the observations to busarm.vision.calibration:

- ``calibration_views``: where to look from. The camera rides on the wrist-pitch link,
  so it only turns with the base and the pitch joints: every view looks along the
  vertical plane through the base axis at its target's bearing. Views differ by where
  on the board they aim (which moves the board about the image and turns it) and by the
  camera's tilt in that plane (-35..35 deg) and distance. Each candidate is checked with
  the *nominal* camera mount and intrinsics (the drawing and the vendor's file: only to
  choose views, never in the result) to keep the whole board in the picture, and the
  chosen set is spread out greedily.
- ``capture_views``: move, wait, let the picture settle, read the *measured* joints and
  take the picture; an interactive ``confirm`` callback can skip views.

The twin runs these without a person; on hardware the CLI asks before each view.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from busarm.arm.arm import Arm
from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import UnreachableError, VisionError
from busarm.perception.locate import CAMERA_LINK, link2base
from busarm.units import check_int_range
from busarm.vision.calibration import (
    BoardObservation,
    BoardSpec,
    CameraIntrinsics,
    ChessboardSpec,
    HandEyeResult,
    IntrinsicsResult,
    calibrate_hand_eye,
    calibrate_intrinsics,
    find_board,
)
from busarm.vision.camera import CameraSource

__all__ = [
    "GRIPPER_IN_VIEW",
    "IMAGE_MARGIN_PX",
    "MAX_HAND_EYE_RMS_PX",
    "MAX_HAND_EYE_STD_MM",
    "MAX_INTRINSICS_RMS_PX",
    "NOMINAL_MOUNT",
    "SETTLE_S",
    "CalibrationView",
    "FloatArray",
    "calibration_views",
    "capture_views",
    "hand_eye_from_views",
    "intrinsics_from_views",
    "joints_looking_at",
    "sees_points",
    "visible_fraction",
]


FloatArray = npt.NDArray[np.float64]

NOMINAL_MOUNT = CameraMount.from_config(load_arm_config().camera)
"""The camera where the shipped arm's drawing puts it (its ``[camera]``): for choosing views
only; ``calibration_views(mount=...)`` takes another arm's."""
IMAGE_MARGIN_PX = 12.0
SETTLE_S = 0.3


@dataclass(frozen=True)
class CalibrationView:
    """One picture of the board: the joints measured when it was taken, and what was found."""

    joints_deg: tuple[float, ...]
    link2base: FloatArray
    observation: BoardObservation | None
    image: npt.NDArray[np.uint8]


GRIPPER_IN_VIEW = (0.27, 0.70, 0.73, 1.0)
"""The part of the picture the gripper hides (left, top, right, bottom as fractions of
the image), seen from the wrist camera: the palm and fingers at the bottom centre."""


def _board_grid(spec: BoardSpec, board2base: FloatArray, n: int = 9) -> FloatArray:
    w, h = spec.extent_mm
    u, v = np.meshgrid(np.linspace(0, w, n), np.linspace(0, h, n))
    pts = np.stack([u.ravel(), v.ravel(), np.zeros(u.size), np.ones(u.size)], 1)
    out: FloatArray = (board2base @ pts.T).T[:, :3]
    return out


def visible_fraction(points_base: FloatArray, cam2base: FloatArray,
                     intrinsics: CameraIntrinsics, margin_px: float = IMAGE_MARGIN_PX,
                     hidden: tuple[float, float, float, float] = GRIPPER_IN_VIEW) -> float:
    """The share of the points that land in the picture, ``margin_px`` inside its border;
    0 if any lands where the gripper hides the picture (a marker cut by the gripper's edge
    could be found with a wrong corner; one cut by the picture's edge is not found)."""
    base2cam = np.linalg.inv(cam2base)
    p_cam = points_base @ base2cam[:3, :3].T + base2cam[:3, 3]
    if np.any(p_cam[:, 2] < 50.0):
        return 0.0
    px = intrinsics.pixels_from_camera_points(p_cam)
    w, h = intrinsics.width_px, intrinsics.height_px
    inside = np.all((px >= margin_px) & (px <= (w - 1 - margin_px, h - 1 - margin_px)), axis=1)
    x0, y0, x1, y1 = hidden
    behind = ((px[:, 0] >= x0 * w - margin_px) & (px[:, 0] <= x1 * w + margin_px)
              & (px[:, 1] >= y0 * h - margin_px) & (px[:, 1] <= y1 * h + margin_px))
    return 0.0 if np.any(behind) else float(np.mean(inside))


def sees_points(points_base: FloatArray, cam2base: FloatArray, intrinsics: CameraIntrinsics,
                margin_px: float = IMAGE_MARGIN_PX) -> bool:
    """Whether every point lands in the picture and clear of the gripper."""
    return visible_fraction(points_base, cam2base, intrinsics, margin_px) == 1.0


def _tool_in_link4(kin: ArmKinematics) -> FloatArray:
    """The tool point in link 4's frame (homogeneous): fixed, so any pose gives it."""
    frames = kin.frames([0.0, -90.0, 0.0, -90.0, 0.0])
    return np.asarray(np.linalg.inv(frames[CAMERA_LINK]) @ frames[-1][:, 3])


def joints_looking_at(
    kin: ArmKinematics, target_mm: Sequence[float], tilt_deg: float, distance_mm: float,
    mount: CameraMount = NOMINAL_MOUNT, *, tool_in_4: FloatArray | None = None,
) -> tuple[float, ...]:
    """Joints that put the (nominal) camera ``distance_mm`` from ``target_mm``, looking at it
    with its axis tilted ``tilt_deg`` from vertical in the plane through the base axis
    (positive: the camera nearer the base, looking outward). Raises UnreachableError.
    ``tool_in_4``: ``_tool_in_link4(kin)``, when the caller has it already."""
    tx, ty, tz = (float(v) for v in target_mm)
    bearing = math.atan2(ty, tx)
    e = np.array([math.cos(bearing), math.sin(bearing), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    tilt = math.radians(tilt_deg)
    cam = np.array([tx, ty, tz]) + distance_mm * (-math.sin(tilt) * e + math.cos(tilt) * up)
    pitch = tilt - math.pi / 2  # the camera axis' elevation; the tool's is the same
    axis = math.cos(pitch) * e + math.sin(pitch) * up
    above = -math.sin(pitch) * e + math.cos(pitch) * up
    # The tool point from the camera, through the link-4 geometry (tool axis = +y4,
    # "above" = +x4): tool = cam + (tool_y4 - cam_y4) * axis + (0 - cam_x4) * above.
    c = mount.cam2link[:3, 3]
    if tool_in_4 is None:
        tool_in_4 = _tool_in_link4(kin)
    tool = cam + (tool_in_4[1] - c[1]) * axis + (tool_in_4[0] - c[0]) * above
    sols = kin.ik(float(tool[0]), float(tool[1]), float(tool[2]), math.degrees(pitch), 0.0)
    facing = [q for q in sols if abs((q[0] - math.degrees(bearing) + 180) % 360 - 180) < 1.0]
    if not facing:
        raise UnreachableError(f"no joints look at ({tx:.1f}, {ty:.1f}, {tz:.1f}) mm from "
                               f"{distance_mm:g} mm at {tilt_deg:g} deg", "reach")
    return facing[0]


def calibration_views(
    kin: ArmKinematics, spec: BoardSpec, board2base: FloatArray, count: int, *,
    intrinsics_guess: CameraIntrinsics | None = None, seed: int = 0,
    tilt_range_deg: tuple[float, float] = (-35.0, 35.0),
    distance_range_mm: tuple[float, float] = (220.0, 450.0),
    min_visible: float | None = None, mount: CameraMount = NOMINAL_MOUNT,
) -> list[tuple[float, ...]]:
    """``count`` joint poses looking at the board from spread-out viewpoints.

    ``min_visible``: the share of the board that must be in the picture; by default all
    of a chessboard (it is found whole or not at all), 70 % of a board with markers.
    """
    if min_visible is None:
        min_visible = 1.0 if isinstance(spec, ChessboardSpec) else 0.7
    check_int_range("views", count, 3, 100)
    check_int_range("seed", seed, 0, 2**32 - 1)
    guess = intrinsics_guess or CameraIntrinsics.vendor_default()
    grid = _board_grid(spec, board2base)
    centre = grid.mean(axis=0)
    w, h = spec.extent_mm
    rng = np.random.default_rng(seed)
    tool_in_4 = _tool_in_link4(kin)
    candidates: list[tuple[tuple[float, ...], FloatArray]] = []
    for _ in range(200 * count):
        # Aim anywhere on the board (even off it a little): the board wanders in the image.
        u, v = rng.uniform(-1.1, 1.1, 2)
        target = centre + board2base[:3, 0] * u * w + board2base[:3, 1] * v * h
        tilt = rng.uniform(*tilt_range_deg)
        distance = rng.uniform(*distance_range_mm)
        try:
            q = joints_looking_at(kin, target, tilt, distance, mount, tool_in_4=tool_in_4)
        except UnreachableError:
            continue
        cam2base = link2base(kin, q) @ mount.cam2link
        if visible_fraction(grid, cam2base, guess) < min_visible:
            continue
        # Describe the view by where the camera is and which way it looks.
        candidates.append((q, np.concatenate([cam2base[:3, 3] / 100.0, cam2base[:3, 2] * 3])))
    if len(candidates) < count:
        raise VisionError(f"only {len(candidates)} of {count} views of the board at "
                          f"{np.round(centre, 1).tolist()} mm are reachable with "
                          f"{min_visible:.0%} of the board in the picture: move the board "
                          "nearer the arm's front")
    # Farthest-point sampling: each next view is the most unlike those chosen.
    feats = np.array([f for _, f in candidates])
    chosen = [int(np.argmin(np.linalg.norm(feats - feats.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(feats - feats[chosen[0]], axis=1)
    while len(chosen) < count:
        nxt = int(np.argmax(dist))
        chosen.append(nxt)
        dist = np.minimum(dist, np.linalg.norm(feats - feats[nxt], axis=1))
    return [candidates[i][0] for i in chosen]


def capture_views(
    arm: Arm, camera: CameraSource, poses: Sequence[Sequence[float]], spec: BoardSpec, *,
    speed_deg_s: float = 90.0, settle_s: float = SETTLE_S,
    confirm: Callable[[int, int], bool] | None = None,
    progress: Callable[[int, int, CalibrationView], None] | None = None,
) -> list[CalibrationView]:
    """Visit each pose, take a picture and look for the board in it.

    ``confirm(i, n)`` (interactive use) is asked before each picture and may skip it.
    """
    views: list[CalibrationView] = []
    for i, pose in enumerate(poses):
        arm.move_joints(pose, speed_deg_s=speed_deg_s)
        arm.clock.sleep(settle_s)  # let the arm stop swaying and the camera deliver a new frame
        if confirm is not None and not confirm(i, len(poses)):
            continue
        frame = camera.read()
        measured = arm.read_joints_deg()
        view = CalibrationView(tuple(measured), link2base(arm.kin, measured),
                               find_board(frame.image, spec), frame.image)
        views.append(view)
        if progress is not None:
            progress(i, len(poses), view)
    return views


MAX_INTRINSICS_RMS_PX = 1.0
"""A calibration worse than this is refused (a good one is 0.1-0.5 px)."""
MAX_HAND_EYE_RMS_PX = 2.0
"""A hand-eye fit worse than this is refused: wrong intrinsics, or the board moved."""
MAX_HAND_EYE_STD_MM = 3.0
"""... and so is one whose camera position is this uncertain (too little motion)."""


def intrinsics_from_views(views: Sequence[CalibrationView], model: str = "pinhole"
                          ) -> IntrinsicsResult:
    """Camera intrinsics from the board pictures (see busarm.vision.calibration); a fit
    whose reprojection error says it is wrong raises VisionError instead."""
    if not views:
        raise VisionError("no pictures were taken")
    h, w = views[0].image.shape[:2]
    result = calibrate_intrinsics([v.observation for v in views], (w, h), model)
    if result.rms_px > MAX_INTRINSICS_RMS_PX:
        raise VisionError(
            f"the calibration does not fit its pictures: reprojection rms {result.rms_px:.2f} "
            f"px (at most {MAX_INTRINSICS_RMS_PX:g}); is the board flat, sharp and still?")
    return result


def hand_eye_from_views(views: Sequence[CalibrationView], intrinsics: CameraIntrinsics
                        ) -> HandEyeResult:
    """The camera's pose on the wrist-pitch link from board pictures at measured joints;
    a fit whose errors say it is wrong raises VisionError instead."""
    result = calibrate_hand_eye([v.link2base for v in views],
                                [v.observation for v in views], intrinsics)
    if result.rms_px > MAX_HAND_EYE_RMS_PX or result.translation_std_mm > MAX_HAND_EYE_STD_MM:
        raise VisionError(
            f"the hand-eye fit is poor: reprojection rms {result.rms_px:.2f} px (at most "
            f"{MAX_HAND_EYE_RMS_PX:g}), camera position +-{result.translation_std_mm:.2f} mm "
            f"(at most {MAX_HAND_EYE_STD_MM:g}); are the intrinsics for this camera, and did "
            "the board stay still?")
    return result
