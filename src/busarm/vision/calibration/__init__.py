"""Camera calibration for the wrist camera: intrinsics, calibration boards, hand-eye.

Conventions (every public function):

- Millimetres and degrees; radians only inside.
- Transforms are 4x4 float64 homogeneous matrices named ``a2b``: ``p_b = a2b @ p_a``
  (``board2cam``, ``cam2link``, ``link2base``, ``board2base``).
- The OpenCV camera frame: x right, y down, z forward (out of the lens). Pixel
  coordinates are OpenCV's: the *centre* of pixel (u, v) is at (u, v), so a 640x480
  image spans -0.5 .. 639.5 by -0.5 .. 479.5 (the centroid of a mask's pixel indices is
  in the same coordinates).
- Board frames: origin at the pattern's outer top-left corner (chessboard and ChArUco:
  the corner of the square grid; tag board: the outer corner of the first tag's black
  border), x along the columns, y along the rows (down the printed page), z = x cross y
  pointing into the board, the surface at z = 0. A camera in front of the board sees
  the board's z axis pointing away from it. ``board_image`` documents the relation
  between the printable image's pixels and this frame exactly.

The flow:

1. Intrinsics: 10..30 images of a ChArUco board (or a chessboard) covering the whole
   image at tilts up to about 45 deg; ``find_board`` on each, ``calibrate_intrinsics``,
   ``save_intrinsics``.
2. Hand-eye (eye-in-hand: the camera rides on the wrist-pitch link): a tag board (or a
   ChArUco board) fixed on the table, the arm at 8..20 poses that turn the base *and*
   tilt the wrist; for each pose ``link2base`` (forward kinematics of the measured
   joints, DH frame 4) and ``find_board``; then ``calibrate_hand_eye``, ``save_hand_eye``.
   A chessboard cannot be used here: its pose is ambiguous under a half turn.

Modules:

- ``core``: array types and checks, rigid transforms (``as_transform``).
- ``camera_model``: ``CameraIntrinsics`` (projection, distortion, undistortion).
- ``boards``: board specs and their printable images (``board_image_frame``).
- ``detection``: ``find_board`` and ``BoardObservation``.
- ``render``: ``render_board_view``, synthetic views of a board.
- ``pose``: ``board_pose`` and reprojection errors.
- ``intrinsics``: ``calibrate_intrinsics``.
- ``handeye``: ``calibrate_hand_eye``.
- ``files``: ``load_*`` / ``save_*`` of the JSON formats.

Every public name is importable from this package.
"""

from __future__ import annotations

from busarm.vision.calibration.boards import (
    TAG_DICTIONARY,
    BoardSpec,
    CharucoSpec,
    ChessboardSpec,
    TagBoardSpec,
    board_image_frame,
)
from busarm.vision.calibration.camera_model import (
    MODELS,
    UNDISTORT_TOL_PX,
    CameraIntrinsics,
    distortion_text,
)
from busarm.vision.calibration.core import (
    RIGID_TOL,
    FloatArray,
    IntArray,
    UInt8Array,
    as_transform,
    invert_transform,
)
from busarm.vision.calibration.detection import (
    TAG_MIN_CELL_PX,
    BoardObservation,
    default_min_points,
    find_board,
)
from busarm.vision.calibration.files import (
    FORMAT_VERSION,
    HAND_EYE_FORMAT,
    INTRINSICS_FORMAT,
    load_hand_eye,
    load_intrinsics,
    save_hand_eye,
    save_intrinsics,
)
from busarm.vision.calibration.handeye import MIN_HAND_EYE_VIEWS, HandEyeResult, calibrate_hand_eye
from busarm.vision.calibration.intrinsics import (
    MIN_INTRINSIC_VIEWS,
    IntrinsicsResult,
    calibrate_intrinsics,
)
from busarm.vision.calibration.pose import OUTLIER_VIEW_PX, board_pose
from busarm.vision.calibration.render import render_board_view

__all__ = [
    "FORMAT_VERSION",
    "HAND_EYE_FORMAT",
    "INTRINSICS_FORMAT",
    "MIN_HAND_EYE_VIEWS",
    "MIN_INTRINSIC_VIEWS",
    "MODELS",
    "OUTLIER_VIEW_PX",
    "RIGID_TOL",
    "TAG_DICTIONARY",
    "TAG_MIN_CELL_PX",
    "UNDISTORT_TOL_PX",
    "BoardObservation",
    "BoardSpec",
    "CameraIntrinsics",
    "CharucoSpec",
    "ChessboardSpec",
    "FloatArray",
    "HandEyeResult",
    "IntArray",
    "IntrinsicsResult",
    "TagBoardSpec",
    "UInt8Array",
    "as_transform",
    "board_image_frame",
    "board_pose",
    "calibrate_hand_eye",
    "calibrate_intrinsics",
    "default_min_points",
    "distortion_text",
    "find_board",
    "invert_transform",
    "load_hand_eye",
    "load_intrinsics",
    "render_board_view",
    "save_hand_eye",
    "save_intrinsics",
]
