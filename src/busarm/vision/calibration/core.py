"""Shared basics of the calibration modules: array types and checks, rigid transforms."""

from __future__ import annotations

import datetime as _dt

import numpy as np
import numpy.typing as npt
from scipy.spatial.transform import Rotation

from busarm.errors import ConfigError

__all__ = [
    "RIGID_TOL",
    "FloatArray",
    "IntArray",
    "UInt8Array",
    "as_transform",
    "inverse_of",
    "invert_transform",
]


FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
UInt8Array = npt.NDArray[np.uint8]

RIGID_TOL = 1e-6
"""Largest |R R^T - I| entry (and bottom-row error) accepted for a rigid transform."""


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def _array(name: str, value: object, shape: tuple[int, ...] | None = None) -> FloatArray:
    """``value`` as a finite float64 array (of ``shape``), else ConfigError naming ``name``."""
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be an array of numbers, got {value!r:.80}") from None
    if shape is not None and arr.shape != shape:
        raise ConfigError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ConfigError(f"{name} must be finite, got {arr.tolist()!r:.120}")
    return arr


def _points(name: str, value: object, dim: int) -> FloatArray:
    """(N, dim) finite float64 points; a single point may be given flat."""
    arr = _array(name, value)
    if arr.ndim == 1 and arr.shape[0] == dim:
        arr = arr.reshape(1, dim)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ConfigError(f"{name} must be an (N, {dim}) array, got shape {arr.shape}")
    return arr


def _readonly(arr: FloatArray) -> FloatArray:
    out = np.array(arr, dtype=np.float64)
    out.setflags(write=False)
    return out


def as_transform(name: str, value: object) -> FloatArray:
    """``value`` as a rigid 4x4 transform (a copy), else ConfigError naming ``name``."""
    t = _array(name, value, (4, 4))
    # Plain floats: this check runs once per located frame, and numpy's small-array
    # overhead (np.linalg.det alone) would cost more than the arithmetic.
    (a, b, c, _), (d, e, f, _), (g, h, i, _), bottom = t.tolist()
    worst = max(
        abs(a * a + b * b + c * c - 1.0), abs(d * d + e * e + f * f - 1.0),
        abs(g * g + h * h + i * i - 1.0), abs(a * d + b * e + c * f),
        abs(a * g + b * h + c * i), abs(d * g + e * h + f * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    off = max(abs(bottom[0]), abs(bottom[1]), abs(bottom[2]), abs(bottom[3] - 1.0))
    if not (worst <= RIGID_TOL and det > 0.0 and off <= RIGID_TOL):
        raise ConfigError(
            f"{name} is not a rigid transform (rotation must be orthonormal with det +1 "
            f"within {RIGID_TOL:g}, bottom row 0 0 0 1)"
        )
    return t


_last_inverse: tuple[tuple[str, tuple[int, ...], bytes], FloatArray] | None = None


def inverse_of(a2b: FloatArray) -> FloatArray:
    """``np.linalg.inv(a2b)`` (the same numbers), read only; the last one is kept, as
    the steps that take one picture apart each invert its camera pose."""
    global _last_inverse
    key = (a2b.dtype.str, a2b.shape, a2b.tobytes())
    last = _last_inverse
    if last is not None and last[0] == key:
        return last[1]
    out: FloatArray = np.asarray(np.linalg.inv(a2b), np.float64)
    out.flags.writeable = False
    _last_inverse = (key, out)
    return out


def invert_transform(a2b: FloatArray) -> FloatArray:
    """b2a of a rigid a2b."""
    out = np.eye(4)
    r = a2b[:3, :3]
    out[:3, :3] = r.T
    out[:3, 3] = -r.T @ a2b[:3, 3]
    return out


def _transform(rotation: FloatArray, translation: FloatArray) -> FloatArray:
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = translation
    return out


def _rotvec_matrix(rotvec: FloatArray) -> FloatArray:
    out: FloatArray = Rotation.from_rotvec(rotvec).as_matrix()
    return out


def _mean_rotation(rotations: FloatArray) -> FloatArray:
    """Chordal mean of (N, 3, 3) rotations (nearest rotation to their sum)."""
    u, _, vt = np.linalg.svd(rotations.sum(axis=0))
    d = np.sign(np.linalg.det(u @ vt))
    out: FloatArray = u @ np.diag([1.0, 1.0, d]) @ vt
    return out
