"""Camera model, calibration boards, board detection, intrinsics calibration, board pose.

Data are synthetic and seeded: boards are rendered through a known camera (with lens
distortion) by ``render_board_view``, or their points projected directly for the
math-only tests, and the calibration must recover what made them.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from busarm.errors import ConfigError, VisionError
from busarm.vision import calibration as cal
from busarm.vision.calibration import (
    BoardObservation,
    CameraIntrinsics,
    CharucoSpec,
    ChessboardSpec,
    TagBoardSpec,
    board_image_frame,
    board_pose,
    calibrate_intrinsics,
    find_board,
    render_board_view,
)

VENDOR = CameraIntrinsics.vendor_default()
K_VENDOR = VENDOR.camera_matrix
SIZE = (640, 480)


def pinhole(dist: list[float], k: np.ndarray = K_VENDOR) -> CameraIntrinsics:
    return CameraIntrinsics("pinhole", 640, 480, k, np.array(dist))


def fisheye(dist: list[float]) -> CameraIntrinsics:
    k = np.array([[260.0, 0.0, 321.0], [0.0, 261.0, 242.0], [0.0, 0.0, 1.0]])
    return CameraIntrinsics("fisheye", 640, 480, k, np.array(dist))


def aimed_pose(
    spec: cal.BoardSpec, intr: CameraIntrinsics, rng: np.random.Generator,
    pixel: tuple[float, float], depth: float, tilt_deg: float = 40.0,
) -> np.ndarray:
    """board2cam: the board's centre on the ray of ``pixel`` at ``depth``, tilted."""
    w, h = spec.extent_mm
    r = Rotation.from_euler(
        "xyz", [rng.uniform(-tilt_deg, tilt_deg), rng.uniform(-tilt_deg, tilt_deg),
                rng.uniform(-30, 30)], degrees=True,
    ).as_matrix()
    ray = np.append(intr.normalized_from_pixels([pixel])[0], 1.0)
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = ray * depth - r @ np.array([w / 2, h / 2, 0.0])
    return t


def camera_image(
    spec: cal.BoardSpec, intr: CameraIntrinsics, board2cam: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """A rendered view with a little optical blur and sensor noise."""
    img = cv2.GaussianBlur(render_board_view(spec, intr, board2cam), (0, 0), 0.6)
    return np.clip(img + rng.normal(0.0, 2.0, img.shape), 0, 255).astype(np.uint8)


def projected(obs: BoardObservation, intr: CameraIntrinsics, board2cam: np.ndarray) -> np.ndarray:
    p = obs.object_points_mm @ board2cam[:3, :3].T + board2cam[:3, 3]
    return intr.pixels_from_camera_points(p)


# --------------------------------------------------------------------------- camera model


@pytest.mark.parametrize(
    "dist",
    [[-0.0275, -0.0005, -0.0059, -0.0034, -0.0356], [0.1, -0.2, 0.001, -0.002],
     [-0.3, 0.1, 0.002, 0.001, -0.02, 0.05, 0.01, -0.003]],
)
def test_pinhole_projection_matches_opencv(dist: list[float]) -> None:
    intr = pinhole(dist)
    rng = np.random.default_rng(1)
    p = rng.uniform([-150, -120, 200], [150, 120, 600], (200, 3))
    ours = intr.pixels_from_camera_points(p)
    theirs, _ = cv2.projectPoints(p, np.zeros(3), np.zeros(3), intr.camera_matrix, intr.distortion)
    assert np.abs(ours - theirs.reshape(-1, 2)).max() < 1e-9
    homogeneous = intr._project_h(p)  # the block-location hot path: same model
    assert np.abs(homogeneous[:, :2] - ours).max() < 1e-9
    assert np.all(homogeneous[:, 2] == 1.0)


def test_fisheye_projection_matches_opencv() -> None:
    intr = fisheye([0.02, -0.01, 0.004, -0.001])
    rng = np.random.default_rng(2)
    p = rng.uniform([-300, -300, 100], [300, 300, 400], (200, 3))
    ours = intr.pixels_from_camera_points(p)
    theirs, _ = cv2.fisheye.projectPoints(
        p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), intr.camera_matrix, intr.distortion
    )
    assert np.abs(ours - theirs.reshape(-1, 2)).max() < 1e-9
    assert np.abs(intr._project_h(p)[:, :2] - ours).max() < 1e-9


@pytest.mark.parametrize(
    "intr",
    [VENDOR, pinhole([-0.33, 0.12, 0.003, -0.002, -0.02]),
     pinhole([-0.3, 0.1, 0.002, 0.001, -0.02, 0.05, 0.01, -0.003]),
     fisheye([0.02, -0.01, 0.004, -0.001])],
    ids=["vendor", "strong-barrel", "rational", "fisheye"],
)
def test_undistortion_round_trip(intr: CameraIntrinsics) -> None:
    # Points the lens can image (inside the image), from known undistorted coordinates.
    rng = np.random.default_rng(3)
    xy = rng.uniform(-0.9, 0.9, (3000, 2)) * (1.0, 0.75)
    px = intr._distort(xy)
    inside = (px[:, 0] > 0) & (px[:, 0] < 639) & (px[:, 1] > 0) & (px[:, 1] < 479)
    assert inside.sum() > 500
    back = intr.normalized_from_pixels(px[inside])
    assert np.abs(back - xy[inside]).max() < 1e-7
    assert np.abs(intr._distort(back) - px[inside]).max() < 0.01


def test_pixel_beyond_the_fold_is_refused() -> None:
    # k1 = -0.5: no ray reaches the image corners (r (1 - 0.5 r^2) peaks at 0.54).
    intr = pinhole([-0.5, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(VisionError, match=r"pixel \(0\.00, 0\.00\) \(#1\)"):
        intr.normalized_from_pixels([[320.0, 240.0], [0.0, 0.0]])


def test_point_behind_the_camera_is_refused() -> None:
    with pytest.raises(VisionError, match="#1"):
        VENDOR.pixels_from_camera_points([[0, 0, 100], [0, 0, -5]])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"model": "kannala"}, "camera model 'kannala'"),
        ({"width_px": 0}, "width_px"),
        ({"camera_matrix": [[470, 1, 320], [0, 470, 240], [0, 0, 1]]}, "no skew"),
        ({"camera_matrix": [[-470, 0, 320], [0, 470, 240], [0, 0, 1]]}, "fx"),
        ({"camera_matrix": [[470, 0, 700], [0, 470, 240], [0, 0, 1]]}, "principal point"),
        ({"camera_matrix": [[470, 0, 320], [0, np.nan, 240], [0, 0, 1]]}, "finite"),
        ({"distortion": [0.1, 0.2, 0.0]}, "4 or 5 or 8"),
        ({"model": "fisheye", "distortion": [0.1, 0.2, 0.0, 0.0, 0.0]}, "fisheye distortion"),
        ({"distortion": [0.1, np.inf, 0, 0, 0]}, "finite"),
    ],
)
def test_intrinsics_are_validated(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {
        "model": "pinhole", "width_px": 640, "height_px": 480, "camera_matrix": K_VENDOR,
        "distortion": np.zeros(5),
    }
    args.update(kwargs)
    with pytest.raises(ConfigError, match=match):
        CameraIntrinsics(**args)  # type: ignore[arg-type]


def test_vendor_default_and_value_semantics() -> None:
    v = CameraIntrinsics.vendor_default()
    assert (v.fx, v.fy, v.cx, v.cy) == (473.45, 474.22, 323.55, 238.60)
    assert v.distortion.tolist() == [-0.0275, -0.0005, -0.0059, -0.0034, -0.0356]
    assert not v.calibrated and "not calibrated" in v.describe()
    same = CameraIntrinsics("pinhole", 640, 480, v.camera_matrix.copy(), v.distortion.copy(),
                            calibrated=False)
    assert same == v and hash(same) == hash(v)
    assert pinhole(v.distortion.tolist()) != v  # calibrated differs
    with pytest.raises(ValueError):
        v.camera_matrix[0, 0] = 1.0  # read-only


def test_undistort_image_straightens_the_board() -> None:
    spec = ChessboardSpec(7, 5, 20.0)
    strong = pinhole([-0.25, 0.08, 0.0, 0.0, 0.0])
    ideal = pinhole([0.0, 0.0, 0.0, 0.0, 0.0])
    board2cam = aimed_pose(spec, ideal, np.random.default_rng(4), (320, 240), 260.0, 15.0)
    img = cv2.GaussianBlur(render_board_view(spec, strong, board2cam), (0, 0), 0.6)
    flat = strong.undistort_image(img)
    maps = strong._cache["undistort_maps"]
    assert np.array_equal(strong.undistort_image(img), flat)
    assert strong._cache["undistort_maps"] is maps  # computed once
    obs = find_board(flat, spec)
    assert obs is not None
    truth = projected(obs, ideal, board2cam)
    err = np.minimum(  # a chessboard may be reported from either end
        np.abs(obs.image_points_px - truth).max(), np.abs(obs.image_points_px - truth[::-1]).max()
    )
    assert err < 0.35  # bilinear resampling blurs a little; distortion itself is gone
    with pytest.raises(ConfigError, match="1280x720 but these intrinsics are for 640x480"):
        strong.undistort_image(np.zeros((720, 1280), np.uint8))


# --------------------------------------------------------------------------- boards


@pytest.mark.parametrize(
    ("factory", "match"),
    [
        (lambda: ChessboardSpec(1, 5, 20.0), "inner_cols"),
        (lambda: ChessboardSpec(7, 5, 0.0), "square_mm"),
        (lambda: CharucoSpec(5, 4, 20.0, 20.0), "marker_mm"),
        (lambda: CharucoSpec(5, 4, 20.0, 12.0, "DICT_NOPE"), "DICT_NOPE"),
        (lambda: CharucoSpec(20, 20, 20.0, 12.0, "DICT_4X4_50"), "needs 200 markers"),
        (lambda: TagBoardSpec(4, 3, 40.0, 2.0), "gap_mm"),
        (lambda: TagBoardSpec(4, 3, 40.0, 10.0, first_id=580), "first_id"),
        (lambda: ChessboardSpec(7, 5, 20.0).board_image(0.0), "px_per_mm"),
    ],
)
def test_board_specs_are_validated(factory: object, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        factory()  # type: ignore[operator]


def test_board_object_points() -> None:
    chess = ChessboardSpec(4, 3, 25.0)
    assert chess.object_points.shape == (12, 3)
    assert chess.object_points[0].tolist() == [25.0, 25.0, 0.0]
    assert chess.object_points[5].tolist() == [50.0, 50.0, 0.0]  # row by row
    charuco = CharucoSpec(5, 4, 20.0, 12.0)
    assert charuco.object_points.shape == (12, 3)
    assert charuco.object_points[5].tolist() == [40.0, 40.0, 0.0]
    tags = TagBoardSpec(3, 2, 40.0, 10.0, first_id=7)
    pts = tags.object_points.reshape(6, 4, 3)
    assert pts[0].tolist() == [[0, 0, 0], [40, 0, 0], [40, 40, 0], [0, 40, 0]]
    assert pts[4, 0].tolist() == [50.0, 50.0, 0.0]  # tag 4: column 1, row 1
    assert tags.extent_mm == (140.0, 90.0)


def test_board_image_pixels_match_the_documented_frame() -> None:
    spec = ChessboardSpec(3, 2, 20.0)  # 4 x 3 squares, top-left black
    img = spec.board_image(2.0, margin_mm=10.0)
    x_min, y_min, width, height = board_image_frame(spec, 2.0, 10.0)
    assert (x_min, y_min, width, height) == (-10.0, -10.0, 200, 160)
    assert img.shape == (160, 200) and img.dtype == np.uint8
    # Board x in [0, 20) mm is columns 20..59 at 2 px/mm after a 10 mm margin.
    assert np.all(img[20:60, 20:60] == 0)
    assert np.all(img[20:60, 60:100] == 255)
    assert np.all(img[:20, :] == 255) and np.all(img[:, :20] == 255)
    assert np.all(img[60:100, 60:100] == 0)


@pytest.mark.parametrize(
    "spec",
    [ChessboardSpec(7, 5, 20.0), CharucoSpec(6, 5, 20.0, 12.0), TagBoardSpec(3, 2, 30.0, 10.0)],
    ids=["chessboard", "charuco", "tags"],
)
def test_detected_points_land_where_the_image_frame_says(spec: cal.BoardSpec) -> None:
    ppm = 4.0
    img = cv2.GaussianBlur(spec.board_image(ppm), (0, 0), 1.0)
    obs = find_board(img, spec)
    assert obs is not None
    x_min, y_min, _, _ = board_image_frame(spec, ppm)
    expected = (obs.object_points_mm[:, :2] - (x_min, y_min)) * ppm - 0.5  # pixel centres
    if isinstance(spec, ChessboardSpec):
        expected = np.where(  # either end of the chessboard
            np.abs(obs.image_points_px - expected).max() < 1.0, expected, expected[::-1]
        )
    assert np.abs(obs.image_points_px - expected).max() < 0.08
    assert obs.count == spec.object_points.shape[0]


@pytest.fixture(scope="module")
def rendered_views() -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """Three views of each board through the vendor camera, with distortion."""
    rng = np.random.default_rng(5)
    specs = {
        "chessboard": ChessboardSpec(7, 5, 20.0),
        "charuco": CharucoSpec(7, 5, 20.0, 12.0),
        "tags": TagBoardSpec(4, 3, 30.0, 8.0),
    }
    out = {}
    for name, spec in specs.items():
        views = []
        for pixel in ((320, 240), (200, 170), (440, 300)):
            t = aimed_pose(spec, VENDOR, rng, pixel, rng.uniform(300, 380), 35.0)
            views.append((t, camera_image(spec, VENDOR, t, rng)))
        out[name] = views
    return out


@pytest.mark.parametrize("name", ["chessboard", "charuco", "tags"])
def test_find_board_in_camera_views(
    rendered_views: dict[str, list[tuple[np.ndarray, np.ndarray]]], name: str
) -> None:
    spec = {"chessboard": ChessboardSpec(7, 5, 20.0), "charuco": CharucoSpec(7, 5, 20.0, 12.0),
            "tags": TagBoardSpec(4, 3, 30.0, 8.0)}[name]
    errors = []
    for board2cam, img in rendered_views[name]:
        obs = find_board(img, spec)
        assert obs is not None
        assert obs.image_size == SIZE
        truth = projected(obs, VENDOR, board2cam)
        err = obs.image_points_px - truth
        if isinstance(spec, ChessboardSpec) and np.abs(err).max() > 2.0:
            err = obs.image_points_px - truth[::-1]
        errors.append(err)
        assert len(set(obs.ids.tolist())) == obs.count
    e = np.concatenate(errors)
    assert np.sqrt((e**2).sum(axis=1).mean()) < 0.12  # corner accuracy, px rms
    assert np.abs(e).max() < 0.5
    assert np.abs(e.mean(axis=0)).max() < 0.05  # no half-pixel convention offset


def test_find_board_partial_views_and_misses() -> None:
    rng = np.random.default_rng(6)
    tags = TagBoardSpec(4, 3, 30.0, 8.0)
    charuco = CharucoSpec(7, 5, 20.0, 12.0)
    for spec in (tags, charuco):
        # The board's centre near the right edge: about half of it is out of the image.
        t = aimed_pose(spec, VENDOR, rng, (630, 240), 330.0, 10.0)
        img = camera_image(spec, VENDOR, t, rng)
        obs = find_board(img, spec)
        assert obs is not None
        assert cal.default_min_points(spec) <= obs.count < spec.object_points.shape[0]
        assert np.abs(obs.image_points_px - projected(obs, VENDOR, t)).max() < 0.5
        assert find_board(img, spec, min_points=spec.object_points.shape[0]) is None
        bgr = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        again = find_board(bgr, spec)
        assert again is not None and again.count == obs.count
    blank = np.full((480, 640), 128, np.uint8)
    for spec in (tags, charuco, ChessboardSpec(7, 5, 20.0)):
        assert find_board(blank, spec) is None
    # Another board's tags are not this board's.
    other = TagBoardSpec(4, 3, 30.0, 8.0, first_id=100)
    t = aimed_pose(tags, VENDOR, rng, (320, 240), 330.0, 10.0)
    assert find_board(camera_image(tags, VENDOR, t, rng), other) is None
    with pytest.raises(ConfigError, match="uint8"):
        find_board(np.zeros((480, 640), np.float32), tags)


# --------------------------------------------------------------------------- intrinsics


def test_calibrate_intrinsics_from_rendered_charuco_views() -> None:
    rng = np.random.default_rng(7)
    spec = CharucoSpec(9, 7, 20.0, 12.0)
    observations = []
    for i in range(12):  # board centres spread over the image, corners included
        pixel = ((70, 320, 570)[i % 3] + rng.uniform(-20, 20),
                 (70, 240, 410)[(i // 3) % 3] + rng.uniform(-20, 20))
        t = aimed_pose(spec, VENDOR, rng, pixel, rng.uniform(280, 420))
        observations.append(find_board(camera_image(spec, VENDOR, t, rng), spec))
    result = calibrate_intrinsics(observations, SIZE)
    k = result.intrinsics.camera_matrix
    assert np.abs(k[[0, 1, 0, 1], [0, 1, 2, 2]] - K_VENDOR[[0, 1, 0, 1], [0, 1, 2, 2]]).max() < 1.0
    assert result.rms_px < 0.1
    assert len(result.per_view_rms_px) == len(result.views_used) >= 10
    assert result.intrinsics.calibrated and "charuco 9x7" in result.board
    # The calibrated camera maps pixels to rays as the true one does, up to a small
    # common rotation (which a hand-eye calibration absorbs): compare after Kabsch.
    grid = np.stack(np.meshgrid(np.linspace(40, 600, 9), np.linspace(30, 450, 7)), -1)
    grid = grid.reshape(-1, 2)
    assert ray_mismatch_px(result.intrinsics, VENDOR, grid) < 0.3


def ray_mismatch_px(a: CameraIntrinsics, b: CameraIntrinsics, px: np.ndarray) -> float:
    """Largest angle between the rays two cameras give the same pixels, after the best
    common rotation, in pixels of ``b``'s focal length."""
    rays = []
    for intr in (a, b):
        r = np.hstack([intr.normalized_from_pixels(px), np.ones((px.shape[0], 1))])
        rays.append(r / np.linalg.norm(r, axis=1, keepdims=True))
    u, _, vt = np.linalg.svd(rays[0].T @ rays[1])
    rot = (u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt).T
    angle = np.arccos(np.clip(((rays[0] @ rot.T) * rays[1]).sum(axis=1), -1.0, 1.0))
    return float(angle.max() * b.fx)


def test_calibrate_intrinsics_from_rendered_chessboard_views() -> None:
    rng = np.random.default_rng(8)
    spec = ChessboardSpec(8, 6, 20.0)
    observations = []
    for i in range(9):
        pixel = ((200, 320, 440)[i % 3], (160, 240, 320)[i // 3])
        t = aimed_pose(spec, VENDOR, rng, pixel, rng.uniform(320, 420), 35.0)
        observations.append(find_board(camera_image(spec, VENDOR, t, rng), spec))
    result = calibrate_intrinsics(observations, SIZE, fix_k3=True)
    k = result.intrinsics.camera_matrix
    assert np.abs(k[[0, 1, 0, 1], [0, 1, 2, 2]] - K_VENDOR[[0, 1, 0, 1], [0, 1, 2, 2]]).max() < 2.0
    assert result.intrinsics.distortion[4] == 0.0  # k3 held at 0
    assert result.rms_px < 0.2


def synthetic_observations(
    intr: CameraIntrinsics, spec: cal.BoardSpec, count: int, noise_px: float, seed: int,
    depth: tuple[float, float] = (280.0, 420.0), poses: list[np.ndarray] | None = None,
) -> list[BoardObservation]:
    """Board points projected straight through ``intr`` (math only), in-image points;
    the board2cam of each view is appended to ``poses``."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        pixel = ((80, 320, 560)[i % 3] + rng.uniform(-30, 30),
                 (80, 240, 400)[(i // 3) % 3] + rng.uniform(-30, 30))
        t = aimed_pose(spec, intr, rng, pixel, rng.uniform(*depth))
        if poses is not None:
            poses.append(t)
        p = spec.object_points @ t[:3, :3].T + t[:3, 3]
        px = intr.pixels_from_camera_points(p) + rng.normal(0.0, noise_px, (p.shape[0], 2))
        keep = (px[:, 0] > 0) & (px[:, 0] < 639) & (px[:, 1] > 0) & (px[:, 1] < 479)
        out.append(BoardObservation(spec, spec.object_points[keep], px[keep],
                                    np.flatnonzero(keep), SIZE))
    return out


def test_calibrate_fisheye() -> None:
    truth = fisheye([0.02, -0.01, 0.004, -0.001])
    obs = synthetic_observations(truth, CharucoSpec(9, 7, 20.0, 12.0), 12, 0.1, 9, (150, 250))
    result = calibrate_intrinsics(obs, SIZE, "fisheye")
    k = result.intrinsics.camera_matrix
    assert result.intrinsics.model == "fisheye"
    fx_fy_cx_cy = [0, 1, 0, 1], [0, 1, 2, 2]
    assert np.abs(k[fx_fy_cx_cy] - truth.camera_matrix[fx_fy_cx_cy]).max() < 1.0
    # 0.1 px noise per axis is 0.14 px of 2-D error, less what the fit absorbs.
    assert 0.11 < result.rms_px < 0.15


def test_fisheye_ill_conditioned_view_is_dropped(monkeypatch: pytest.MonkeyPatch) -> None:
    truth = fisheye([0.02, -0.01, 0.004, -0.001])
    obs = synthetic_observations(truth, CharucoSpec(9, 7, 20.0, 12.0), 8, 0.05, 10, (150, 250))
    real = cv2.fisheye.calibrate
    calls: list[int] = []

    def flaky(objp, *args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(len(objp))
        if len(calls) == 1:  # OpenCV's complaint about one view
            raise cv2.error("CALIB_CHECK_COND - Ill-conditioned matrix for input array 3")
        return real(objp, *args, **kwargs)

    monkeypatch.setattr(cv2.fisheye, "calibrate", flaky)
    result = calibrate_intrinsics(obs, SIZE, "fisheye")
    assert calls == [8, 7]
    assert result.views_dropped == (3,)
    assert 3 not in result.views_used and len(result.views_used) == 7


def test_outlier_view_is_dropped() -> None:
    obs = synthetic_observations(VENDOR, CharucoSpec(9, 7, 20.0, 12.0), 10, 0.1, 11)
    bad = obs[4]
    rng = np.random.default_rng(12)
    obs[4] = BoardObservation(bad.spec, bad.object_points_mm,
                              bad.image_points_px + rng.normal(0, 4.0, bad.image_points_px.shape),
                              bad.ids, SIZE)
    result = calibrate_intrinsics(obs, SIZE)
    assert result.views_dropped == (4,)
    assert result.rms_px < 0.15
    kept = calibrate_intrinsics(obs, SIZE, reject_outliers=False)
    assert kept.views_dropped == () and kept.rms_px > 0.5


def test_calibrate_intrinsics_refuses_bad_input() -> None:
    obs = synthetic_observations(VENDOR, CharucoSpec(9, 7, 20.0, 12.0), 3, 0.1, 13)
    with pytest.raises(VisionError, match="board found in 3 of 5 images; need at least 6"):
        calibrate_intrinsics([*obs, None, None], SIZE)
    with pytest.raises(ConfigError, match="1280x720"):
        calibrate_intrinsics(obs, (1280, 720), min_views=3)
    with pytest.raises(ConfigError, match="camera model"):
        calibrate_intrinsics(obs, SIZE, "orthographic")


# --------------------------------------------------------------------------- board pose


@pytest.mark.parametrize(
    "intr", [VENDOR, fisheye([0.02, -0.01, 0.004, -0.001])], ids=["pinhole", "fisheye"]
)
def test_board_pose(intr: CameraIntrinsics) -> None:
    spec = TagBoardSpec(4, 3, 30.0, 8.0)
    poses: list[np.ndarray] = []
    exact = synthetic_observations(intr, spec, 1, 0.0, 14, (200, 260), poses)[0]
    truth = poses[0]
    rng = np.random.default_rng(14)
    pose, rms = board_pose(exact, intr)
    assert rms < 1e-6
    assert np.abs(pose - truth).max() < 1e-5
    noise = rng.normal(0, 0.15, exact.image_points_px.shape)
    noisy = BoardObservation(spec, exact.object_points_mm, exact.image_points_px + noise,
                             exact.ids, SIZE)
    pose, rms = board_pose(noisy, intr)
    assert 0.05 < rms < 0.25
    assert np.linalg.norm(pose[:3, 3] - truth[:3, 3]) < 1.0
    other = CameraIntrinsics(intr.model, 1280, 720, intr.camera_matrix, intr.distortion)
    with pytest.raises(ConfigError, match="1280x720"):
        board_pose(exact, other)


def test_board_observation_is_validated() -> None:
    with pytest.raises(ConfigError, match="as many object points"):
        BoardObservation(ChessboardSpec(3, 3, 10.0), np.zeros((4, 3)), np.zeros((3, 2)),
                         np.arange(4), SIZE)
    with pytest.raises(ConfigError, match="finite"):
        BoardObservation(ChessboardSpec(3, 3, 10.0), np.zeros((4, 3)),
                         np.full((4, 2), np.nan), np.arange(4), SIZE)
