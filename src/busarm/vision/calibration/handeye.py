"""Eye-in-hand calibration: the camera's pose on the arm's link, from a fixed board."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from busarm.errors import ConfigError, VisionError
from busarm.units import check_int_range, check_range
from busarm.vision.calibration.boards import ChessboardSpec
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.calibration.core import (
    FloatArray,
    _mean_rotation,
    _now,
    _rotvec_matrix,
    _transform,
    as_transform,
)
from busarm.vision.calibration.detection import BoardObservation, _found_views
from busarm.vision.calibration.pose import OUTLIER_VIEW_PX, _rms, board_pose

__all__ = [
    "MIN_HAND_EYE_VIEWS",
    "HandEyeResult",
    "calibrate_hand_eye",
]


MIN_HAND_EYE_VIEWS = 3

_MIN_MOTION_DEG = 3.0
"""Relative rotations smaller than this tell nothing about the hand-eye rotation axis."""
_MIN_AXIS_SPREAD_DEG = 10.0
"""Two motion axes at least this far apart make a hand-eye calibration well posed."""
_N_GLOBAL = 12
"""Fit parameters shared by every view: cam2link's and board2base's rotation vector and
translation (each view's link-pose correction follows, 6 more)."""


@dataclass(frozen=True, eq=False)
class HandEyeResult:
    """An eye-in-hand calibration.

    ``cam2link``: the camera on the ``link``; ``board2base``: the fixed board. ``rms_px``
    and ``per_view_rms_px``: reprojection error with the link poses *as given* over the
    views used (indices into the lists given). ``pose_rms_deg`` / ``pose_rms_mm``: the
    rms correction the fit gave each view's link pose (what the joint readings were
    off by, seen through the camera). ``translation_std_mm`` / ``rotation_std_deg``:
    1-sigma uncertainty of cam2link under the noise model. ``method``: the OpenCV
    hand-eye method that gave the start.
    """

    cam2link: FloatArray
    board2base: FloatArray
    rms_px: float
    per_view_rms_px: tuple[float, ...]
    views_used: tuple[int, ...]
    intrinsics: CameraIntrinsics
    link: str = "wrist_pitch"
    method: str = ""
    translation_std_mm: float = 0.0
    rotation_std_deg: float = 0.0
    pose_rms_deg: float = 0.0
    pose_rms_mm: float = 0.0
    created: str = ""


_HAND_EYE_METHODS = (
    ("tsai", cv2.CALIB_HAND_EYE_TSAI),
    ("park", cv2.CALIB_HAND_EYE_PARK),
    ("horaud", cv2.CALIB_HAND_EYE_HORAUD),
    ("andreff", cv2.CALIB_HAND_EYE_ANDREFF),
    ("daniilidis", cv2.CALIB_HAND_EYE_DANIILIDIS),
)
_LOSSES = ("linear", "soft_l1", "huber", "cauchy", "arctan")


def _check_motion(rotations: FloatArray) -> None:
    """VisionError unless the link rotates about at least two different axes."""
    n = rotations.shape[0]
    i, j = np.triu_indices(n, 1)
    rel = np.einsum("nji,njk->nik", rotations[i], rotations[j])  # R_i^T R_j, in link frame i
    rv = Rotation.from_matrix(rel).as_rotvec()
    angle = np.linalg.norm(rv, axis=1)
    big = angle >= math.radians(_MIN_MOTION_DEG)
    if not np.any(big):
        raise VisionError(
            f"degenerate motion: the camera link turns at most {math.degrees(angle.max()):.1f} "
            f"deg between views; need rotations of at least {_MIN_MOTION_DEG:g} deg about two "
            f"different axes (turn the base and tilt the wrist)"
        )
    axes = rv[big] / angle[big, None]
    if axes.shape[0] > 200:
        axes = axes[np.linspace(0, axes.shape[0] - 1, 200).astype(int)]
    spread = np.linalg.norm(np.cross(axes[:, None, :], axes[None, :, :]), axis=-1).max()
    if spread < math.sin(math.radians(_MIN_AXIS_SPREAD_DEG)):
        a = axes[0] * np.sign(axes[0][np.argmax(np.abs(axes[0]))])
        raise VisionError(
            f"degenerate motion: every rotation between views is about one axis "
            f"({a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f} in the link frame, within "
            f"{math.degrees(math.asin(min(1.0, spread))):.1f} deg); rotate about a second axis "
            f"as well (turn the base and tilt the wrist)"
        )


def calibrate_hand_eye(
    link2base: Sequence[npt.ArrayLike],
    observations: Sequence[BoardObservation | None],
    intrinsics: CameraIntrinsics,
    *,
    link: str = "wrist_pitch",
    min_views: int = MIN_HAND_EYE_VIEWS,
    pixel_noise_px: float = 0.2,
    pose_noise_deg: float = 0.15,
    pose_noise_mm: float = 0.5,
    loss: str = "soft_l1",
    reject_outliers: bool = True,
) -> HandEyeResult:
    """Eye-in-hand calibration: the camera's pose on the link, from a fixed board.

    ``link2base[i]``: forward kinematics of the measured joints at view i (DH frame 4
    for the wrist-pitch link); ``observations[i]``: the board in that view's image
    (None: not found, skipped).

    1. A start from ``cv2.calibrateHandEye`` (every method; the best by reprojection).
    2. cam2link and board2base refined by least squares on the reprojection error of
       every board point in every view.
    3. Measured joints are off by a fraction of a degree (a servo reads in 0.24 deg
       steps), which moves each view's link pose. Step 2 alone would bend cam2link to
       explain those errors as pixels (several mm with 0.1 deg joint noise), so each
       view also gets a small pose correction, held to ``pose_noise_deg`` /
       ``pose_noise_mm`` (1 sigma) by a prior, with pixels at ``pixel_noise_px``
       (a maximum a posteriori fit; about 3x smaller errors). ``pose_noise_deg = 0``
       and ``pose_noise_mm = 0`` skip it (exact link poses: pixel noise only).

    ``loss`` (scipy's) makes the fits robust to stray points, at 3 sigma. With
    ``reject_outliers`` a view whose rms is above 3x the median and 1 px, or whose pose
    correction is beyond 4 sigma, is dropped once and the fit redone. VisionError for
    fewer than ``min_views`` views or rotations about a single axis.
    """
    if len(link2base) != len(observations):
        raise ConfigError(
            f"link2base has {len(link2base)} poses but observations has {len(observations)}"
        )
    _check_options(min_views, loss, pixel_noise_px, pose_noise_deg, pose_noise_mm)
    used = _found_views(observations, min_views, "views")
    links = {i: as_transform(f"link2base[{i}]", link2base[i]) for i in used}
    obs = _board_views(observations, used)
    _check_motion(np.stack([links[i][:3, :3] for i in used]))
    method_name, c2l, b2b = _start(links, obs, used, intrinsics)
    noise = (pixel_noise_px, math.radians(pose_noise_deg), pose_noise_mm)
    fit, used = _refine(
        _HandEyeProblem(links, obs, used, intrinsics), (c2l, b2b), noise, loss,
        min_views if reject_outliers else None,
    )
    total = sum(obs[i].count for i in used)
    sq = sum(e * e * obs[i].count for i, e in zip(used, fit.per_view_rms, strict=True))
    return HandEyeResult(
        fit.cam2link, fit.board2base, math.sqrt(sq / total), tuple(fit.per_view_rms),
        tuple(used), intrinsics, link, method_name, fit.translation_std_mm,
        fit.rotation_std_deg, fit.pose_rms_deg, fit.pose_rms_mm, _now(),
    )


def _check_options(
    min_views: int, loss: str, pixel_noise_px: float, pose_noise_deg: float,
    pose_noise_mm: float,
) -> None:
    """ConfigError for a bad ``calibrate_hand_eye`` option."""
    check_int_range("min_views", min_views, MIN_HAND_EYE_VIEWS, 10_000)
    if loss not in _LOSSES:
        raise ConfigError(f"loss {loss!r} is not one of {', '.join(_LOSSES)}")
    check_range("pixel_noise_px", pixel_noise_px, 0.01, 10.0)
    check_range("pose_noise_deg", pose_noise_deg, 0.0, 10.0)
    check_range("pose_noise_mm", pose_noise_mm, 0.0, 50.0)
    if (pose_noise_deg > 0) != (pose_noise_mm > 0):
        raise ConfigError(
            f"pose_noise_deg ({pose_noise_deg!r}) and pose_noise_mm ({pose_noise_mm!r}) must "
            f"both be > 0 (uncertain link poses) or both 0 (exact ones)"
        )


def _board_views(
    observations: Sequence[BoardObservation | None], used: list[int]
) -> dict[int, BoardObservation]:
    """The used views' observations; ConfigError for a chessboard."""
    obs: dict[int, BoardObservation] = {}
    for i in used:
        o = observations[i]
        assert o is not None
        if isinstance(o.spec, ChessboardSpec):
            raise ConfigError(
                "a chessboard cannot calibrate hand-eye: its pose is ambiguous under a half "
                "turn; use a TagBoardSpec or CharucoSpec board"
            )
        obs[i] = o
    return obs


def _start(
    links: dict[int, FloatArray], obs: dict[int, BoardObservation], used: list[int],
    intrinsics: CameraIntrinsics,
) -> tuple[str, FloatArray, FloatArray]:
    """(method, cam2link, board2base): the best ``cv2.calibrateHandEye`` start by
    reprojection error."""
    board2cam = {i: board_pose(obs[i], intrinsics)[0] for i in used}
    best: tuple[float, str, FloatArray, FloatArray] | None = None
    start = _HandEyeProblem(links, obs, used, intrinsics)
    for name, method in _HAND_EYE_METHODS:
        try:
            r_cv, t_cv = cv2.calibrateHandEye(
                [links[i][:3, :3] for i in used], [links[i][:3, 3] for i in used],
                [board2cam[i][:3, :3] for i in used], [board2cam[i][:3, 3] for i in used],
                method=method,
            )
        except cv2.error:
            continue
        r = np.asarray(r_cv, np.float64)
        t = np.asarray(t_cv, np.float64).ravel()
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(t))):
            continue
        if np.abs(r @ r.T - np.eye(3)).max() > 1e-3:
            continue
        c2l = _transform(_mean_rotation(r[None]), t)
        b2b = _board2base(c2l, links, board2cam, used)
        rms = _rms(start.residual(c2l, b2b))
        if best is None or rms < best[0]:
            best = (rms, name, c2l, b2b)
    if best is None:
        raise VisionError("no hand-eye method gave a solution (check the poses and images)")
    _, method_name, c2l, b2b = best
    return method_name, c2l, b2b


def _refine(
    problem: _HandEyeProblem, start: tuple[FloatArray, FloatArray],
    noise: tuple[float, float, float], loss: str, min_views: int | None,
) -> tuple[_HandEyeFit, list[int]]:
    """The fit over the problem's views and the views used; with ``min_views`` (outlier
    rejection on) views above 3x the median rms and 1 px, or with a pose correction
    beyond 4 sigma, are dropped once and the fit redone from the first fit."""
    used = list(problem.used)
    fit = problem.solve(*start, noise, loss)
    if min_views is None:
        return fit, used
    per_view = fit.per_view_rms
    limit = max(OUTLIER_VIEW_PX, 3.0 * float(np.median(per_view)))
    bad = [
        k for k, (e, m) in enumerate(zip(per_view, fit.pose_sigmas, strict=True))
        if e > limit or m > 4.0
    ]
    if not bad or len(used) - len(bad) < min_views:
        return fit, used
    used = [u for k, u in enumerate(used) if k not in bad]
    problem = _HandEyeProblem(problem.links, problem.obs, used, problem.intr)
    return problem.solve(fit.cam2link, fit.board2base, noise, loss), used


def _board2base(
    c2l: FloatArray, links: dict[int, FloatArray], board2cam: dict[int, FloatArray],
    used: list[int],
) -> FloatArray:
    poses = np.stack([links[i] @ c2l @ board2cam[i] for i in used])
    return _transform(_mean_rotation(poses[:, :3, :3]), poses[:, :3, 3].mean(axis=0))


@dataclass
class _HandEyeFit:
    cam2link: FloatArray
    board2base: FloatArray
    per_view_rms: list[float]
    pose_sigmas: list[float]
    translation_std_mm: float
    rotation_std_deg: float
    pose_rms_deg: float
    pose_rms_mm: float


class _HandEyeProblem:
    """Every board point of every view, and the fits of cam2link and board2base."""

    def __init__(
        self, links: dict[int, FloatArray], obs: dict[int, BoardObservation], used: list[int],
        intr: CameraIntrinsics,
    ) -> None:
        self.links, self.obs, self.used, self.intr = links, obs, used, intr
        self.views = len(used)
        self.obj = np.concatenate([obs[i].object_points_mm for i in used])
        self.img = np.concatenate([obs[i].image_points_px for i in used])
        self.counts = [obs[i].count for i in used]
        self.view = np.repeat(np.arange(self.views), self.counts)
        self.link_r = np.stack([links[i][:3, :3] for i in used])
        self.link_t = np.stack([links[i][:3, 3] for i in used])
        self.rows_of_view = [
            np.flatnonzero(np.repeat(self.view == k, 2)) for k in range(self.views)
        ]

    def residual(
        self, c2l: FloatArray, b2b: FloatArray, link_r: FloatArray | None = None,
        link_t: FloatArray | None = None,
    ) -> FloatArray:
        """(N, 2) reprojection errors, px (with corrected link poses if given)."""
        rot = self.link_r if link_r is None else link_r
        org = self.link_t if link_t is None else link_t
        p_base = self.obj @ b2b[:3, :3].T + b2b[:3, 3]
        # base -> link: R^T (p - t), per point with its view's link pose.
        p_link = np.einsum("nji,nj->ni", rot[self.view], p_base - org[self.view])
        p_cam = (p_link - c2l[:3, 3]) @ c2l[:3, :3]  # link -> camera: R^T (p - t)
        p_cam[:, 2] = np.maximum(p_cam[:, 2], 1e-6)  # behind the camera: a large error
        out: FloatArray = self.intr._project(p_cam) - self.img
        return out

    def per_view_rms(self, err: FloatArray) -> list[float]:
        return [_rms(e) for e in np.split(err, np.cumsum(self.counts)[:-1])]

    def solve(
        self, c2l0: FloatArray, b2b0: FloatArray, noise: tuple[float, float, float], loss: str
    ) -> _HandEyeFit:
        sigma_px, sigma_rad, sigma_mm = noise
        views = self.views
        with_poses = sigma_rad > 0.0
        n_params = _N_GLOBAL + (6 * views if with_poses else 0)

        def unpack(x: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
            c2l = _transform(_rotvec_matrix(x[0:3]) @ c2l0[:3, :3], c2l0[:3, 3] + x[3:6])
            b2b = _transform(_rotvec_matrix(x[6:9]) @ b2b0[:3, :3], b2b0[:3, 3] + x[9:12])
            if not with_poses:
                return c2l, b2b, self.link_r, self.link_t
            xi = x[_N_GLOBAL:].reshape(views, 6)
            # A view's corrected link pose: link2base @ [exp(w), v], w and v in the link frame.
            rot = self.link_r @ Rotation.from_rotvec(xi[:, :3]).as_matrix()
            org = self.link_t + np.einsum("nij,nj->ni", self.link_r, xi[:, 3:])
            return c2l, b2b, rot, org

        def fun(x: FloatArray) -> FloatArray:
            err = self.residual(*unpack(x)).ravel() / sigma_px
            if not with_poses:
                return err
            xi = x[_N_GLOBAL:].reshape(views, 6)
            priors = [(xi[:, :3] / sigma_rad).ravel(), (xi[:, 3:] / sigma_mm).ravel()]
            return np.concatenate([err, *priors])

        def jac(x: FloatArray) -> FloatArray:
            return self._jacobian(fun, x, n_params, with_poses, sigma_rad, sigma_mm)

        res = least_squares(
            fun, np.zeros(n_params), jac=jac, method="trf", tr_solver="exact", loss=loss,
            f_scale=3.0, x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10, max_nfev=100,
        )
        c2l, b2b, rot, org = unpack(res.x)
        err = self.residual(c2l, b2b)  # with the link poses as given
        std_t, std_r = _cam2link_std(np.asarray(res.jac), res.fun, n_params)
        if with_poses:
            xi = res.x[_N_GLOBAL:].reshape(views, 6)
            sigmas, pose_deg, pose_mm = _pose_corrections(xi, sigma_rad, sigma_mm)
        else:
            sigmas, pose_deg, pose_mm = np.zeros(views), 0.0, 0.0
        return _HandEyeFit(
            c2l, b2b, self.per_view_rms(err), [float(m) for m in sigmas], std_t, std_r,
            pose_deg, pose_mm,
        )

    def _jacobian(
        self, fun: Callable[[FloatArray], FloatArray], x: FloatArray, n_params: int,
        with_poses: bool, sigma_rad: float, sigma_mm: float,
    ) -> FloatArray:
        """Forward differences grouped by structure: a view's correction moves only that
        view's residuals, so one probe per correction component serves every view."""
        views = self.views
        f0 = fun(x)
        out = np.zeros((f0.size, n_params))
        h = 1e-6
        for j in range(_N_GLOBAL):
            xp = x.copy()
            xp[j] += h
            out[:, j] = (fun(xp) - f0) / h
        if with_poses:
            n_pix = 2 * self.img.shape[0]
            for c in range(6):
                xp = x.copy()
                xp[_N_GLOBAL + c :: 6] += h
                diff = (fun(xp) - f0) / h
                prior = n_pix + (c if c < 3 else 3 * views + c - 3)
                scale = 1.0 / (sigma_rad if c < 3 else sigma_mm)
                for k in range(views):
                    col = _N_GLOBAL + 6 * k + c
                    out[self.rows_of_view[k], col] = diff[self.rows_of_view[k]]
                    out[prior + 3 * k, col] = scale
        return out


def _cam2link_std(jac: FloatArray, fun: FloatArray, n_params: int) -> tuple[float, float]:
    """(translation mm, rotation deg) 1-sigma of cam2link from the Gauss-Newton covariance
    at the solution, scaled by the fit's own noise level when it is worse than assumed."""
    dof = max(1, fun.size - n_params)
    chi2 = max(1.0, float((fun * fun).sum()) / dof)
    try:
        cov = np.linalg.pinv(jac.T @ jac)[:6, :6] * chi2
        std_r = math.degrees(math.sqrt(max(0.0, float(np.trace(cov[0:3, 0:3])))))
        std_t = math.sqrt(max(0.0, float(np.trace(cov[3:6, 3:6]))))
    except np.linalg.LinAlgError:
        std_r = std_t = math.inf
    return std_t, std_r


def _pose_corrections(
    xi: FloatArray, sigma_rad: float, sigma_mm: float
) -> tuple[FloatArray, float, float]:
    """Per view the size of its link-pose correction in sigmas, and the rms corrections
    (deg, mm) over the views."""
    w = np.linalg.norm(xi[:, :3], axis=1)
    v = np.linalg.norm(xi[:, 3:], axis=1)
    sigmas: FloatArray = np.sqrt(((w / sigma_rad) ** 2 + (v / sigma_mm) ** 2) / 2.0)
    pose_deg = math.degrees(float(np.sqrt((w * w).mean())))
    pose_mm = float(np.sqrt((v * v).mean()))
    return sigmas, pose_deg, pose_mm
