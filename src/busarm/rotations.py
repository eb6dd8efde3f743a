"""Rotation matrices as unit quaternions (the one conversion every layer shares)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = [
    "quaternion_wxyz",
]


def quaternion_wxyz(rotation: npt.ArrayLike) -> tuple[float, float, float, float]:
    """The unit quaternion (w, x, y, z), w >= 0, of a 3 x 3 rotation matrix.

    Shepperd's method: from the largest of w, x, y, z (found on the diagonal), the others
    from the off-diagonal sums or differences, so that every rotation (180 degrees
    about any axis included) comes out right and well conditioned.
    """
    r = np.asarray(rotation, dtype=np.float64)
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    k = int(np.argmax([trace, r[0, 0], r[1, 1], r[2, 2]]))
    if k == 0:
        s = 2.0 * math.sqrt(max(1.0 + trace, 0.0))
        q = (s / 4, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s)
    elif k == 1:
        s = 2.0 * math.sqrt(max(1.0 + r[0, 0] - r[1, 1] - r[2, 2], 0.0))
        q = ((r[2, 1] - r[1, 2]) / s, s / 4, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(max(1.0 - r[0, 0] + r[1, 1] - r[2, 2], 0.0))
        q = ((r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, s / 4, (r[1, 2] + r[2, 1]) / s)
    else:
        s = 2.0 * math.sqrt(max(1.0 - r[0, 0] - r[1, 1] + r[2, 2], 0.0))
        q = ((r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, s / 4)
    norm = math.sqrt(sum(v * v for v in q))
    sign = -1.0 if q[0] < 0 else 1.0
    w, x, y, z = (float(sign * v / norm) for v in q)
    return w, x, y, z
