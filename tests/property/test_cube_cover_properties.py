"""How well cubes explain a thing's outline (busarm.perception.shape): scored for any set of
them from silhouettes drawn once (``OutlineCover``), it is the intersection over union
that a canvas drawn for that set alone gives, cube by cube, to the bit."""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import numpy.typing as npt
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.arm.camera_mount import CameraMount
from busarm.arm.config import load_arm_config
from busarm.arm.kinematics import ArmKinematics
from busarm.errors import VisionError
from busarm.perception.locate import link2base
from busarm.perception.shape import OutlineCover, cube_silhouettes, cubes_explain
from busarm.twin.lens import LensSpec
from busarm.vision.calibration import CameraIntrinsics
from busarm.vision.localize import camera_to_base

LENS = LensSpec()
INTR = CameraIntrinsics(model="pinhole", width_px=LENS.width_px, height_px=LENS.height_px,
                        camera_matrix=LENS.camera_matrix, distortion=LENS.dist_coeffs)
_CFG = load_arm_config()
CAM2BASE = camera_to_base(link2base(ArmKinematics.from_config(_CFG), _CFG.pose("look")),
                          CameraMount.jetauto().cam2link)
Cube = tuple[float, float, float, float]


def _plain_explain(outline: npt.NDArray[np.int32], cubes: list[Cube]) -> float:
    """The score as first written: each cube's corners projected on their own, a canvas
    fitted to the outline and these cubes."""
    base2cam = np.linalg.inv(CAM2BASE)
    hulls = []
    for x, y, yaw_deg, side in cubes:
        a = np.radians(yaw_deg)
        corners = np.array([[x + side / 2 * (su * np.cos(a) - sv * np.sin(a)),
                             y + side / 2 * (su * np.sin(a) + sv * np.cos(a)), z]
                            for su in (-1, 1) for sv in (-1, 1) for z in (0.0, side)])
        try:
            px = INTR.pixels_from_camera_points(corners @ base2cam[:3, :3].T
                                                + base2cam[:3, 3])
        except VisionError:
            return 0.0
        hulls.append(cv2.convexHull(np.round(px).astype(np.int32)).reshape(-1, 2))
    every = np.vstack([outline, *hulls])
    x0, y0 = every.min(axis=0) - 1
    x1, y1 = every.max(axis=0) + 2
    thing = np.zeros((int(y1 - y0), int(x1 - x0)), np.uint8)
    model = np.zeros_like(thing)
    cv2.drawContours(thing, [(outline - (x0, y0)).reshape(-1, 1, 2)], -1, 1, cv2.FILLED)
    for hull in hulls:
        cv2.fillConvexPoly(model, (hull - (x0, y0)).astype(np.int32), 1)
    union = int(np.count_nonzero(thing | model))
    return float(np.count_nonzero(thing & model)) / union if union else 0.0


cubes = st.lists(st.tuples(st.floats(120.0, 280.0), st.floats(-120.0, 120.0),
                           st.floats(-45.0, 45.0), st.floats(20.0, 45.0)),
                 min_size=1, max_size=4)


@settings(max_examples=60, deadline=None)
@given(cubes, st.integers(0, 3), st.integers(-6, 6), st.integers(-6, 6))
def test_every_set_of_cubes_scores_as_drawn_on_its_own(
        many: list[Cube], which: int, du: int, dv: int) -> None:
    # The thing: one cube's silhouette, moved a few pixels (a rough split).
    hulls = cube_silhouettes(many, INTR, CAM2BASE, 0.0)
    shown = hulls[which % len(hulls)]
    assert shown is not None
    outline = shown + np.array([du, dv], np.int32)
    cover = OutlineCover(outline, hulls)
    for k in range(1, len(many) + 1):
        for subset in itertools.combinations(range(len(many)), k):
            want = _plain_explain(outline, [many[i] for i in subset])
            assert cover.share(subset) == want
            assert cubes_explain(outline, [many[i] for i in subset], INTR, CAM2BASE,
                                 0.0) == want
