"""Eye-in-hand calibration: the wrist camera's pose on the wrist-pitch link.

The arm's own forward kinematics (DH frame 4) gives the link poses; the camera is
fixed on that link at a known, deliberately skewed pose; a tag board lies on the
table. Views are made by projecting the board (math only) or rendering it, with
pixel noise and joint-angle noise in the "measured" link poses, and the calibration
must recover the camera's pose without being told it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import ConfigError, VisionError
from busarm.vision.calibration import (
    BoardObservation,
    CameraIntrinsics,
    ChessboardSpec,
    TagBoardSpec,
    calibrate_hand_eye,
    find_board,
    render_board_view,
)

KIN = ArmKinematics.from_config(load_arm_config())
INTR = CameraIntrinsics.vendor_default()
SPEC = TagBoardSpec(4, 3, 30.0, 8.0)


def camera_on_link() -> np.ndarray:
    """cam2link: 51 mm behind and 64 mm above the wrist-pitch axis, looking along the
    tool (frame 4's y axis) tilted 15 deg forward, and a few degrees off every axis."""
    z = np.array([0.27, 1.0, 0.0])
    z /= np.linalg.norm(z)
    x = np.array([0.0, 0.0, -1.0])
    y = np.cross(z, x)
    out = np.eye(4)
    out[:3, :3] = np.stack([x, y, z], 1) @ Rotation.from_euler(
        "xyz", [1.5, -2.0, 3.0], degrees=True
    ).as_matrix()
    out[:3, 3] = [-51.0, -64.0, 3.0]
    return out


CAM2LINK = camera_on_link()
BOARD2BASE = np.eye(4)
BOARD2BASE[:3, :3] = np.diag([1.0, -1.0, -1.0])  # face up: board z points down
BOARD2BASE[:3, 3] = [170.0, 55.0, 0.0]


def errors(cam2link: np.ndarray) -> tuple[float, float]:
    """(translation mm, rotation deg) of an estimate against the truth."""
    d = np.linalg.inv(CAM2LINK) @ cam2link
    return float(np.linalg.norm(d[:3, 3])), float(
        np.degrees(np.linalg.norm(Rotation.from_matrix(d[:3, :3]).as_rotvec()))
    )


def poses(
    count: int, rng: np.random.Generator, *, pitch: tuple[float, float] = (-90.0, -55.0),
    y_mm: tuple[float, float] = (-90.0, 90.0),
) -> list[np.ndarray]:
    """Joint angles that point the tool at the board's region from varied directions
    (base yaw from the target's bearing, wrist pitch from the approach angle)."""
    out = []
    while len(out) < count:
        sols = KIN.ik(rng.uniform(150, 300), rng.uniform(*y_mm), rng.uniform(110, 200),
                      rng.uniform(*pitch))
        if sols:
            out.append(np.array(sols[0]))
    return out


def math_views(
    count: int, seed: int, *, px_noise: float, joint_noise_deg: float, **kw: tuple[float, float]
) -> tuple[list[np.ndarray], list[BoardObservation | None]]:
    """Link poses from noisy joints; board points projected with the true ones."""
    rng = np.random.default_rng(seed)
    links: list[np.ndarray] = []
    views: list[BoardObservation | None] = []
    for q in poses(3 * count, rng, **kw):
        board2cam = np.linalg.inv(KIN.frames(q)[3] @ CAM2LINK) @ BOARD2BASE
        p = SPEC.object_points @ board2cam[:3, :3].T + board2cam[:3, 3]
        if np.any(p[:, 2] < 50.0):
            continue
        px = INTR.pixels_from_camera_points(p)
        inside = (px[:, 0] > 5) & (px[:, 0] < 635) & (px[:, 1] > 5) & (px[:, 1] < 475)
        if inside.sum() < 16:
            continue
        px = px + rng.normal(0.0, px_noise, px.shape)
        views.append(BoardObservation(SPEC, SPEC.object_points[inside], px[inside],
                                      np.flatnonzero(inside), (640, 480)))
        links.append(KIN.frames(q + rng.normal(0.0, joint_noise_deg, 5))[3])
        if len(links) == count:
            break
    assert len(links) == count
    return links, views


def test_exact_data_give_the_exact_camera() -> None:
    links, views = math_views(8, 1, px_noise=0.0, joint_noise_deg=0.0)
    result = calibrate_hand_eye(links, views, INTR, pose_noise_deg=0, pose_noise_mm=0)
    dt, dr = errors(result.cam2link)
    assert dt < 1e-4 and dr < 1e-5
    assert np.abs(result.board2base - BOARD2BASE).max() < 1e-4
    assert result.rms_px < 1e-4 and result.views_used == tuple(range(8))
    assert len(result.per_view_rms_px) == 8 and result.link == "wrist_pitch"
    assert result.method in ("tsai", "park", "horaud", "andreff", "daniilidis")


def test_pixel_noise() -> None:
    links, views = math_views(15, 2, px_noise=0.15, joint_noise_deg=0.0)
    result = calibrate_hand_eye(links, views, INTR, pose_noise_deg=0, pose_noise_mm=0)
    dt, dr = errors(result.cam2link)
    assert dt < 0.3 and dr < 0.05
    assert 0.15 < result.rms_px < 0.25  # 0.15 px per axis
    assert 0.0 < result.translation_std_mm < 0.5


def test_joint_noise_and_pixel_noise() -> None:
    # Servo readings are 0.24 deg steps; 0.05 deg of noise per joint, 0.15 px per corner.
    links, views = math_views(20, 3, px_noise=0.15, joint_noise_deg=0.05)
    result = calibrate_hand_eye(links, views, INTR)
    dt, dr = errors(result.cam2link)
    assert dt < 1.0 and dr < 0.2
    assert 0.0 < result.pose_rms_deg < 0.3 and 0.0 < result.pose_rms_mm < 1.0
    # Treating the link poses as exact bends the camera pose to explain their errors.
    exact = calibrate_hand_eye(links, views, INTR, pose_noise_deg=0, pose_noise_mm=0)
    assert errors(exact.cam2link)[0] > 1.5 * dt


def test_rendered_tag_board_views() -> None:
    rng = np.random.default_rng(4)
    links, views = [], []
    for q in poses(12, rng):
        link = KIN.frames(q)[3]
        board2cam = np.linalg.inv(link @ CAM2LINK) @ BOARD2BASE
        img = render_board_view(SPEC, INTR, board2cam)
        img = np.clip(img + rng.normal(0.0, 2.0, img.shape), 0, 255).astype(np.uint8)
        links.append(link)
        views.append(find_board(img, SPEC))
    found = sum(v is not None for v in views)
    assert found >= 8
    result = calibrate_hand_eye(links, views, INTR, pose_noise_deg=0, pose_noise_mm=0)
    dt, dr = errors(result.cam2link)
    assert dt < 1.0 and dr < 0.2
    assert len(result.views_used) == found and result.rms_px < 0.2


def test_a_bad_view_is_dropped() -> None:
    links, views = math_views(10, 5, px_noise=0.1, joint_noise_deg=0.0)
    links[6] = links[6] @ np.block([  # a joint read 3 deg off in that view
        [Rotation.from_euler("z", 3.0, degrees=True).as_matrix(), np.zeros((3, 1))],
        [np.zeros((1, 3)), np.ones((1, 1))],
    ])
    result = calibrate_hand_eye(links, views, INTR, pose_noise_deg=0, pose_noise_mm=0)
    assert 6 not in result.views_used and len(result.views_used) == 9
    dt, dr = errors(result.cam2link)
    assert dt < 0.5 and dr < 0.1
    kept = calibrate_hand_eye(links, views, INTR, pose_noise_deg=0, pose_noise_mm=0,
                              reject_outliers=False)
    assert 6 in kept.views_used and errors(kept.cam2link)[0] > 2.0 * dt


def test_degenerate_motion_is_refused() -> None:
    # Same wrist pitch everywhere and the base turning: every rotation is about one axis.
    links, views = math_views(6, 6, px_noise=0.1, joint_noise_deg=0.0, pitch=(-80.0, -80.0))
    with pytest.raises(VisionError, match="degenerate motion: every rotation between views is "
                                          "about one axis"):
        calibrate_hand_eye(links, views, INTR)
    # Barely moving at all.
    links, views = math_views(4, 7, px_noise=0.1, joint_noise_deg=0.0, pitch=(-80.0, -79.0),
                              y_mm=(0.0, 1.0))
    with pytest.raises(VisionError, match="turns at most"):
        calibrate_hand_eye(links, views, INTR)


def test_bad_input_is_refused() -> None:
    links, views = math_views(5, 8, px_noise=0.1, joint_noise_deg=0.0)
    with pytest.raises(VisionError, match="board found in 2 of 5 views; need at least 3"):
        calibrate_hand_eye(links, [views[0], None, views[2], None, None], INTR)
    with pytest.raises(ConfigError, match="5 poses but observations has 4"):
        calibrate_hand_eye(links, views[:4], INTR)
    bent = [link.copy() for link in links]
    bent[1][0, 0] = 1.5
    with pytest.raises(ConfigError, match=r"link2base\[1\] is not a rigid transform"):
        calibrate_hand_eye(bent, views, INTR)
    chess = ChessboardSpec(3, 3, 10.0)
    flat = [BoardObservation(chess, chess.object_points, np.zeros((9, 2)), np.arange(9),
                             (640, 480))] * 5
    with pytest.raises(ConfigError, match="chessboard cannot calibrate hand-eye"):
        calibrate_hand_eye(links, flat, INTR)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="both be > 0"):
        calibrate_hand_eye(links, views, INTR, pose_noise_deg=0.1, pose_noise_mm=0)
    with pytest.raises(ConfigError, match="loss 'l3'"):
        calibrate_hand_eye(links, views, INTR, loss="l3")
