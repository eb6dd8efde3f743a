"""The floor line (tape) seen by a camera, in metres on the floor, for line following.

Frames and units: the base frame lies on the floor (x forward, y left, z up, REP 103),
metres and radians; ``cam_to_floor`` is the camera's pose in it (OpenCV camera axes,
4x4, metres), so the floor is the plane z = 0.

``find_floor_line`` works on the floor, not on pixels (the vendor's three image bands
and their weighted centroids are neither metric nor robust to a curve):

1. **Tape score** per pixel. Black tape: how much darker a pixel is than the floor
   around it, ``1 - grey / local floor grey`` (the floor's level from a grey closing
   wider than the tape looks, so uneven light and soft shadows cancel, and a dark
   thing wider than that closing, a box's base or a shadow, is no darker than its
   own surroundings), counted only where the pixel has no colour (a blue block's
   shaded side is dark too). White tape (on a dark floor): the same, brighter than the
   floor (a grey opening). A colour (``"blue"``, any ``ColorRange``): the pixels in its
   Lab box. ``"contrast"`` (the first look, busarm.vision.tape_colour): how far a
   pixel's colour is from the floor's, whatever the tape's colour.
2. **Pieces**: the connected blobs of tape-like pixels, each cast onto the floor
   through the camera model (lens distortion undone); the pieces are tried nearest
   to the robot first, so where the loop curves out of view and comes back farther
   off, the piece that starts nearest the robot is the one followed.
3. **Tracking on the floor**: from a piece's nearest part, a cross-section is sampled
   perpendicular to the tape every ``STEP_M`` (floor points projected into the
   image, the score read there bilinearly); the tape's edges are where the score
   crosses half its peak (sub-pixel), its centre their midpoint, its width their
   distance in metres. A cross-section counts only when that width is the tape's
   (within ``WIDTH_TOLERANCE``): a block, a box's side or a shadow beside the tape is
   stepped over, and a piece that never has the tape's width is not tape.
4. **A smooth curve**: local quadratic fits along the arc length give each centre
   point, the line's heading and its curvature; ``lateral_m`` and ``heading_rad``
   answer at a look-ahead distance (extrapolated along the end's arc up to
   ``EXTRAPOLATE_M`` beyond what is seen: the line under the robot itself).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError, VisionError
from busarm.units import check_range, listing
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.calibration.core import as_transform, invert_transform
from busarm.vision.camera import check_bgr_image
from busarm.vision.color_thresholds import ColorRange, default_thresholds

__all__ = [
    "BRIGHT_MIN",
    "CHROMA_MAX",
    "CONTRAST_MIN",
    "CURVATURE_WINDOW_M",
    "DARK_MIN",
    "EXTRAPOLATE_M",
    "MAX_GAP_M",
    "MAX_RANGE_M",
    "MIN_LENGTH_M",
    "MIN_PIECE_PX",
    "NEAR_ARC_M",
    "POSITION_WINDOW_M",
    "SEED_RADIUS_M",
    "SEED_SAMPLES",
    "STEP_M",
    "TAPE_WIDTH_M",
    "UNDISTORT_TOL_PX",
    "WIDTH_TOLERANCE",
    "BoolArray",
    "FloatArray",
    "FloorLineSighting",
    "TapeSpec",
    "each_floor_line",
    "find_floor_line",
    "floor_pixels",
    "tape_colour_spec",
]


FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

TAPE_WIDTH_M = 0.03
"""The usual floor tape: 30 mm (the twin's arenas use it)."""
WIDTH_TOLERANCE = 0.35
"""A cross-section is tape when its width is within this share of the tape's width."""
STEP_M = 0.01
"""Between cross-sections along the line."""
MAX_GAP_M = 0.06
"""Cross-sections that are not tape (a block on it, glare) are stepped over this far."""
MIN_LENGTH_M = 0.06
"""A piece shorter than this (a dark block is one tape width long) is not the line."""
MAX_RANGE_M = 1.5
"""Floor farther from the base's centre than this is not looked at (by default)."""
EXTRAPOLATE_M = 0.3
"""How far beyond the seen ends ``lateral_m`` and ``heading_rad`` follow the end's arc."""
DARK_MIN = 0.4
"""Black tape: at least this much darker than the floor around it (the tape is about
0.9 darker; shadows about 0.2-0.4)."""
BRIGHT_MIN = 0.4
"""White tape: at least this much brighter than the floor around it (``1 - floor / grey``;
white tape on a dark floor is about 0.8)."""
CONTRAST_MIN = 30.0
"""``"contrast"``: a pixel this far from the floor's colour (Lab, 8-bit, lightness counted
half: light falls unevenly, a colour's hue does not) may be tape."""
CHROMA_MAX = 30
"""Black tape: the most its BGR channels may differ (levels); coloured things differ more."""
MIN_PIECE_PX = 30
"""Smaller blobs of tape-like pixels are specks."""
SEED_RADIUS_M = 0.08
"""The piece's part this near its point nearest the robot gives where tracking starts."""
POSITION_WINDOW_M = 0.03
"""Centre points: quadratic fits over this much of the arc each side."""
CURVATURE_WINDOW_M = 0.08
"""Headings and curvatures: over this much each side (derivatives need the length)."""
NEAR_ARC_M = 0.25
"""``curvature_1_m`` is the mean curvature over the line's first this much."""
SEED_SAMPLES = 600
"""At most this many of a blob's pixels are cast onto the floor to place it."""
UNDISTORT_TOL_PX = 0.05
_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-8)


@dataclass(frozen=True, eq=False)
class FloorLineSighting:
    """The line's centre on the floor (base frame, m), nearest first; see the module
    docstring. ``found_share``: the share of cross-sections along it that found the tape
    (1.0 when nothing covered it)."""

    points_m: FloatArray
    """(N, 2) smoothed centre points, ordered along the line from the end nearest the robot."""
    s_m: FloatArray
    """(N,) arc length of each point from the first."""
    headings_rad: FloatArray
    """(N,) the line's direction at each point (toward the far end), from the base's x."""
    curvatures_1_m: FloatArray
    """(N,) the line's curvature at each point (1/m, positive turning left)."""
    width_m: float
    """The tape's width as measured (median over the cross-sections)."""
    found_share: float
    colour: str
    found_m: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    """(M, 2) the centres of the cross-sections that found the tape (its width), along the
    line: where the tape lies bare (not where something stands on it)."""

    @property
    def length_m(self) -> float:
        return float(self.s_m[-1])

    @property
    def curvature_1_m(self) -> float:
        """The mean curvature (1/m, + left) over the first ``NEAR_ARC_M`` of the line."""
        near = self.s_m <= min(NEAR_ARC_M, self.length_m) + 1e-9
        return float(np.mean(self.curvatures_1_m[near]))

    def lateral_m(self, at_x_m: float) -> float:
        """Where the line is sideways (m, + left) at ``at_x_m`` ahead of the base's centre."""
        return self._at_x(at_x_m)[1]

    def heading_rad(self, at_x_m: float) -> float:
        """The line's direction (rad, + left of the base's x) at ``at_x_m`` ahead."""
        return self._at_x(at_x_m)[2]

    def _at_x(self, at_x_m: float) -> tuple[float, float, float]:
        """(x, y, heading) where the line first reaches x = ``at_x_m`` along it, seen or
        within ``EXTRAPOLATE_M`` of arc beyond an end; VisionError if it does not."""
        x = check_range("at_x_m", at_x_m, -100.0, 100.0, "m")
        p, th = self.points_m, np.unwrap(self.headings_rad)
        side = p[:, 0] - x
        hits = np.flatnonzero((side[:-1] * side[1:] <= 0) & (side[:-1] != side[1:]))
        if side[0] == 0.0:
            return float(p[0, 0]), float(p[0, 1]), float(self.headings_rad[0])
        if hits.size:
            k = int(hits[0])
            f = side[k] / (side[k] - side[k + 1])
            y = p[k, 1] + f * (p[k + 1, 1] - p[k, 1])
            return x, float(y), _wrap(float(th[k] + f * (th[k + 1] - th[k])))
        kappa = self.curvature_1_m
        for start, heading, sign in ((p[0], th[0], -1.0), (p[-1], th[-1], 1.0)):
            found = _arc_to_x(start, float(heading), kappa, sign, x)
            if found is not None:
                return found
        raise VisionError(
            f"the line is seen from x {p[:, 0].min():.3f} to {p[:, 0].max():.3f} m and does "
            f"not reach x = {x:g} m within {EXTRAPOLATE_M:g} m beyond its ends")

    def to_dict(self) -> dict[str, object]:
        """For reports (JSON): the points (metres, to 0.1 mm) and the summary numbers."""
        return {"colour": self.colour, "points_m": np.round(self.points_m, 4).tolist(),
                "length_m": round(self.length_m, 4), "width_m": round(self.width_m, 4),
                "curvature_1_m": round(self.curvature_1_m, 4),
                "found_share": round(self.found_share, 3)}


def _wrap(angle_rad: float) -> float:
    return (angle_rad + math.pi) % (2 * math.pi) - math.pi


def _arc_to_x(start: FloatArray, heading: float, kappa: float, sign: float,
              x: float) -> tuple[float, float, float] | None:
    """Follow the arc through ``start`` (heading, curvature) forward (``sign`` 1) or back
    (-1) up to EXTRAPOLATE_M; where it first reaches x = ``x``, else None."""
    u = sign * np.linspace(0.0, EXTRAPOLATE_M, 151)
    th = heading + kappa * u
    if abs(kappa) < 1e-9:
        xs, ys = start[0] + u * math.cos(heading), start[1] + u * math.sin(heading)
    else:
        xs = start[0] + (np.sin(th) - math.sin(heading)) / kappa
        ys = start[1] - (np.cos(th) - math.cos(heading)) / kappa
    side = xs - x
    hits = np.flatnonzero(side[:-1] * side[1:] <= 0)
    if not hits.size:
        return None
    k = int(hits[0])
    f = 0.0 if side[k] == side[k + 1] else side[k] / (side[k] - side[k + 1])
    return (x, float(ys[k] + f * (ys[k + 1] - ys[k])),
            _wrap(float(th[k] + f * (th[k + 1] - th[k]))))


# ---------------------------------------------------------------------- the camera


class _FloorView:
    """Casting between the floor (base frame, m) and the picture's pixels."""

    def __init__(self, intrinsics: CameraIntrinsics, cam_to_floor: FloatArray) -> None:
        self.intrinsics = intrinsics
        self.cam2floor = cam_to_floor
        self.floor2cam = invert_transform(cam_to_floor)

    def pixels(self, floor_xy: FloatArray) -> FloatArray:
        """(N, 2) floor points -> (N, 2) pixels; NaN where a point is not in front."""
        p = floor_xy @ self.floor2cam[:3, :2].T + self.floor2cam[:3, 3]  # z = 0
        out = np.full((len(p), 2), np.nan)
        ahead = p[:, 2] > 1e-3
        if np.any(ahead):
            out[ahead] = self.intrinsics.pixels_from_camera_points(p[ahead] * 1000.0)
        return out

    def floor(self, px: FloatArray) -> FloatArray:
        """(N, 2) pixels -> (N, 2) floor points; NaN where the ray misses the floor."""
        xy = self._normalized(px)
        rot, origin = self.cam2floor[:3, :3], self.cam2floor[:3, 3]
        ray = np.c_[xy, np.ones(len(xy))] @ rot.T
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -origin[2] / ray[:, 2]
        out: FloatArray = origin[:2] + s[:, None] * ray[:, :2]
        out[~(s > 0)] = np.nan
        return out

    def _normalized(self, px: FloatArray) -> FloatArray:
        """Undistorted normalised coordinates of pixels; NaN where the lens model does not
        map back onto the pixel (beyond where a strong distortion folds over, at the
        corners): such pixels are left out rather than failing the picture."""
        intr = self.intrinsics
        src = px.reshape(-1, 1, 2)
        if intr.model == "pinhole":
            eye = np.eye(3)  # no rectification; normalised coordinates out
            out = cv2.undistortPointsIter(src, intr.camera_matrix, intr.distortion, eye, eye,
                                          _UNDISTORT_CRITERIA)
        else:
            out = cv2.fisheye.undistortPoints(src, intr.camera_matrix, intr.distortion)
        xy = np.asarray(out, dtype=np.float64).reshape(-1, 2)
        back = intr.pixels_from_camera_points(np.c_[xy, np.ones(len(xy))])
        xy[~(np.hypot(*(back - px).T) <= UNDISTORT_TOL_PX)] = np.nan
        return xy

    def tape_px(self, width_m: float) -> float:
        """How wide the tape looks at most (px): seen from straight above the camera's foot."""
        return self.intrinsics.fx * width_m / float(self.cam2floor[2, 3])


# ---------------------------------------------------------------------- scores


TapeSpec = ColorRange | Literal["black", "white", "contrast"]
"""How tape is told from the floor: a Lab box, darker or brighter than the floor and
colourless, or any colour far from the floor's (the first look)."""


def tape_colour_spec(colour: str | ColorRange) -> tuple[str, TapeSpec]:
    """The name and the scoring of a tape colour: ``black``, ``white``, a colour of the
    default thresholds or a ``ColorRange`` (``contrast``: any colour, for the first look);
    ConfigError naming the value and what is allowed."""
    if isinstance(colour, ColorRange):
        return colour.name, colour
    if colour == "black":
        return "black", "black"
    if colour == "white":
        return "white", "white"
    if colour == "contrast":
        return "contrast", "contrast"
    table = default_thresholds()
    if isinstance(colour, str) and colour in table.names:
        return colour, table[colour]
    raise ConfigError(f"line colour {colour!r}: give black, white, one of "
                      f"{listing(table.names)}, or a ColorRange")


def _relative(grey: npt.NDArray[np.uint8], mask: BoolArray, tape_px: float,
              darker: bool) -> npt.NDArray[np.float32]:
    """How much darker (``darker``) or brighter than the floor around it each pixel is:
    the floor's level from a grey closing (opening) wider than the tape looks."""
    if not np.all(mask):  # the floor's level where the picture is not floor
        grey = grey.copy()
        grey[~mask] = int(np.median(np.asarray(grey[mask]))) if np.any(mask) else 255
    side = int(min(max(3 * tape_px, 7), 255)) | 1
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (side, side))
    op = cv2.MORPH_CLOSE if darker else cv2.MORPH_OPEN
    floor = cv2.morphologyEx(grey, op, kernel).astype(np.float32)
    g = grey.astype(np.float32)
    if darker:
        return np.asarray(1.0 - g / np.maximum(floor, 1.0), dtype=np.float32)
    return np.asarray(1.0 - np.maximum(floor, 1.0) / np.maximum(g, 1.0), dtype=np.float32)


def _tape_score(image: npt.NDArray[np.uint8], colour: TapeSpec, mask: BoolArray,
                tape_px: float) -> tuple[npt.NDArray[np.float32], float]:
    """Per pixel how tape-like it is (NaN outside ``mask``), and the level that counts."""
    if isinstance(colour, ColorRange):
        lab = cv2.cvtColor(image, cv2.COLOR_BGR2Lab)
        score = cv2.inRange(lab, np.array(colour.lab_min, np.uint8),
                            np.array(colour.lab_max, np.uint8)).astype(np.float32) / 255.0
        level = 0.5
    elif colour == "contrast":
        lab = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2Lab), dtype=np.float32)
        floor = (np.median(np.asarray(lab[mask], dtype=np.float64), axis=0) if np.any(mask)
                 else np.full(3, 128.0))
        diff = (lab - floor.astype(np.float32)) * np.array([0.5, 1.0, 1.0], np.float32)
        score = np.sqrt(np.sum(diff * diff, axis=2), dtype=np.float32)
        level = CONTRAST_MIN
    else:
        grey = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)
        score = _relative(grey, mask, tape_px, colour == "black")
        chroma = cv2.subtract(cv2.max(cv2.max(image[..., 0], image[..., 1]), image[..., 2]),
                              cv2.min(cv2.min(image[..., 0], image[..., 1]), image[..., 2]))
        score[chroma > CHROMA_MAX] = 0.0
        level = DARK_MIN if colour == "black" else BRIGHT_MIN
    score[~mask] = np.nan
    return score, level


# ---------------------------------------------------------------------- cross-sections


@dataclass(frozen=True)
class _Cut:
    """One cross-section: where the tape's centre is along it (m from its middle), how
    wide it is, or that the section left the picture (``outside``)."""

    offset_m: float = 0.0
    width_m: float = math.nan
    outside: bool = False


class _Tracker:
    """Samples cross-sections of the tape score on the floor (see the module docstring)."""

    def __init__(self, view: _FloorView, score: npt.NDArray[np.float32], level: float,
                 width_m: float, max_range_m: float) -> None:
        self.view, self.score, self.level = view, score, level
        self.width_m, self.max_range_m = width_m, max_range_m
        self.ds_m = width_m / 20
        half = 1.5 * width_m + 0.02
        self.offsets: FloatArray = np.arange(-half, half + self.ds_m / 2, self.ds_m,
                                             dtype=np.float64)

    def sample(self, centre: FloatArray, along: FloatArray,
               offsets: FloatArray | None = None) -> tuple[FloatArray, FloatArray]:
        """The score at ``centre + offsets * along`` (NaN outside the picture's floor)."""
        off = self.offsets if offsets is None else offsets
        px = self.view.pixels(centre + off[:, None] * along).astype(np.float32)
        values = cv2.remap(self.score, px[None, :, 0], px[None, :, 1], cv2.INTER_LINEAR,
                           borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
        return off, np.asarray(values[0], dtype=np.float64)

    def cut(self, centre: FloatArray, normal: FloatArray,
            offsets: FloatArray | None = None) -> _Cut:
        """The tape across ``normal`` through ``centre``: the run nearest the middle."""
        off, v = self.sample(centre, normal, offsets)
        mid = len(off) // 2
        if not math.isfinite(v[mid]) or math.hypot(*centre) > self.max_range_m:
            return _Cut(outside=True)
        idx = np.flatnonzero(v >= self.level)  # NaN compares False
        if not idx.size:
            return _Cut()
        jumps = np.diff(idx) > 1
        starts = idx[np.concatenate(([True], jumps))]
        ends = idx[np.concatenate((jumps, [True]))]
        away = np.where((starts <= mid) & (ends >= mid), 0,
                        np.minimum(np.abs(starts - mid), np.abs(ends - mid)))
        k = int(np.argmin(away))
        a, b = int(starts[k]), int(ends[k])
        peak = a + int(np.argmax(v[a:b + 1]))
        half = 0.5 * float(v[peak])
        left, right = _edge(off, v, peak, half, -1), _edge(off, v, peak, half, 1)
        if math.isnan(left) or math.isnan(right):  # the tape runs out of the picture
            return _Cut(outside=True)
        if math.isinf(left) or math.isinf(right):
            return _Cut()
        return _Cut((left + right) / 2, right - left)

    def is_tape(self, cut: _Cut) -> bool:
        return abs(cut.width_m - self.width_m) <= WIDTH_TOLERANCE * self.width_m


def _edge(off: FloatArray, v: FloatArray, peak: int, level: float, step: int) -> float:
    """Where ``v`` falls below ``level`` walking from ``peak`` by ``step`` (interpolated);
    NaN if the walk meets the picture's edge first, inf if the section's end."""
    i = peak
    while 0 <= i + step < len(v):
        nxt = v[i + step]
        if math.isnan(nxt):
            return math.nan
        if nxt < level:
            f = (v[i] - level) / (v[i] - nxt)
            return float(off[i] + f * (off[i + step] - off[i]))
        i += step
    return math.inf


def _unit(v: FloatArray) -> FloatArray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _normal(t: FloatArray) -> FloatArray:
    return np.array([-t[1], t[0]])


def _seed(tracker: _Tracker, near: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """A start on the tape near ``near`` (its centre) and the tape's direction there: of
    sections through it every 15 degrees, the narrowest runs across the tape."""
    wide: FloatArray = np.arange(-0.1, 0.1 + tracker.ds_m / 2, tracker.ds_m, dtype=np.float64)
    best: tuple[float, FloatArray, float] | None = None
    for angle in np.radians(np.arange(0.0, 180.0, 15.0)):
        across = np.array([math.cos(angle), math.sin(angle)])
        cut = tracker.cut(near, across, wide)
        if math.isfinite(cut.width_m) and (best is None or cut.width_m < best[0]):
            best = (cut.width_m, across, cut.offset_m)
    if best is None:
        return None
    across = best[1]
    centre = near + best[2] * across
    cut = tracker.cut(centre, across)
    if cut.outside or not tracker.is_tape(cut):
        return None
    return centre + cut.offset_m * across, np.array([across[1], -across[0]])


def _march(tracker: _Tracker, start: FloatArray, direction: FloatArray
           ) -> tuple[list[FloatArray], int, int, list[float]]:
    """Follow the tape from ``start`` along ``direction``: its centres (not ``start``),
    sections tried and found, and the widths found."""
    points: list[FloatArray] = []
    widths: list[float] = []
    tried = found = 0
    centre, t, last = start, direction, [start]
    missed_m = 0.0
    while missed_m <= MAX_GAP_M:
        guess = centre + STEP_M * t
        cut = tracker.cut(guess, _normal(t))
        if cut.outside:
            break
        tried += 1
        if not tracker.is_tape(cut):
            centre, missed_m = guess, missed_m + STEP_M
            continue
        found += 1
        centre, missed_m = guess + cut.offset_m * _normal(t), 0.0
        points.append(centre)
        widths.append(cut.width_m)
        last = [*last[-2:], centre]
        t = _unit(centre - last[0])  # over up to three steps: smoother than one
    return points, tried, found, widths


# ---------------------------------------------------------------------- the line


def _pieces(view: _FloorView, score: npt.NDArray[np.float32], level: float,
            max_range_m: float) -> list[FloatArray]:
    """Each blob of tape-like pixels as floor points, nearest the robot first."""
    on = (np.nan_to_num(score, nan=0.0) >= level).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(on, connectivity=8)
    ys, xs = np.nonzero(labels)
    which = labels[ys, xs]
    out: list[tuple[float, FloatArray]] = []
    for label in range(1, count):
        if stats[label, cv2.CC_STAT_AREA] < MIN_PIECE_PX:
            continue
        sel = np.flatnonzero(which == label)
        sel = sel[:: max(1, len(sel) // SEED_SAMPLES)]
        floor = view.floor(np.c_[xs[sel], ys[sel]].astype(np.float64))
        floor = floor[np.all(np.isfinite(floor), axis=1)]
        dist = np.hypot(floor[:, 0], floor[:, 1])
        floor, dist = floor[dist <= max_range_m], dist[dist <= max_range_m]
        if len(floor):
            out.append((float(dist.min()), floor))
    out.sort(key=lambda item: item[0])
    return [floor for _, floor in out]


def _follow(tracker: _Tracker, piece: FloatArray, from_middle: bool = False
            ) -> tuple[FloatArray, float, float] | None:
    """The tape of one piece: its centres (nearest end first), width and found share
    (``from_middle``: tracked from its middle if not from its near end)."""
    nearest = piece[int(np.argmin(np.hypot(piece[:, 0], piece[:, 1])))]
    away = np.hypot(*(piece - nearest).T)
    seed = _seed(tracker, piece[away <= SEED_RADIUS_M].mean(axis=0))
    if seed is None and from_middle:  # its near end runs into something else
        seed = _seed(tracker, piece[int(np.argmin(np.abs(away - np.median(away))))])
    if seed is None:
        return None
    start, t = seed
    ahead, tried_a, found_a, widths_a = _march(tracker, start, t)
    back, tried_b, found_b, widths_b = _march(tracker, start, -t)
    points = np.array([*back[::-1], start, *ahead])
    if len(points) < 2:
        return None
    if math.hypot(*points[0]) > math.hypot(*points[-1]):
        points = points[::-1]
    length = float(np.sum(np.hypot(*np.diff(points, axis=0).T)))
    if length < MIN_LENGTH_M:
        return None
    tried = tried_a + tried_b + 1
    found = found_a + found_b + 1
    return points, float(np.median(widths_a + widths_b or [tracker.width_m])), found / tried


def _local_quadratic(s: FloatArray, values: FloatArray, window_m: float
                     ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """At each arc length of ``s``: a least-squares quadratic of the (N, 2) ``values``
    over the points within ``window_m`` along the arc; its value, first and second
    derivative (all (N, 2))."""
    u = (s[None, :] - s[:, None]) / window_m  # scaled: well conditioned
    w = (np.abs(u) <= 1.0).astype(np.float64)
    powers = np.stack([w * u ** p for p in range(5)])  # (5, N, N)
    moments = powers.sum(axis=2)  # (5, N)
    normal = np.stack([moments[i:i + 3] for i in range(3)]).transpose(2, 0, 1)  # (N, 3, 3)
    # Two points in a window: a straight line; one alone (past a gap in the tape, which
    # the march steps over up to MAX_GAP_M, wider than a window): itself, level.
    normal[:, 1, 1] += 1e-9
    normal[:, 2, 2] += 1e-9
    rhs = np.einsum("pnj,jd->npd", powers[:3], values)  # (N, 3, 2)
    c = np.linalg.solve(normal, rhs)
    return c[:, 0], c[:, 1] / window_m, 2 * c[:, 2] / window_m ** 2


def _smooth(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Local quadratic fits along the arc: points, arc lengths, headings, curvatures."""
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(points, axis=0).T))]
    out, _, _ = _local_quadratic(s, points, POSITION_WINDOW_M)
    _, d1, d2 = _local_quadratic(s, points, CURVATURE_WINDOW_M)
    heading = np.arctan2(d1[:, 1], d1[:, 0])
    speed = np.maximum(np.hypot(d1[:, 0], d1[:, 1]), 1e-9)
    kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / speed ** 3
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(out, axis=0).T))]
    return out, s, heading, kappa


def each_floor_line(
    image: npt.NDArray[np.uint8], intrinsics: CameraIntrinsics, cam_to_floor: npt.ArrayLike,
    colour: str | ColorRange = "black", *, tape_width_m: float = TAPE_WIDTH_M,
    mask: npt.NDArray[np.bool_] | None = None, max_range_m: float = MAX_RANGE_M,
    from_middle: bool = False,
) -> Iterator[FloorLineSighting]:
    """Every piece of tape in ``image`` that is a line, nearest the robot first (see
    ``find_floor_line`` for the arguments; ``colour`` may also be ``"contrast"``);
    ``from_middle``: a piece whose near end runs into something (the gripper's edge in
    a close look) is tracked from its middle."""
    img = check_bgr_image(image)
    if (img.shape[1], img.shape[0]) != intrinsics.size:
        raise ConfigError(f"the image is {img.shape[1]}x{img.shape[0]} px; the intrinsics "
                          f"are for {intrinsics.width_px}x{intrinsics.height_px}")
    pose = as_transform("cam_to_floor", cam_to_floor)
    check_range("camera height (cam_to_floor z)", pose[2, 3], 0.02, 10.0, "m")
    width = check_range("tape_width_m", tape_width_m, 0.005, 0.2, "m")
    reach = check_range("max_range_m", max_range_m, 0.1, 20.0, "m")
    name, spec = tape_colour_spec(colour)
    floor_ok = np.ones(img.shape[:2], bool) if mask is None else np.asarray(mask)
    if floor_ok.shape != img.shape[:2]:
        raise ConfigError(f"mask is {floor_ok.shape}; the image is {img.shape[:2]}")
    view = _FloorView(intrinsics, pose)
    score, level = _tape_score(img, spec, floor_ok.astype(bool), view.tape_px(width))
    tracker = _Tracker(view, score, level, width, reach)
    for piece in _pieces(view, score, level, reach):
        followed = _follow(tracker, piece, from_middle)
        if followed is None:
            continue
        raw, measured_width, share = followed
        points, s, heading, kappa = _smooth(raw)
        yield FloorLineSighting(points, s, heading, kappa, measured_width, share, name, raw)


def find_floor_line(
    image: npt.NDArray[np.uint8], intrinsics: CameraIntrinsics, cam_to_floor: npt.ArrayLike,
    colour: str | ColorRange = "black", *, tape_width_m: float = TAPE_WIDTH_M,
    mask: npt.NDArray[np.bool_] | None = None, max_range_m: float = MAX_RANGE_M,
) -> FloorLineSighting | None:
    """The floor line in ``image`` (see the module docstring), or None if none is seen.

    ``cam_to_floor``: the camera's pose in the base frame on the floor (4x4, m).
    ``colour``: ``"black"``, ``"white"``, a colour of the default thresholds (``"blue"``...)
    or a ``ColorRange``. ``mask``: the pixels that may show the floor (H x W, True; e.g.
    not the robot's own gripper); ``max_range_m``: farther floor is not looked at.
    """
    return next(each_floor_line(image, intrinsics, cam_to_floor, colour,
                                tape_width_m=tape_width_m, mask=mask,
                                max_range_m=max_range_m), None)


def floor_pixels(intrinsics: CameraIntrinsics, cam_to_floor: npt.ArrayLike,
                 floor_xy_m: npt.ArrayLike) -> FloatArray:
    """(N, 2) floor points (base frame, m) -> (N, 2) pixels; NaN where not in front."""
    view = _FloorView(intrinsics, as_transform("cam_to_floor", cam_to_floor))
    return view.pixels(np.asarray(floor_xy_m, dtype=np.float64).reshape(-1, 2))
