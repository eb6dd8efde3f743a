"""Pixels to the table: rays from the calibrated camera met with horizontal planes.

Frames and units as in ``busarm.vision.calibration``: millimetres, degrees, 4x4
``a2b`` transforms (``p_b = a2b @ p_a``), the OpenCV camera frame, pixel centres at
integer coordinates. The arm's base frame has z up and the table at ``table_z_mm``.
``cam2base`` comes from the arm's forward kinematics of the measured joints and the
hand-eye calibration: ``camera_to_base(link2base, cam2link)``.

Blocks: a colour blob's centroid is the centroid of the cube's *silhouette* (top face
plus the side faces the camera sees), not of its top face, so meeting its ray with the
top-face plane puts the block 3..15 mm off in an oblique view (the side faces pull the
centroid outward). ``locate_block`` models the silhouette:

- ``silhouette=True`` (default): the blob is the whole visible cube (a colour mask of a
  uniformly coloured block, any view that is not straight down). The cube (known side,
  on the table, at ``yaw_deg``) is projected through the real, distorted camera model,
  the area centroid of its silhouette computed exactly (the visible faces' projected
  polygons, their edges subdivided so lens distortion bends them), and its position
  adjusted by Gauss-Newton steps until that centroid is the measured one (< 0.01 px).
- ``silhouette=False``: the blob is the top face only (a detector that segments the top
  face, e.g. by its brighter shade, or a tag on top of the block): a plain ray hit
  at the top-face height.

The yaw matters little (a 45 deg error moves a 30 mm cube by at most 0.7 mm in the
arm's views): pass the blob's ``minAreaRect`` angle if it is known, else 0.

Speed: ``locate_blocks`` solves all blocks of one frame in one vectorised pass: a start
within about a pixel (``_better_start``), then typically two Gauss-Newton evaluations of
every silhouette (the first with its Jacobian probes, the second the centre alone); per
block that is several times cheaper than one ``locate_block`` call each.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError, VisionError
from busarm.units import check_range, listing
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.calibration.core import as_transform

FloatArray = npt.NDArray[np.float64]

SILHOUETTE_TOL_PX = 0.01
"""The fitted silhouette centroid is within this of the measured one."""
MAX_ITERATIONS = 8
EDGE_SAMPLES = 4
"""Points per cube edge (including its start corner; even). Lens distortion bends the
straight edges and the silhouette's area centroid follows the bent outline; the
polygon's error shrinks as (1/samples)^2, so the moments of the outline with every
point and with every other point are combined (Richardson) to cancel that term: with
4 points per edge the centroid is within 1e-3 mm of the exact one even for a cube
200 mm from the camera in the corner of a k1 = -0.17 picture (2 points: 0.01 mm)."""
_STEP_NORMALIZED = 1e-3
"""Finite-difference step of the Jacobian, in normalised image units (about 0.5 px)."""
REPROBE_PX = 3.0
"""Gauss-Newton probes a new Jacobian only while the centroid is further off than this."""


@dataclass(frozen=True)
class BlockLocation:
    """A block on the table, in the base frame (mm).

    ``x_mm``, ``y_mm``: the centre of the cube's footprint; ``z_mm``: its top face.
    ``residual_px``: how far the fitted centroid is from the measured one (an upper
    bound: a last Gauss-Newton step is taken after the check). ``frames``,
    ``spread_mean_mm``, ``spread_max_mm``: from ``average_locations`` (the mean and
    largest horizontal distance of a frame's location from the average).
    """

    x_mm: float
    y_mm: float
    z_mm: float
    yaw_deg: float
    size_mm: float
    centroid_px: tuple[float, float]
    residual_px: float = 0.0
    silhouette: bool = True
    frames: int = 1
    spread_mean_mm: float = 0.0
    spread_max_mm: float = 0.0

    @property
    def xy_mm(self) -> tuple[float, float]:
        return (self.x_mm, self.y_mm)


def camera_to_base(link2base: npt.ArrayLike, cam2link: npt.ArrayLike) -> FloatArray:
    """cam2base = link2base @ cam2link (both rigid 4x4, mm)."""
    out: FloatArray = as_transform("link2base", link2base) @ as_transform("cam2link", cam2link)
    return out


def _finite(name: str, value: object, lo: float = -1e6, hi: float = 1e6) -> float:
    """``value`` as a float within lo..hi (a millimetre or degree: +-1e6 unless told)."""
    return check_range(name, value, lo, hi)


def _pixels(name: str, value: npt.ArrayLike) -> FloatArray:
    try:
        arr = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be an (N, 2) array of pixels, got {value!r:.80}") from None
    if arr.ndim == 1 and arr.shape[0] == 2:
        arr = arr.reshape(1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ConfigError(f"{name} must be an (N, 2) array of pixels, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ConfigError(f"{name} must be finite")
    return arr


def _rays_to_plane(
    xy: FloatArray, cam2base: FloatArray, plane_z_mm: float, px: FloatArray
) -> FloatArray:
    """Meet the rays of normalised points (N, 2) with the plane z = plane_z_mm (base)."""
    r, origin = cam2base[:3, :3], cam2base[:3, 3]
    direction = xy @ r[:, :2].T + r[:, 2]
    height = plane_z_mm - origin[2]
    dz = direction[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = height / dz
    # The ray must meet the plane in front of the camera, not graze it (1e-9 rad).
    norm = np.linalg.norm(direction, axis=1)
    bad = np.flatnonzero(~((s > 0.0) & (np.abs(dz) > 1e-9 * norm) & np.isfinite(s)))
    if bad.size:
        i = int(bad[0])
        raise VisionError(
            f"pixel ({px[i, 0]:.2f}, {px[i, 1]:.2f}) (#{i}) never meets the plane "
            f"z = {plane_z_mm:g} mm: its ray runs parallel to it or away from it "
            f"(camera at z = {origin[2]:.1f} mm)"
        )
    out: FloatArray = origin + s[:, None] * direction
    return out


def table_points_from_pixels(
    px: npt.ArrayLike,
    intrinsics: CameraIntrinsics,
    cam2base: npt.ArrayLike,
    plane_z_mm: float = 0.0,
) -> FloatArray:
    """(N, 2) pixels -> (N, 3) points (mm, base frame) on the plane z = ``plane_z_mm``.

    Each pixel is undistorted, its ray cast from the camera and met with the plane.
    VisionError naming the pixel if its ray runs parallel to the plane or away from it.
    """
    p = _pixels("px", px)
    t = as_transform("cam2base", cam2base)
    plane = _finite("plane_z_mm", plane_z_mm)
    return _rays_to_plane(intrinsics.normalized_from_pixels(p), t, plane, p)


# The unit cube (side 1, footprint centred on the origin, z 0..1): its top and four
# side faces (the bottom lies on the table), corners counter-clockwise seen from
# outside, so every face the camera sees projects with the same (negative) orientation
# in image coordinates (y down).
_FACES = np.array(
    [
        [[-0.5, -0.5, 1.0], [0.5, -0.5, 1.0], [0.5, 0.5, 1.0], [-0.5, 0.5, 1.0]],  # top
        [[0.5, -0.5, 0.0], [0.5, 0.5, 0.0], [0.5, 0.5, 1.0], [0.5, -0.5, 1.0]],  # +x
        [[-0.5, 0.5, 0.0], [-0.5, -0.5, 0.0], [-0.5, -0.5, 1.0], [-0.5, 0.5, 1.0]],  # -x
        [[0.5, 0.5, 0.0], [-0.5, 0.5, 0.0], [-0.5, 0.5, 1.0], [0.5, 0.5, 1.0]],  # +y
        [[-0.5, -0.5, 0.0], [0.5, -0.5, 0.0], [0.5, -0.5, 1.0], [-0.5, -0.5, 1.0]],  # -y
    ]
)


def _face_outline(samples: int) -> FloatArray:
    """(5, 4 * samples + 1, 3): each face's closed outline, ``samples`` points per edge
    (the first point repeated at the end, so "next point" is a slice, not a gather)."""
    t = np.arange(samples) / samples
    start, end = _FACES, np.roll(_FACES, -1, axis=1)
    pts = start[:, :, None, :] + t[None, None, :, None] * (end - start)[:, :, None, :]
    pts = pts.reshape(5, 4 * samples, 3)
    return np.concatenate([pts, pts[:, :1]], axis=1)


_OUTLINE = _face_outline(EDGE_SAMPLES)
_PROBES = np.array([[0.0, 0.0, 0.0], [_STEP_NORMALIZED, 0.0, 0.0], [0.0, _STEP_NORMALIZED, 0.0]])


def _centroids(intrinsics: CameraIntrinsics, x: FloatArray, y: FloatArray, z: FloatArray
               ) -> FloatArray:
    """Silhouette centroids (..., 2) of outlines given by their camera points' x, y, z
    arrays (..., 5 | 3 faces, 4 * EDGE_SAMPLES + 1)."""
    u, v, px = intrinsics._project_h_columns(x, y, z)  # u, v and (u, v, 1)
    fine = _face_moments(px, u, v)
    # Every other outline point.
    coarse = _face_moments(px[..., ::2, :], u[..., ::2], v[..., ::2])
    moments = (4.0 * fine - coarse) / 3.0  # Richardson: the chords' h^2 error cancels
    seen = fine[..., 0, 2] < 0.0  # (N, G, 5)
    total = (seen[..., None, :] @ moments[..., 0, :])[..., 0, :]  # (N, G, 3)
    out: FloatArray = total[..., :2] / (1.5 * total[..., 2:3])
    return out


def _face_moments(px: FloatArray, u: FloatArray, v: FloatArray) -> FloatArray:
    """Per closed outline (..., K + 1, 3 homogeneous px; ``u``, ``v``: its first two
    columns, contiguous ones the cheaper): (6 Mx, 6 My, 4 A) as (..., 1, 3), A the signed
    area (faces the camera sees: negative), by the shoelace formula."""
    a, b = px[..., :-1, :], px[..., 1:, :]
    cross = u[..., :-1] * v[..., 1:] - u[..., 1:] * v[..., :-1]
    out: FloatArray = cross[..., None, :] @ (a + b)
    return out


def locate_blocks(
    centroids_px: npt.ArrayLike,
    intrinsics: CameraIntrinsics,
    cam2base: npt.ArrayLike,
    *,
    table_z_mm: float = 0.0,
    block_size_mm: float = 30.0,
    yaw_deg: float | Sequence[float] = 0.0,
    silhouette: bool = True,
) -> list[BlockLocation]:
    """``locate_block`` for several blobs of one frame at once (one vectorised solve).

    ``yaw_deg``: one yaw for all blocks or one per block.
    """
    c = _pixels("centroids_px", centroids_px)
    n = c.shape[0]
    t = as_transform("cam2base", cam2base)
    table = _finite("table_z_mm", table_z_mm)
    size = _finite("block_size_mm", block_size_mm, 1.0, 1000.0)
    if isinstance(yaw_deg, int | float) and not isinstance(yaw_deg, bool):
        yaws = [_finite("yaw_deg", yaw_deg)] * n
    else:
        yaws = [_finite(f"yaw_deg[{i}]", y) for i, y in enumerate(yaw_deg)]
        if len(yaws) != n:
            raise ConfigError(f"yaw_deg has {len(yaws)} values for {n} blocks")
    if n == 0:
        return []
    if not silhouette:
        top = table + size
        pts = _rays_to_plane(intrinsics.normalized_from_pixels(c), t, top, c)
        return [
            BlockLocation(
                float(p[0]), float(p[1]), top, y, size, (float(u), float(v)), 0.0, False
            )
            for p, y, (u, v) in zip(pts.tolist(), yaws, c.tolist(), strict=True)
        ]
    return locate_checked_blocks(c, intrinsics, t, table, size, yaws)


def locate_checked_blocks(
    centroids_px: FloatArray, intrinsics: CameraIntrinsics, cam2base: FloatArray,
    table_z_mm: float, block_size_mm: float, yaws_deg: list[float],
) -> list[BlockLocation]:
    """``locate_blocks`` (silhouettes) for inputs checked already: (N >= 1, 2) finite
    float64 centroids, a rigid float64 ``cam2base``, finite floats in range, one yaw per
    block (a caller whose numbers come from a detector and forward kinematics skips the
    per-frame checks; the same answer)."""
    c, table, size, yaws = centroids_px, table_z_mm, block_size_mm, yaws_deg
    xy, residual = _solve_silhouettes(c, intrinsics, cam2base, table, size, yaws)
    return [
        BlockLocation(
            float(p[0]), float(p[1]), table + size, y, size, (float(u), float(v)), float(r), True
        )
        for p, y, (u, v), r in zip(xy.tolist(), yaws, c.tolist(), residual.tolist(), strict=True)
    ]


def _yaw_matrix(yaw_deg: float) -> FloatArray:
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _yaw_matrices(yaws: list[float]) -> FloatArray:
    """(N, 3, 3): ``_yaw_matrix`` of each yaw, in one pass."""
    a = np.radians(yaws)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((len(yaws), 3, 3))
    out[:, 0, 0] = c
    out[:, 0, 1] = -s
    out[:, 1, 0] = s
    out[:, 1, 1] = c
    out[:, 2, 2] = 1.0
    return out


def _solve_silhouettes(
    measured: FloatArray, intr: CameraIntrinsics, cam2base: FloatArray, table: float,
    size: float, yaws: list[float],
) -> tuple[FloatArray, FloatArray]:
    """Footprint centres (N, 2) whose silhouette centroids are the measured ones.

    The unknown is the undistorted normalised image point of the cube's centre (mid
    height): the centroid is that point, distorted, plus a small, slowly varying offset,
    so Gauss-Newton (numeric Jacobian, the three probes evaluated in one pass) converges
    in one or two steps from the measured pixel itself, in one from ``_better_start``.
    Only the top face and the one side face along each of the cube's axes that faces the
    camera can be seen; they are chosen at the start and checked at the end (the solve
    is redone if the answer moved the cube past one of their planes, which takes a start
    15 mm off).
    """
    r, origin = cam2base[:3, :3], cam2base[:3, 3]
    base2cam = r.T
    count = measured.shape[0]
    template = _OUTLINE * size
    # Each cube's face outlines in the camera frame, about its footprint centre.
    if len(set(yaws)) == 1:
        rotation = _yaw_matrix(yaws[0])
        outlines = (template @ (base2cam @ rotation).T)[None]
        local_xy = rotation[:2, :2]  # the cube's axes in the base frame
    else:
        rotations = _yaw_matrices(yaws)
        # One (45, 3) @ (3, 3N) product: cheaper than N stacked (45, 3) @ (3, 3) ones.
        cols = (base2cam @ rotations).reshape(-1, 3).T  # column 3n + i: cube n's row i
        outlines = (template.reshape(-1, 3) @ cols).reshape(5, -1, count, 3).transpose(2, 0, 1, 3)
        local_xy = rotations[:, :2, :2]
    mid = table + 0.5 * size
    down = 0.5 * size * base2cam[:, 2]  # camera-frame vector from mid height to the footprint
    height = mid - origin[2]
    row = r[2]  # base z of a camera-frame direction
    n = np.empty((count, 3))
    # (The intrinsics' own (cx, cy) and (fx, fy) arrays: no tuples made into arrays.)
    n[:, :2] = (measured - intr._principal) / intr._focal  # distortion: the solve
    n[:, 2] = 1.0
    index = np.arange(count)[:, None] if outlines.shape[0] > 1 else np.zeros((count, 1), np.intp)
    residual: FloatArray = np.full(count, np.inf)
    # A blob no cube explains (half a block at a corner, say) goes non-finite on the way;
    # that is caught below and named, so numpy need not warn about it.
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        faces = _better_start(n, measured, intr, outlines, index, r, height, local_xy, down)
        if faces is None:
            faces = _facing(n, r, height, local_xy)
        for _ in range(3):
            residual = _gauss_newton(
                n, measured, intr, outlines[index, faces], row, height, down, 0.87 * size, mid
            )
            again = _facing(n, r, height, local_xy)
            if np.array_equal(again, faces):
                break
            faces = again
    bad = np.flatnonzero(~(residual < SILHOUETTE_TOL_PX) | ~np.isfinite(n).all(axis=1))
    if bad.size:
        i = int(bad[0])
        raise VisionError(
            f"centroid ({measured[i, 0]:.2f}, {measured[i, 1]:.2f}) (#{i}): no block position "
            f"reproduces it (off by {residual[i]:.3g} px after {MAX_ITERATIONS} steps)"
        )
    s = height / (n @ row)
    centre = origin + (n * s[:, None]) @ r.T
    return centre[:, :2], residual


def _better_start(
    n: FloatArray, measured: FloatArray, intr: CameraIntrinsics, outlines: FloatArray,
    index: npt.NDArray[np.intp], r: FloatArray, height: float, local_xy: FloatArray,
    down: FloatArray,
) -> npt.NDArray[np.intp] | None:
    """Move the start ``n`` (in place) close to the answer, so that Gauss-Newton needs
    one evaluation fewer: the undistorted measured point less the silhouette centroid's
    offset from the cube's centre, both in normalised units, the offset from the
    corners alone through a plain pinhole (the offset varies slowly, and a lens bends
    it by a few per cent). The start only saves steps: the solve still goes on to
    < ``SILHOUETTE_TOL_PX``. A blob where this fails keeps the plain start. Returns the
    faces seen from the start when every blob got one (the solve checks them anyway)."""
    # OpenCV's plain undistortion (a few fixed-point steps, no checks): a start needs
    # no more, and the checked ``normalized_from_pixels`` would cost a whole step.
    src = measured.reshape(-1, 1, 2)
    if intr.model == "fisheye":
        raw = cv2.fisheye.undistortPoints(src, intr.camera_matrix, intr.distortion)
    else:
        raw = cv2.undistortPoints(src, intr.camera_matrix, intr.distortion)
    u = np.asarray(raw, dtype=np.float64).reshape(-1, 2)
    start = np.empty_like(n)
    start[:, :2] = u
    start[:, 2] = 1.0
    faces = _facing(start, r, height, local_xy)
    centre = start * (height / (start @ r[2]))[:, None] - down
    # The corners picked out before the faces are gathered: a quarter of the copying.
    corners = outlines[:, :, ::EDGE_SAMPLES][index, faces] + centre[:, None, None, :]
    q = corners / corners[..., 2:3]  # (x, y, 1) through a plain pinhole
    moments = _face_moments(q, q[..., 0], q[..., 1])[..., 0, :]  # (N, 3 faces, 3)
    seen = moments[..., 2] < 0.0
    total = (seen[:, None, :] @ moments)[:, 0]
    start[:, :2] -= total[:, :2] / (1.5 * total[:, 2:3]) - u
    ok = np.isfinite(start).all(axis=1) & (corners[..., 2] > 0.0).all(axis=(1, 2))
    if ok.all():
        n[:] = start
        return faces
    n[ok] = start[ok]
    return None


def _facing(
    n: FloatArray, r: FloatArray, height: float, local_xy: FloatArray
) -> npt.NDArray[np.intp]:
    """Per cube, the faces that can face the camera: top, +x or -x, +y or -y (indices
    into ``_FACES``), from where the camera is in the cube's own horizontal axes."""
    s = height / (n @ r[2])
    toward = -((n * s[:, None]) @ r[:2].T)  # camera from the cube centre, base x y
    # One yaw for all (2x2) or one per cube (N, 2, 2): into each cube's axes.
    toward = toward @ local_xy if local_xy.ndim == 2 else np.einsum("nji,nj->ni", local_xy, toward)
    faces = np.zeros((n.shape[0], 3), dtype=np.intp)
    faces[:, 1:] = (toward < 0.0) + _SIDE_FACES  # +x (1) or -x (2); +y (3) or -y (4)
    return faces


_SIDE_FACES = np.array([1, 3], dtype=np.intp)


_ADJUGATE_SIGN = np.array([[1.0, -1.0], [-1.0, 1.0]])


def _gauss_newton(
    n: FloatArray, measured: FloatArray, intr: CameraIntrinsics, outline: FloatArray,
    row: FloatArray, height: float, down: FloatArray, min_depth: float, mid: float,
) -> FloatArray:
    """Update ``n`` in place until the centroids match; returns the last residuals (px).

    The Jacobian is probed afresh only while the error is large (> ``REPROBE_PX``) or
    fell less than tenfold: near the answer it changes by a fraction of a per cent, so a
    step with the last one still converges (to the same < ``SILHOUETTE_TOL_PX`` check)
    and the centre alone is cast.
    """
    err = np.full(measured.shape, np.inf)
    inverse: FloatArray = np.zeros((measured.shape[0], 2, 2))
    fresh, last = True, math.inf
    for _ in range(MAX_ITERATIONS):
        probes = n[:, None, :] + (_PROBES if fresh else _PROBES[:1])  # homogeneous (x, y, 1)
        # The ray through each probe meets z = mid at s * (x, y, 1) in the camera frame.
        den = probes @ row
        s = height / den
        # The cube is wholly in front of the camera if its centre is deeper than its
        # half-diagonal (sqrt(3)/2 of the side). Those bounds on s also keep every den
        # on height's side and > |height| / 1e7 away from 0 (the ray is not parallel).
        if not (s.min() > min_depth and s.max() < 1e7 and abs(height) >= 1e-2):
            if not (den.min() > 1e-9 or den.max() < -1e-9):
                raise VisionError(_miss(measured, den * np.sign(height), mid))
            if not (s.min() > min_depth and s.max() < 1e7):
                raise VisionError(_miss(measured, s - min_depth, mid))
        probes *= s[..., None]
        probes -= down
        # Each camera coordinate broadcast on its own: a (..., 3) sum runs three at a time.
        cen = _centroids(intr, *(outline[:, None, ..., k] + probes[:, :, None, None, k]
                                 for k in range(3)))  # (N, 1|3, 2)
        err = cen[:, 0] - measured
        if fresh:
            inverse = _step_inverse(cen)
        n[:, :2] -= (err[:, None, :] @ inverse)[:, 0]
        worst = float(np.abs(err).max())
        if worst < SILHOUETTE_TOL_PX:
            break
        # Slow progress (a strong lens's rim bends the Jacobian): probe it afresh.
        fresh = not (worst <= REPROBE_PX and worst <= 0.1 * last)
        last = worst
    out: FloatArray = np.abs(err).max(axis=1)
    return out


def _step_inverse(cen: FloatArray) -> FloatArray:
    """(N, 2, 2): the inverse Jacobian (in n's units) from the probes' centroids."""
    # Rows of jac are d centroid / d (x, y) times the step; the 2x2 inverse in closed
    # form (adjugate / determinant), cheaper than linalg.solve.
    jac = cen[:, 1:] - cen[:, :1]
    det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
    adjugate = jac[:, ::-1, ::-1].transpose(0, 2, 1) * _ADJUGATE_SIGN
    out: FloatArray = adjugate * (_STEP_NORMALIZED / det)[:, None, None]
    return out


def _miss(measured: FloatArray, value: FloatArray, mid: float) -> str:
    """The message for a centroid whose ray misses the block's mid-height plane."""
    bad = np.flatnonzero(~(value > 0.0).all(axis=1))
    i = int(bad[0]) if bad.size else 0
    return (
        f"centroid ({measured[i, 0]:.2f}, {measured[i, 1]:.2f}) (#{i}): its ray does not meet "
        f"the block's mid-height plane z = {mid:g} mm in front of the camera"
    )


def locate_block(
    centroid_px: npt.ArrayLike,
    intrinsics: CameraIntrinsics,
    cam2base: npt.ArrayLike,
    *,
    table_z_mm: float = 0.0,
    block_size_mm: float = 30.0,
    yaw_deg: float = 0.0,
    silhouette: bool = True,
) -> BlockLocation:
    """Where a cube of side ``block_size_mm`` sits on the table, from its blob centroid.

    ``silhouette=True``: the centroid is the whole visible cube's (see the module
    docstring); the location reproduces it to < 0.01 px through the distorted camera
    model. ``silhouette=False``: the centroid is the top face's; a plain ray hit at
    ``table_z_mm + block_size_mm``. ``yaw_deg`` turns the cube about the vertical (it
    changes the silhouette a little; 0 = faces along the base axes). VisionError if the
    centroid's ray misses the table or no position reproduces it.
    """
    c = _pixels("centroid_px", centroid_px)
    if c.shape[0] != 1:
        raise ConfigError(f"centroid_px must be one pixel (u, v), got {c.shape[0]}")
    return locate_blocks(
        c, intrinsics, cam2base, table_z_mm=table_z_mm, block_size_mm=block_size_mm,
        yaw_deg=yaw_deg, silhouette=silhouette,
    )[0]


def average_locations(locations: Sequence[BlockLocation]) -> BlockLocation:
    """The mean of one block's locations over frames, with their spread.

    Yaw is averaged modulo 90 deg (a cube's symmetry). ``spread_mean_mm`` and
    ``spread_max_mm``: mean and largest horizontal distance of a location from the mean.
    ConfigError for no locations or blocks of different sizes.
    """
    locs = list(locations)
    if not locs:
        raise ConfigError("average_locations needs at least one location")
    if any(not isinstance(loc, BlockLocation) for loc in locs):
        raise ConfigError("average_locations takes BlockLocation values")
    sizes = {loc.size_mm for loc in locs}
    if len(sizes) != 1:
        raise ConfigError(f"cannot average blocks of different sizes {listing(sorted(sizes))} mm")
    weights = np.array([loc.frames for loc in locs], dtype=np.float64)
    xyz = np.array([[loc.x_mm, loc.y_mm, loc.z_mm] for loc in locs])
    mean = (xyz * weights[:, None]).sum(axis=0) / weights.sum()
    dist = np.linalg.norm(xyz[:, :2] - mean[:2], axis=1)
    quad = np.radians(4.0 * np.array([loc.yaw_deg for loc in locs]))
    yaw = math.degrees(
        math.atan2(float((np.sin(quad) * weights).sum()), float((np.cos(quad) * weights).sum()))
    ) / 4.0
    centroid = np.array([loc.centroid_px for loc in locs]).mean(axis=0)
    return BlockLocation(
        float(mean[0]), float(mean[1]), float(mean[2]), yaw, locs[0].size_mm,
        (float(centroid[0]), float(centroid[1])),
        max(loc.residual_px for loc in locs), all(loc.silhouette for loc in locs),
        int(weights.sum()), float((dist * weights).sum() / weights.sum()), float(dist.max()),
    )


__all__ = [
    "BlockLocation",
    "average_locations",
    "camera_to_base",
    "locate_block",
    "locate_blocks",
    "locate_checked_blocks",
    "table_points_from_pixels",
]
