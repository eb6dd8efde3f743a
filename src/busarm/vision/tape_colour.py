"""Which tape the floor line is: given by name (``check_tape``), or measured on the first
look (``measure_tape``), and where it lies bare in a picture (``tape_strip_mask``).

Tape is sold black, white, red, green, blue and yellow (and more). The robot starts on
the tape facing along it, so the first look finds it without knowing its colour: the
pixels whose colour is far from the floor's (``find_floor_line``'s ``"contrast"``), and
of their pieces the longest that is the tape's width all along (a box, a table's foot or
a shadow is not: ``find_floor_line``'s cross-sections). Its colour is read along its
middle (median Lab) and named: colourless and darker than the floor is ``black``,
brighter ``white``; else the default thresholds' colour holding most of its pixels;
else a Lab box around what was measured (``"measured"``), as long as it leaves out the
floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.units import listing
from busarm.vision.calibration.camera_model import CameraIntrinsics
from busarm.vision.color_thresholds import ColorRange, default_thresholds
from busarm.vision.floor_line import (
    STEP_M,
    TAPE_WIDTH_M,
    BoolArray,
    FloatArray,
    FloorLineSighting,
    each_floor_line,
    floor_pixels,
)

__all__ = [
    "FIRST_LOOK_MIN_M",
    "FLOOR_SAMPLE",
    "MEASURED_MARGIN_AB",
    "NAMED_SHARE",
    "NEUTRAL_CHROMA",
    "STANDING_LAB",
    "STRIP_BEYOND_M",
    "TapeLook",
    "check_tape",
    "flat_tape_mask",
    "measure_tape",
    "tape_names",
    "tape_strip_mask",
    "without_tape",
]


FIRST_LOOK_MIN_M = 0.2
"""The tape seen on the first look is at least this long (a patch is not the line)."""
NEUTRAL_CHROMA = 15.0
"""Tape whose colour is this near grey (Lab a, b from 128) is black or white."""
NAMED_SHARE = 0.8
"""A colour of the thresholds names the tape when it holds this share of its pixels."""
MEASURED_MARGIN_AB = 14
"""A measured colour's Lab box: its pixels' a and b (5th to 95th percentile) and this."""
STANDING_LAB = 15.0
"""A pixel of the tape's strip this far (Lab) from the tape's colour is not flat tape
(flat tape under one light is within a few: the twin's within 1; a block's lit top 25
lighter, its sides 70 darker)."""
FLOOR_SAMPLE = 16
"""The floor's colour: the median of every this many of its pixels."""
STRIP_BEYOND_M = 0.1
"""The tape's strip goes on this far beyond the seen ends (below the first floor row)."""


def tape_names() -> tuple[str, ...]:
    """The tape colours known by name: black, white and the default thresholds'."""
    return ("black", "white", *default_thresholds().names)


def check_tape(value: object, what: str = "tape colour") -> str:
    """``value`` if it names a tape colour; else ConfigError naming it and the allowed."""
    if not isinstance(value, str) or value not in tape_names():
        raise ConfigError(f"{what} {value!r}: allowed: {listing(tape_names())}")
    return value


@dataclass(frozen=True)
class TapeLook:
    """The tape found on the first look: what ``find_floor_line`` follows it by
    (``colour``), its name, and its colour and the floor's as measured (Lab, 8-bit)."""

    colour: str | ColorRange
    name: str
    lab: tuple[float, float, float]
    floor_lab: tuple[float, float, float]
    sighting: FloorLineSighting

    def text(self) -> str:
        lab = "/".join(f"{v:.0f}" for v in self.lab)
        floor = "/".join(f"{v:.0f}" for v in self.floor_lab)
        return (f"{self.name} (measured: Lab {lab} on a floor of Lab {floor}, "
                f"{self.sighting.length_m:.2f} m seen)")


def measure_tape(image: npt.NDArray[np.uint8], intrinsics: CameraIntrinsics,
                 cam_to_floor: npt.ArrayLike, *, mask: BoolArray | None = None,
                 tape_width_m: float = TAPE_WIDTH_M) -> TapeLook | None:
    """The tape in ``image`` and its colour (see the module docstring); None if no piece
    of the tape's width is at least ``FIRST_LOOK_MIN_M`` long."""
    lines = [s for s in each_floor_line(image, intrinsics, cam_to_floor, "contrast",
                                        tape_width_m=tape_width_m, mask=mask)
             if s.length_m >= FIRST_LOOK_MIN_M]
    if not lines:
        return None
    line = max(lines, key=lambda s: s.length_m)
    lab = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2Lab), dtype=np.uint8)
    floor_ok = np.ones(lab.shape[:2], bool) if mask is None else np.asarray(mask, bool).copy()
    floor_ok &= ~tape_strip_mask(line, intrinsics, cam_to_floor, 0.02)
    floor = np.median(lab[floor_ok].astype(np.float64), axis=0)
    px = np.round(floor_pixels(intrinsics, cam_to_floor, line.found_m))
    px = px[np.all(np.isfinite(px), axis=1)].astype(int)
    h, w = lab.shape[:2]
    px = px[(px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)]
    if not len(px):
        return None
    samples = lab[px[:, 1], px[:, 0]].astype(np.float64)
    tape = np.median(samples, axis=0)
    name, colour = _named(samples, tape, floor)
    return TapeLook(colour, name, _triple(tape), _triple(floor), line)


def _triple(v: FloatArray) -> tuple[float, float, float]:
    return float(v[0]), float(v[1]), float(v[2])


def _named(samples: FloatArray, tape: FloatArray, floor: FloatArray
           ) -> tuple[str, str | ColorRange]:
    """The tape's name and what it is followed by (see the module docstring)."""
    if math.hypot(tape[1] - 128.0, tape[2] - 128.0) <= NEUTRAL_CHROMA:
        name = "black" if tape[0] < floor[0] else "white"
        return name, name
    table = default_thresholds()
    shares = {n: float(np.mean([table[n].contains(tuple(int(v) for v in s))
                                for s in samples])) for n in table.names}
    best = max(shares, key=lambda n: shares[n])
    if shares[best] >= NAMED_SHARE and not table[best].contains(tuple(int(v) for v in floor)):
        return best, best
    lo = np.percentile(samples, 5, axis=0)
    hi = np.percentile(samples, 95, axis=0)
    low = [int(max(v - MEASURED_MARGIN_AB, 0)) for v in lo[1:]]
    high = [int(min(v + MEASURED_MARGIN_AB, 255)) for v in hi[1:]]
    box = ColorRange("measured", (int(max(lo[0] * 0.5, 0)), low[0], low[1]),
                     (255, high[0], high[1]))
    if box.contains(tuple(int(v) for v in floor)):
        raise ConfigError(f"the tape (Lab {'/'.join(f'{v:.0f}' for v in tape)}) is too near "
                          f"the floor's colour (Lab {'/'.join(f'{v:.0f}' for v in floor)}) "
                          "to follow by its colour")
    return "measured", box


def tape_strip_mask(sighting: FloorLineSighting, intrinsics: CameraIntrinsics,
                    cam_to_floor: npt.ArrayLike, margin_m: float = 0.006) -> BoolArray:
    """The pixels (H x W) of the strip the tape of ``sighting`` lies in: its width and
    ``margin_m`` each side, along its smoothed centre (across gaps, where something
    stood on it) and ``STRIP_BEYOND_M`` on beyond each end."""
    pts = sighting.points_m
    out = np.zeros((intrinsics.height_px, intrinsics.width_px), np.uint8)
    if len(pts) < 2:
        return out.astype(bool)
    first = (pts[1] - pts[0]) / max(float(np.linalg.norm(pts[1] - pts[0])), 1e-9)
    last = (pts[-1] - pts[-2]) / max(float(np.linalg.norm(pts[-1] - pts[-2])), 1e-9)
    pts = np.vstack([pts[0] - STRIP_BEYOND_M * first, pts, pts[-1] + STRIP_BEYOND_M * last])
    a, b = pts[:-1], pts[1:]
    step = np.linalg.norm(b - a, axis=1)
    a, b, step = a[step > 0], b[step > 0], step[step > 0]
    along = (b - a) / step[:, None]
    across = np.column_stack([-along[:, 1], along[:, 0]]) * (sighting.width_m / 2 + margin_m)
    ends = along * STEP_M / 4  # the pieces overlap a little: no seams between them
    quads = np.stack([a - ends + across, b + ends + across, b + ends - across,
                      a - ends - across], axis=1)  # (N, 4, 2)
    px = floor_pixels(intrinsics, cam_to_floor, quads.reshape(-1, 2)).reshape(-1, 4, 2)
    seen = np.all(np.isfinite(px), axis=(1, 2))
    for quad in np.round(px[seen] * 16).astype(np.int32):  # one by one: they overlap
        cv2.fillConvexPoly(out, quad, 1, cv2.LINE_8, 4)
    return out.astype(bool)


def flat_tape_mask(image: npt.NDArray[np.uint8], sighting: FloorLineSighting,
                   intrinsics: CameraIntrinsics, cam_to_floor: npt.ArrayLike,
                   mask: BoolArray | None = None) -> tuple[BoolArray, FloatArray]:
    """The pixels (H x W) of the flat tape of ``sighting`` in ``image`` (BGR), and the
    floor's colour (BGR: the median of ``mask``'s pixels off the tape). In the tape's
    strip (``tape_strip_mask``) the pixels within ``STANDING_LAB`` of the tape's colour
    (the median at its centre's bare points) or of a blend of it and the floor's (its
    edges) are flat tape; a thing of its colour standing on it is not (its top and sides
    catch the light otherwise than the flat tape: its height, not its colour)."""
    strip = tape_strip_mask(sighting, intrinsics, cam_to_floor)
    out = np.zeros(strip.shape, bool)
    px = np.round(floor_pixels(intrinsics, cam_to_floor, sighting.found_m))
    h, w = strip.shape
    px = px[np.all(np.isfinite(px), axis=1)].astype(int)
    px = px[(px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)]
    floor_ok = ~strip if mask is None else np.asarray(mask, bool) & ~strip
    floor_px = image[floor_ok][::FLOOR_SAMPLE]  # (enough for a median: fast)
    rows, cols = np.nonzero(strip)
    if not len(rows) or not len(px) or not len(floor_px):
        return out, np.zeros(3)
    floor_bgr = np.median(floor_px.astype(np.float64), axis=0)
    r0, r1, c0, c1 = rows.min(), rows.max() + 1, cols.min(), cols.max() + 1
    lab = np.asarray(cv2.cvtColor(image[r0:r1, c0:c1], cv2.COLOR_BGR2Lab), dtype=np.float32)
    tape = np.median(np.asarray(cv2.cvtColor(image[px[:, 1], px[:, 0]][None], cv2.COLOR_BGR2Lab),
                                dtype=np.float32)[0], axis=0)
    floor = np.asarray(cv2.cvtColor(floor_bgr.astype(np.uint8)[None, None], cv2.COLOR_BGR2Lab),
                       dtype=np.float32).reshape(3)
    # The tape's edges blend it with the floor: what lies near the segment between the
    # two colours is flat.
    span = floor - tape
    t = np.clip((lab - tape) @ span / max(float(span @ span), 1e-6), 0.0, 1.0)
    off = np.linalg.norm(lab - tape - t[..., None] * span, axis=2)
    out[r0:r1, c0:c1] = strip[r0:r1, c0:c1] & (off <= STANDING_LAB)
    return out, floor_bgr


def without_tape(image: npt.NDArray[np.uint8], sighting: FloorLineSighting,
                 intrinsics: CameraIntrinsics, cam_to_floor: npt.ArrayLike,
                 mask: BoolArray | None = None) -> npt.NDArray[np.uint8]:
    """``image`` (BGR) with the flat tape (``flat_tape_mask``) painted the floor's colour:
    a block locator then sees no block of the tape's colour in the tape itself, and still
    one standing on it."""
    flat, floor = flat_tape_mask(image, sighting, intrinsics, cam_to_floor, mask)
    if not np.any(flat):
        return image
    out = image.copy()
    out[flat] = floor.astype(np.uint8)
    return out
