"""The floor line in metres, from synthetic pictures with a known truth.

A floor is drawn from above with OpenCV (a slightly noisy light floor, tape as an
antialiased polyline 30 mm wide, at 1.5 mm a pixel), then seen through a pinhole camera
at the look-ahead pose's height and tilt: ``cv2.warpPerspective`` by the floor-to-image
homography, or, for a lens with distortion, a ``cv2.remap`` whose every pixel's ray is
met with the floor. The truth is the polyline drawn, in the base frame.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.errors import ConfigError, VisionError
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.floor_line import FloorLineSighting, find_floor_line
from busarm.vision.tape_colour import check_tape, measure_tape

K = np.array([[474.0, 0.0, 320.0], [0.0, 474.0, 240.0], [0.0, 0.0, 1.0]])
PINHOLE = CameraIntrinsics("pinhole", 640, 480, K, np.zeros(5))
WIDE = CameraIntrinsics("pinhole", 640, 480, K, np.array([-0.30, 0.12, 0.0008, -0.0006, -0.02]))
RES_M = 0.0015
"""Metres per pixel of the drawn floor."""
EXTENT_M = (-0.3, 1.8, -1.1, 1.1)
"""The drawn floor: x from, x to, y from, y to (base frame)."""
FLOOR_BGR = (170, 180, 186)
TAPE_M = 0.03
Image = npt.NDArray[np.uint8]
Points = npt.NDArray[np.float64]


def camera_pose(x_m: float = 0.165, y_m: float = 0.0, z_m: float = 0.57,
                pitch_down_deg: float = 73.7, yaw_deg: float = 0.0) -> Points:
    """cam_to_floor of a camera at (x, y, z) looking ``pitch_down_deg`` below the horizon
    toward ``yaw_deg``, its image's x to the right (the look-ahead pose's: 0.57 m up)."""
    p, y = math.radians(pitch_down_deg), math.radians(yaw_deg)
    z_axis = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), -math.sin(p)])
    x_axis = np.array([math.sin(y), -math.cos(y), 0.0])
    out = np.eye(4)
    out[:3, 0], out[:3, 1], out[:3, 2] = x_axis, np.cross(z_axis, x_axis), z_axis
    out[:3, 3] = (x_m, y_m, z_m)
    return out


POSE = camera_pose()


def texture_px(points_m: Points) -> Points:
    """Floor points (m) -> pixels of the drawn floor."""
    x0, _, _, y1 = EXTENT_M
    return np.column_stack([(points_m[:, 0] - x0) / RES_M, (y1 - points_m[:, 1]) / RES_M])


@functools.lru_cache(maxsize=2)
def bare_floor(seed: int) -> Image:
    """The floor without anything on it: its colour with a little noise."""
    x0, x1, y0, y1 = EXTENT_M
    size = (round((y1 - y0) / RES_M), round((x1 - x0) / RES_M))
    rng = np.random.default_rng(seed)
    noisy = np.array(FLOOR_BGR) + rng.normal(0.0, 3.0, (*size, 1))
    return np.asarray(np.clip(noisy, 0, 255), dtype=np.uint8)


def floor(lines: Sequence[Points] = (), *,
          blobs: Sequence[tuple[Points, tuple[int, int, int]]] = (),
          tape_bgr: tuple[int, int, int] = (8, 8, 8), seed: int = 0) -> Image:
    """The floor from above: ``lines`` (polylines, m) taped on it, ``blobs`` (polygons, m)
    filled in their colour."""
    image = bare_floor(seed).copy()
    shift = 4
    for points in lines:
        pts = np.round(texture_px(points) * (1 << shift)).astype(np.int32)
        cv2.polylines(image, [pts], False, tape_bgr, round(TAPE_M / RES_M), cv2.LINE_AA, shift)
    for polygon, bgr in blobs:
        pts = np.round(texture_px(polygon) * (1 << shift)).astype(np.int32)
        cv2.fillPoly(image, [pts], bgr, cv2.LINE_AA, shift)
    return image


def seen(texture: Image, pose: Points = POSE, intrinsics: CameraIntrinsics = PINHOLE
         ) -> Image:
    """What the camera at ``pose`` sees of the drawn floor."""
    x0, _, _, y1 = EXTENT_M
    floor2cam = np.linalg.inv(pose)
    if not np.any(intrinsics.distortion):
        tex_to_floor = np.array([[RES_M, 0.0, x0], [0.0, -RES_M, y1], [0.0, 0.0, 1.0]])
        floor_to_px = intrinsics.camera_matrix @ floor2cam[:3][:, [0, 1, 3]]
        return np.asarray(cv2.warpPerspective(
            texture, floor_to_px @ tex_to_floor, intrinsics.size, flags=cv2.INTER_LINEAR,
            borderValue=FLOOR_BGR), dtype=np.uint8)
    w, h = intrinsics.size
    px = np.stack(np.meshgrid(np.arange(w), np.arange(h)), -1).reshape(-1, 2).astype(float)
    xy = cv2.undistortPointsIter(px.reshape(-1, 1, 2), intrinsics.camera_matrix,
                                 intrinsics.distortion, np.eye(3), np.eye(3),
                                 (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-10))
    ray = np.c_[xy.reshape(-1, 2), np.ones(len(px))] @ pose[:3, :3].T
    s = -pose[2, 3] / ray[:, 2]
    hit = pose[:3, 3][:2] + s[:, None] * ray[:, :2]
    tex = texture_px(hit).astype(np.float32).reshape(h, w, 2)
    return np.asarray(cv2.remap(texture, tex[..., 0], tex[..., 1], cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_CONSTANT, borderValue=FLOOR_BGR),
                      dtype=np.uint8)


def straight(lateral_m: float = 0.0, heading_deg: float = 0.0, x_from: float = -0.2,
             x_to: float = 1.6) -> Points:
    """A straight tape through (0, lateral_m) at ``heading_deg`` from the base's x."""
    a = math.radians(heading_deg)
    s = np.linspace(x_from, x_to, 200)
    return np.column_stack([s * math.cos(a), lateral_m + s * math.sin(a)])


def arc(radius_m: float, start: tuple[float, float] = (-0.05, 0.0), sweep_deg: float = 150.0
        ) -> Points:
    """A tape from ``start`` heading along x, curving left (radius > 0) or right."""
    t = np.linspace(0.0, math.radians(sweep_deg), 300)
    r = abs(radius_m)
    return np.column_stack([start[0] + r * np.sin(t),
                            start[1] + math.copysign(1.0, radius_m) * r * (1 - np.cos(t))])


def s_line(amplitude_m: float = 0.05, wavelength_m: float = 0.8) -> Points:
    x = np.linspace(-0.2, 1.6, 600)
    return np.column_stack([x, amplitude_m * np.sin(2 * math.pi * x / wavelength_m)])


def distance_to(truth: Points, points: Points) -> Points:
    """Each point's distance (m) to the polyline ``truth``."""
    a, b = truth[:-1], truth[1:]
    ab = b - a
    out = []
    for q in points:
        t = np.clip(((q - a) * ab).sum(1) / (ab * ab).sum(1), 0.0, 1.0)
        out.append(np.min(np.hypot(*(a + t[:, None] * ab - q).T)))
    return np.array(out)


def truth_at_x(truth: Points, x_m: float) -> tuple[float, float]:
    """(y, heading rad) of ``truth`` where it first reaches x = ``x_m``."""
    side = truth[:, 0] - x_m
    k = int(np.flatnonzero(side[:-1] * side[1:] <= 0)[0])
    f = side[k] / (side[k] - side[k + 1])
    d = truth[k + 1] - truth[k]
    return float(truth[k, 1] + f * d[1]), math.atan2(d[1], d[0])


def find(image: Image, **options: object) -> FloorLineSighting:
    sighting = find_floor_line(image, options.pop("intrinsics", PINHOLE),  # type: ignore[arg-type]
                               options.pop("pose", POSE), **options)  # type: ignore[arg-type]
    assert sighting is not None
    return sighting


def check_on(truth: Points, sighting: FloorLineSighting, within_m: float = 0.005) -> None:
    """The sighting's points lie on ``truth``, start near the robot and reach far."""
    assert np.max(distance_to(truth, sighting.points_m)) < within_m
    assert sighting.length_m > 0.3
    near = np.hypot(*sighting.points_m[0])
    assert near == pytest.approx(np.min(np.hypot(*sighting.points_m.T)))
    assert sighting.width_m == pytest.approx(TAPE_M, abs=0.006)


# ---------------------------------------------------------------------- lines


def test_a_straight_line_ahead() -> None:
    truth = straight()
    sighting = find(seen(floor([truth])))
    check_on(truth, sighting)
    assert sighting.found_share == 1.0
    assert sighting.points_m[0, 0] < 0.2 and sighting.points_m[-1, 0] > 0.65
    for x in (0.0, 0.3, 0.5):
        assert sighting.lateral_m(x) == pytest.approx(0.0, abs=0.003)
        assert math.degrees(sighting.heading_rad(x)) == pytest.approx(0.0, abs=0.5)
    assert abs(sighting.curvature_1_m) < 0.1
    assert sighting.colour == "black"


@pytest.mark.parametrize("radius_m", [0.5, -0.5, 0.35], ids=["left", "right", "tightest"])
def test_a_curve(radius_m: float) -> None:
    truth = arc(radius_m)
    sighting = find(seen(floor([truth])))
    check_on(truth, sighting)
    assert sighting.curvature_1_m == pytest.approx(1 / radius_m, rel=0.1)
    for x in (0.2, 0.25):
        y, heading = truth_at_x(truth, x)
        assert sighting.lateral_m(x) == pytest.approx(y, abs=0.005)
        assert math.degrees(sighting.heading_rad(x)) == pytest.approx(math.degrees(heading),
                                                                      abs=1.0)


def test_an_s_line() -> None:
    truth = s_line()
    sighting = find(seen(floor([truth])))
    check_on(truth, sighting)
    for x in (0.2, 0.3, 0.45, 0.6):
        y, heading = truth_at_x(truth, x)
        assert sighting.lateral_m(x) == pytest.approx(y, abs=0.005)
        assert math.degrees(sighting.heading_rad(x)) == pytest.approx(math.degrees(heading),
                                                                      abs=1.0)
    # It bends both ways along what is seen.
    assert np.min(sighting.curvatures_1_m) < -1.0 < 1.0 < np.max(sighting.curvatures_1_m)


@settings(max_examples=40, deadline=None)
@given(lateral_m=st.floats(-0.12, 0.12), heading_deg=st.floats(-30.0, 30.0))
def test_offsets_and_headings_within_view(lateral_m: float, heading_deg: float) -> None:
    truth = straight(lateral_m, heading_deg)
    sighting = find(seen(floor([truth])))
    assert np.max(distance_to(truth, sighting.points_m)) < 0.005
    for x in (0.0, 0.35):  # under the base itself: extrapolated along the line
        y, _ = truth_at_x(truth, x)
        assert sighting.lateral_m(x) == pytest.approx(y, abs=0.005)
    # The heading where the tape is seen (0.185 m ahead and on); extrapolated 0.185 m back
    # to the base's centre it can be off by a degree or so (the line follower reads the
    # line under the base from remembered sightings instead: busarm.nav.line_track).
    for x in (0.2, 0.35):
        assert math.degrees(sighting.heading_rad(x)) == pytest.approx(heading_deg, abs=1.0)


def test_through_a_wide_angle_lens() -> None:
    truth = arc(0.6)
    sighting = find(seen(floor([truth]), intrinsics=WIDE), intrinsics=WIDE)
    check_on(truth, sighting)
    y, _ = truth_at_x(truth, 0.3)
    assert sighting.lateral_m(0.3) == pytest.approx(y, abs=0.005)


def test_seen_from_a_camera_turned_aside_and_lower() -> None:
    pose = camera_pose(0.2, 0.05, 0.4, 55.0, yaw_deg=15.0)
    truth = arc(0.8, (-0.2, 0.1))
    sighting = find(seen(floor([truth]), pose), pose=pose)
    check_on(truth, sighting)


# ---------------------------------------------------------------------- what is not the line


def test_no_line_is_none() -> None:
    assert find_floor_line(seen(floor()), PINHOLE, POSE) is None


def test_a_dark_box_is_not_tape() -> None:
    box = np.array([[0.35, -0.12], [0.55, -0.12], [0.55, 0.08], [0.35, 0.08]])
    image = seen(floor(blobs=[(box, (20, 20, 20))]))
    assert find_floor_line(image, PINHOLE, POSE) is None


def test_a_dark_square_as_wide_as_the_tape_is_not_a_line() -> None:
    square = np.array([[0.4, -0.015], [0.43, -0.015], [0.43, 0.015], [0.4, 0.015]])
    image = seen(floor(blobs=[(square, (10, 10, 10))]))
    assert find_floor_line(image, PINHOLE, POSE) is None


def test_the_line_beside_a_dark_box_and_under_a_blue_block() -> None:
    truth = straight(0.02, 5.0)
    box = np.array([[0.3, -0.25], [0.5, -0.25], [0.5, -0.08], [0.3, -0.08]])
    block = np.array([[0.45, 0.0], [0.48, 0.0], [0.48, 0.06], [0.45, 0.06]])
    image = seen(floor([truth], blobs=[(box, (25, 25, 25)), (block, (200, 60, 25))]))
    sighting = find(image)
    check_on(truth, sighting)
    assert 0.85 < sighting.found_share < 1.0  # the block covered a few cross-sections


def test_the_piece_nearest_the_robot_is_followed() -> None:
    near = arc(0.35, (0.0, 0.0), 100.0)  # curves out of view to the left
    far = straight(-0.25, 90.0, -0.2, 0.5) + np.array([0.62, 0.0])  # farther off, across
    sighting = find(seen(floor([near, far])))
    assert np.max(distance_to(near, sighting.points_m)) < 0.005
    assert sighting.points_m[0, 0] < 0.25


def test_lighting_dim_uneven_and_a_shadow() -> None:
    truth = arc(-0.7)
    image = seen(floor([truth])).astype(np.float64)
    rows = np.linspace(0.45, 1.0, image.shape[0])[:, None, None]  # dim and uneven
    shadow = np.ones(image.shape[:2])
    shadow[200:260] = 0.6  # a band of soft shadow across the tape
    image = image * rows * cv2.GaussianBlur(shadow, (31, 31), 10)[..., None]
    sighting = find(np.asarray(np.clip(image, 0, 255), dtype=np.uint8))
    check_on(truth, sighting)


def test_a_blue_line_is_blue_not_black() -> None:
    truth = s_line(0.04)
    image = seen(floor([truth], tape_bgr=(180, 64, 25)))
    sighting = find(image, colour="blue")
    check_on(truth, sighting)
    assert sighting.colour == "blue"
    assert find_floor_line(image, PINHOLE, POSE, "black") is None


def test_masked_pixels_are_not_looked_at() -> None:
    truth = straight()
    image = seen(floor([truth]))
    mask = np.ones(image.shape[:2], bool)
    mask[300:] = False  # below, the robot's gripper
    sighting = find(image, mask=mask)
    check_on(truth, sighting)
    assert sighting.points_m[0, 0] > find(image).points_m[0, 0] + 0.05


def test_beyond_what_is_seen_is_an_error() -> None:
    sighting = find(seen(floor([straight()])))
    with pytest.raises(VisionError, match=r"x = 3 m"):
        sighting.lateral_m(3.0)
    with pytest.raises(ConfigError, match="at_x_m"):
        sighting.heading_rad(math.nan)


def test_bad_input_is_refused_by_name() -> None:
    image = seen(floor([straight()]))
    with pytest.raises(ConfigError, match=r"'purple': give black, white, one of red, green, blue"):
        find_floor_line(image, PINHOLE, POSE, "purple")
    with pytest.raises(ConfigError, match="320x240 px; the intrinsics are for 640x480"):
        find_floor_line(np.asarray(cv2.resize(image, (320, 240)), dtype=np.uint8), PINHOLE, POSE)
    below = POSE.copy()
    below[2, 3] = -0.1
    with pytest.raises(ConfigError, match=r"camera height .* -0.1"):
        find_floor_line(image, PINHOLE, below)
    with pytest.raises(ConfigError, match="tape_width_m"):
        find_floor_line(image, PINHOLE, POSE, tape_width_m=0.5)
    with pytest.raises(ConfigError, match="mask"):
        find_floor_line(image, PINHOLE, POSE, mask=np.ones((10, 10), bool))


# ---------------------------------------------------------------------- tape of any colour


def test_white_tape_on_a_dark_floor_is_white_not_black() -> None:
    truth = arc(0.6)
    image = 255 - seen(floor([truth]))  # the floor dark (about 80), the tape white (247)
    sighting = find(image, colour="white")
    check_on(truth, sighting)
    assert sighting.colour == "white"
    assert find_floor_line(image, PINHOLE, POSE, "black") is None


NAMED_BGR = {"black": (8, 8, 8), "blue": (180, 64, 25), "red": (25, 20, 200),
             "green": (64, 128, 13), "yellow": (20, 205, 240)}
"""Tape as the default thresholds name it (sRGB of the twin's tape, BGR)."""


@settings(max_examples=25, deadline=None)
@given(name=st.sampled_from([*NAMED_BGR, "cyan", "pink"]), lateral_m=st.floats(-0.08, 0.08),
       heading_deg=st.floats(-20.0, 20.0), shade=st.floats(0.8, 1.0))
def test_the_first_look_measures_the_tapes_colour(name: str, lateral_m: float,
                                                  heading_deg: float, shade: float) -> None:
    """A tape of a colour the thresholds know is named by it; one they do not (cyan,
    pink) gets a Lab box of its own that leaves the floor out. Either way the line is
    then found by it where it truly is."""
    bgr = NAMED_BGR.get(name, {"cyan": (200, 170, 0), "pink": (160, 90, 230)}.get(name))
    assert bgr is not None
    tape = tuple(int(c * shade) for c in bgr)
    truth = straight(lateral_m, heading_deg)
    box = np.array([[0.3, 0.32], [0.45, 0.32], [0.45, 0.5], [0.3, 0.5]])  # a box aside
    image = seen(floor([truth], tape_bgr=tape, blobs=[(box, (60, 90, 120))]))
    look = measure_tape(image, PINHOLE, POSE)
    assert look is not None
    assert look.name == (name if name in NAMED_BGR else "measured")
    assert np.max(distance_to(truth, look.sighting.points_m)) < 0.005
    sighting = find(image, colour=look.colour)
    assert np.max(distance_to(truth, sighting.points_m)) < 0.005
    assert sighting.colour == look.name


def test_no_tape_on_the_first_look_is_none_and_names_are_checked() -> None:
    square = np.array([[0.4, -0.015], [0.43, -0.015], [0.43, 0.015], [0.4, 0.015]])
    assert measure_tape(seen(floor(blobs=[(square, (180, 64, 25))])), PINHOLE, POSE) is None
    assert check_tape("white") == "white"
    with pytest.raises(ConfigError, match=r"^--tape 'purple': allowed: black, white, red, "
                                          r"green, blue, yellow$"):
        check_tape("purple", "--tape")
    with pytest.raises(ConfigError, match=r"^tape colour 3: allowed: black, white, "):
        check_tape(3)
