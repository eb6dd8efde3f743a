"""A rotation matrix becomes the unit quaternion that gives it back, for every rotation
(180 degrees about any axis included, where naive formulas pick wrong signs)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from busarm.rotations import quaternion_wxyz

UNIT = st.floats(-1.0, 1.0, allow_nan=False)


@given(st.tuples(UNIT, UNIT, UNIT).filter(lambda v: np.linalg.norm(v) > 1e-3),
       st.one_of(st.floats(-np.pi, np.pi), st.sampled_from([np.pi, -np.pi, np.pi / 2])))
def test_the_quaternion_gives_the_matrix_back(axis: tuple[float, float, float],
                                              angle: float) -> None:
    rotvec = np.asarray(axis) / np.linalg.norm(axis) * angle
    matrix = Rotation.from_rotvec(rotvec).as_matrix()
    w, x, y, z = quaternion_wxyz(matrix)
    assert w >= 0 and abs(w * w + x * x + y * y + z * z - 1) < 1e-9
    assert np.allclose(Rotation.from_quat([x, y, z, w]).as_matrix(), matrix, atol=1e-9)


def test_half_turns_about_a_diagonal_keep_the_axis_sign() -> None:
    for axis in ([1, -1, 0], [1, 1, 0], [0, 1, -1], [-1, 0, 1]):
        matrix = Rotation.from_rotvec(np.asarray(axis) / np.sqrt(2) * np.pi).as_matrix()
        w, x, y, z = quaternion_wxyz(matrix)
        assert np.allclose(Rotation.from_quat([x, y, z, w]).as_matrix(), matrix, atol=1e-12)
