"""Colour blocks in Lab: a fast detector, and the vendor's pipeline as its baseline.

A colour is a box ``lab_min..lab_max`` in OpenCV's 8-bit Lab (the thresholds, read from
our TOML or the vendor's YAML: ``busarm.vision.color_thresholds``).

:class:`ColorDetector` finds every blob of each colour in two passes:

1. **Coarse, at reduced resolution** (``downscale``, default 2: 640x480 -> 320x240 by
   ``INTER_AREA``, which also averages the noise away as the vendor's blur does). Each
   pixel's colour is one table look-up: a 32x32x32 BGR table, built once from the Lab
   boxes with ``cv2.cvtColor`` on the bin centres, holds one bit per colour (so
   overlapping boxes both match). The pixel's index into it comes from one
   ``cv2.cvtColor`` to BGR565 (5 bits of blue and red, 6 of green: the table is laid out
   over those 16 bits, each green bin twice). Per colour: that bit's outer contours; specks whose
   bounding box is below the minimum area are dropped right there.
2. **Refined at full resolution**, only inside each coarse blob's bounding box (grown
   by two coarse pixels): exact Lab of those pixels, the colour's box, a 3x3 opening,
   outer contours; centroid, area and the oriented rectangle come from them. The
   table's quantisation therefore only decides whether a blob is looked at, never
   where it is, and blocks merged at the coarse scale come apart again.

On 640x480 frames with 3-6 blocks this runs about 3x the vendor's pipeline
(:func:`vendor_style_detect`, kept as the baseline) on one core in a process whose C
allocator has settled (4-5x in a fresh one, where the vendor's full-frame buffers are
faulted in again every frame), finds the same blocks, and its centroids are within
about 0.1 px of the vendor's (0.5 px at worst, on edges aligned with the pixel grid
where noise decides); ``busarm.bench_vision`` measures both.

Detections are sorted by colour (the detector's colour order), then by area, largest
first. Blobs spanning the whole frame edge to edge are not blocks (a covered lens, a
uniform or saturated frame, a background that matches) and are left out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.units import check_int_range, check_range
from busarm.vision.camera import UInt8Image, check_bgr_image
from busarm.vision.color_thresholds import ColorThresholds, parse_color_names

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int32]

DEFAULT_MIN_AREA_PX = 200.0
DEFAULT_DOWNSCALE = 2
LUT_BITS = 5
"""Bits per BGR channel of the coarse colour table: 32 bins of 8 levels each."""
_KERNEL = np.ones((3, 3), np.uint8)
_MARGIN_SMALL_PX = 2
"""Refinement window: the coarse box grown by this many coarse pixels on each side."""


# ---------------------------------------------------------------------- detections


@dataclass(frozen=True)
class Detection:
    """One blob of one colour, in full-resolution pixel coordinates (u right, v down;
    integer values are pixel centres, as everywhere in OpenCV).

    - ``centroid_px``: the blob's centroid, sub-pixel, from the moments of its outline;
    - ``area_px``: pixels inside the outline, the outline included (holes count);
    - ``rect_center_px``, ``rect_size_px`` (w, h), ``box_px`` (4 x 2 corners): the
      smallest rotated rectangle around the blob's pixels;
    - ``yaw_deg``: that rectangle's angle from the +u axis towards +v (clockwise on the
      screen), normalised to (-45, 45]: a square block looks the same every 90 deg, so
      its yaw is only known modulo 90. ``rect_size_px[0]`` is the side along ``yaw_deg``
      (for an oblong blob, compare w and h to know which way is long);
    - ``contour_px``: the outer outline, N x 2 int32.
    """

    color: str
    centroid_px: tuple[float, float]
    area_px: float
    rect_center_px: tuple[float, float]
    rect_size_px: tuple[float, float]
    yaw_deg: float
    box_px: FloatArray = field(compare=False, repr=False)
    contour_px: IntArray = field(compare=False, repr=False)

    def to_dict(self, *, contour: bool = False) -> dict[str, Any]:
        """Plain numbers for JSON (rounded to 1e-3 px); the outline only if asked."""
        data: dict[str, Any] = {
            "color": self.color,
            "centroid_px": [round(self.centroid_px[0], 3), round(self.centroid_px[1], 3)],
            "area_px": round(self.area_px, 1),
            "yaw_deg": round(self.yaw_deg, 2),
            "rect_center_px": [round(v, 3) for v in self.rect_center_px],
            "rect_size_px": [round(v, 3) for v in self.rect_size_px],
            "box_px": [[round(float(v), 3) for v in row] for row in self.box_px],
        }
        if contour:
            data["contour_px"] = self.contour_px.tolist()
        return data


def normalize_yaw_deg(angle_deg: float) -> tuple[float, int]:
    """``angle_deg`` modulo 90 in (-45, 45], and how many quarter turns were removed."""
    yaw = 45.0 - math.fmod(45.0 - angle_deg, 90.0)
    if yaw <= -45.0:
        yaw += 90.0
    elif yaw > 45.0:
        yaw -= 90.0
    return yaw, round((angle_deg - yaw) / 90.0)


def _measure(color: str, contour: npt.NDArray[Any], scale: int = 1,
             moments: dict[str, float] | None = None) -> Detection:
    """A Detection from an outline (every point, CHAIN_APPROX_NONE) on a grid ``scale``
    times coarser than the image (``moments``: the outline's, if taken already).

    Coarse pixel i covers full pixels scale*i .. scale*i + scale - 1, whose centre is
    ``scale*i + (scale - 1)/2``. The pixels inside a lattice outline number its area
    plus half its steps plus one (Pick's theorem; a one-pixel spike walked out and back
    counts right too): the polygon area alone misses half the outline.
    """
    pts = contour.reshape(-1, 2)
    offset = (scale - 1) / 2.0
    m = cv2.moments(pts) if moments is None else moments
    if m["m00"] > 1e-9:
        cu, cv = m["m10"] / m["m00"], m["m01"] / m["m00"]
    else:  # a line or a point: no area to weigh
        cu, cv = (float(v) for v in pts.mean(axis=0))
    steps = len(pts) if len(pts) > 1 else 0
    area = (abs(m["m00"]) + steps / 2.0 + 1.0) * scale * scale
    (rcx, rcy), (rw, rh), angle = cv2.minAreaRect(pts)
    yaw, turns = normalize_yaw_deg(angle)
    if turns % 2:
        rw, rh = rh, rw
    # The rectangle through pixel centres is one (coarse) pixel short of the blob's extent.
    center = (rcx * scale + offset, rcy * scale + offset)
    size = ((rw + 1.0) * scale, (rh + 1.0) * scale)
    box = cv2.boxPoints((center, size, yaw)).astype(np.float64)
    if scale == 1:
        contour_px = np.ascontiguousarray(pts, dtype=np.int32)
    else:
        contour_px = np.rint(pts * scale + offset).astype(np.int32)
    box.flags.writeable = False
    contour_px.flags.writeable = False
    return Detection(
        color=color,
        centroid_px=(float(cu * scale + offset), float(cv * scale + offset)),
        area_px=float(area),
        rect_center_px=(float(center[0]), float(center[1])),
        rect_size_px=(float(size[0]), float(size[1])),
        yaw_deg=float(yaw),
        box_px=box,
        contour_px=contour_px,
    )


def _spans_frame(x: int, y: int, w: int, h: int, width: int, height: int) -> bool:
    return x == 0 and y == 0 and w == width and h == height


def _resolve_colors(thresholds: ColorThresholds, colors: Iterable[str] | str | None) -> list[str]:
    if not isinstance(thresholds, ColorThresholds):
        raise ConfigError(f"thresholds must be ColorThresholds, got {type(thresholds).__name__}")
    if isinstance(colors, str):
        colors = parse_color_names(colors)
    return list(thresholds.select(colors).names)


class ColorDetector:
    """Every blob of each colour in a BGR frame (see the module docstring for how).

    ``colors``: which of the thresholds' colours to look for (all by default), in the
    order detections are sorted by. ``min_area_px``/``max_area_px``: blob area bounds
    in full-resolution pixels. ``downscale``: the coarse pass's factor (1 = full
    resolution; frames smaller than 8x it are done at full resolution). ``refine``:
    measure each blob at full resolution (default); without it blobs are measured on
    the coarse grid, faster but only to about a coarse pixel.
    """

    def __init__(
        self, thresholds: ColorThresholds, colors: Iterable[str] | str | None = None, *,
        min_area_px: float = DEFAULT_MIN_AREA_PX, max_area_px: float | None = None,
        downscale: int = DEFAULT_DOWNSCALE, refine: bool = True,
    ) -> None:
        self.colors = _resolve_colors(thresholds, colors)
        self.thresholds = thresholds.select(self.colors)
        _check_area("min_area_px", min_area_px)
        if max_area_px is not None:
            _check_area("max_area_px", max_area_px)
            if max_area_px < min_area_px:
                raise ConfigError(
                    f"max_area_px {max_area_px:g} is below min_area_px {min_area_px:g}"
                )
        check_int_range("downscale", downscale, 1, 8)
        self.min_area_px = float(min_area_px)
        self.max_area_px = None if max_area_px is None else float(max_area_px)
        self.downscale = downscale
        self.refine = bool(refine)
        self._bounds = {
            name: (np.array(r.lab_min, np.uint8), np.array(r.lab_max, np.uint8))
            for name, r in self.thresholds.items()
        }
        self._tables, self._bits = _build_tables(self.thresholds)

    def __repr__(self) -> str:
        return (f"ColorDetector(colors={self.colors}, min_area_px={self.min_area_px:g}, "
                f"max_area_px={self.max_area_px!r}, downscale={self.downscale}, "
                f"refine={self.refine})")

    def detect(self, image: UInt8Image) -> list[Detection]:
        """Every blob above ``min_area_px`` (and below ``max_area_px``), per colour,
        sorted by colour then area (largest first). Nothing found is an empty list."""
        img = check_bgr_image(image)
        height, width = img.shape[:2]
        f = self.downscale if min(height, width) >= 8 * self.downscale else 1
        hs, ws = height // f, width // f
        small = img if f == 1 else np.asarray(cv2.resize(
            img[: hs * f, : ws * f], (ws, hs), interpolation=cv2.INTER_AREA
        ), dtype=np.uint8)
        labels = self._label(small)
        out: list[Detection] = []
        for name in self.colors:
            group, bit = self._bits[name]
            # No opening here: specks fail the box test below for the price of a loop
            # turn, and the full-resolution pass opens each blob's own window.
            mask = labels[group] & np.uint8(bit)
            contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            found: list[Detection] = []
            seen: set[tuple[float, float]] = set()
            for contour in contours:
                x, y, w, h = cv2.boundingRect(contour)
                # The box holds at least the blob's pixels: a cheap lower bound to skip specks.
                if w * h * f * f < self.min_area_px or _spans_frame(x, y, w, h, ws, hs):
                    continue
                if self.refine:
                    dets = self._refine(img, name, contour, (x, y, w, h), f)
                else:
                    dets = [_measure(name, contour, f)]
                for det in dets:
                    if det.area_px < self.min_area_px or (
                        self.max_area_px is not None and det.area_px > self.max_area_px
                    ):
                        continue
                    key = (round(det.centroid_px[0], 3), round(det.centroid_px[1], 3))
                    if key not in seen:  # a blob whose window overlaps another's
                        seen.add(key)
                        found.append(det)
            found.sort(key=lambda d: -d.area_px)
            out.extend(found)
        return out

    def mask(self, image: UInt8Image, color: str) -> UInt8Image:
        """The full-resolution mask (0 or 255) of one colour after the 3x3 opening."""
        img = check_bgr_image(image)
        if color not in self._bounds:
            raise ConfigError(f"colour {color!r} is not detected here; colours: "
                              f"{', '.join(self.colors)}")
        lo, hi = self._bounds[color]
        lab = cv2.cvtColor(img, cv2.COLOR_BGR2LAB)
        mask = cv2.morphologyEx(cv2.inRange(lab, lo, hi), cv2.MORPH_OPEN, _KERNEL)
        return np.asarray(mask, dtype=np.uint8)

    def matched_pixels(self, image: UInt8Image) -> dict[str, int]:
        """Per colour, how many full-resolution pixels lie in its Lab box (no opening):
        tells "nothing matched" from "only specks below the minimum area"."""
        img = check_bgr_image(image)
        lab = cv2.cvtColor(img, cv2.COLOR_BGR2LAB)
        return {name: int(cv2.countNonZero(cv2.inRange(lab, lo, hi)))
                for name, (lo, hi) in self._bounds.items()}

    def _label(self, small: UInt8Image) -> list[UInt8Image]:
        # Each pixel's BGR565 value (b >> 3 | (g >> 2) << 5 | (r >> 3) << 11) indexes the
        # tables: one C pass, where three look-ups and two sums took six.
        packed = cv2.cvtColor(np.ascontiguousarray(small), cv2.COLOR_BGR2BGR565)
        index = packed.view(np.uint16).reshape(small.shape[:2])
        # (Every 16-bit index is in the 65536-entry tables: "wrap" only skips numpy's
        # bounds check.)
        return [table.take(index, mode="wrap") for table in self._tables]

    def _refine(
        self, img: UInt8Image, name: str, coarse: npt.NDArray[Any],
        box: tuple[int, int, int, int], f: int,
    ) -> list[Detection]:
        """The full-resolution blobs inside one coarse blob's window: every outline whose
        centroid lies within a coarse pixel of the coarse outline (blocks that touch at
        the coarse scale come apart here; a neighbour reaching into the window does not
        count). A blob cut by the window's edge is looked at again in a wider window."""
        height, width = img.shape[:2]
        lo, hi = self._bounds[name]
        x, y, w, h = box
        offset = (f - 1) / 2.0
        margin = _MARGIN_SMALL_PX * f
        chosen: list[tuple[npt.NDArray[Any], dict[str, float]]] = []
        cm = cv2.moments(coarse)
        # The coarse blob's centre at full resolution: a full-resolution blob that covers
        # it is this blob too, even if its own centre lies elsewhere (two blocks meeting
        # at a corner are one blob here, centred where they meet).
        middle = ((cm["m10"] / cm["m00"]) * f + offset, (cm["m01"] / cm["m00"]) * f + offset
                  ) if cm["m00"] > 0 else None
        for _ in range(3):
            x0, y0 = max(0, x * f - margin), max(0, y * f - margin)
            x1, y1 = min(width, (x + w) * f + margin), min(height, (y + h) * f + margin)
            lab = cv2.cvtColor(img[y0:y1, x0:x1], cv2.COLOR_BGR2LAB)
            mask = cv2.morphologyEx(cv2.inRange(lab, lo, hi), cv2.MORPH_OPEN, _KERNEL)
            contours, _ = cv2.findContours(
                mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE, offset=(x0, y0)
            )
            chosen = []
            clipped = False
            for c in contours:
                bx, by, bw, bh = cv2.boundingRect(c)
                if bw * bh < self.min_area_px:
                    continue
                m = cv2.moments(c)
                if m["m00"] <= 0:
                    continue
                hint = ((m["m10"] / m["m00"] - offset) / f, (m["m01"] / m["m00"] - offset) / f)
                if cv2.pointPolygonTest(coarse, hint, True) < -1.0 and (
                        middle is None or cv2.pointPolygonTest(c, middle, False) < 0):
                    continue
                chosen.append((c, m))
                clipped = clipped or (bx <= x0 < x * f) or (by <= y0 < y * f) or (
                    bx + bw >= x1 > (x + w) * f) or (by + bh >= y1 > (y + h) * f)
            if not clipped:
                break
            margin *= 4  # the blob is larger at full resolution: look again, wider
        return [_measure(name, c, 1, m) for c, m in chosen]


def _check_area(name: str, value: object) -> None:
    """An area in pixels, 0..1e9."""
    check_range(name, value, 0.0, 1e9, "px")


def _build_tables(
    thresholds: ColorThresholds,
) -> tuple[list[UInt8Image], dict[str, tuple[int, int]]]:
    """One uint8 table per 8 colours over the 32x32x32 BGR bins: bit k set when the bin
    centre's Lab lies in colour k's box; indexed by a pixel's BGR565 value (65536
    entries: green's sixth bit, below the bin's five, does not change the bin)."""
    n = 1 << LUT_BITS
    step = 256 // n
    centres = (np.arange(n) * step + step // 2).astype(np.uint8)
    b, g, r = np.meshgrid(centres, centres, centres, indexing="ij")
    bgr = np.stack([b, g, r], axis=-1).reshape(-1, 1, 3)
    lab = cv2.cvtColor(bgr, cv2.COLOR_BGR2LAB).reshape(-1, 3)
    tables: list[UInt8Image] = []
    bits: dict[str, tuple[int, int]] = {}
    for i, (name, rng) in enumerate(thresholds.items()):
        group, bit = divmod(i, 8)
        if group == len(tables):
            tables.append(np.zeros(n**3, np.uint8))
        inside = np.all((lab >= rng.lab_min) & (lab <= rng.lab_max), axis=1)
        tables[group][inside] |= np.uint8(1 << bit)
        bits[name] = (group, 1 << bit)
    # BGR565: b >> 3 in bits 0-4, g >> 2 in bits 5-10, r >> 3 in bits 11-15.
    v = np.arange(1 << 16)
    bin_of_565 = ((v & 31) << 2 * LUT_BITS) | (((v >> 6) & 31) << LUT_BITS) | (v >> 11)
    return [np.ascontiguousarray(t[bin_of_565]) for t in tables], bits


# ---------------------------------------------------------------------- the vendor's way


def vendor_style_detect(
    image: UInt8Image, thresholds: ColorThresholds, colors: Iterable[str] | str | None = None,
    *, min_area_px: float = DEFAULT_MIN_AREA_PX,
) -> list[Detection]:
    """The vendor's pipeline, written from its description, as a baseline: 3x3
    Gaussian blur at full resolution, BGR to Lab, per colour ``inRange``, 3x3 erode
    then dilate, outer contours (every point), ``contourArea`` at least ``min_area_px``.

    Unlike the vendor it keeps every blob (not only the largest) so that it can be
    compared with :class:`ColorDetector`; detections are measured the same way.
    """
    img = check_bgr_image(image)
    names = _resolve_colors(thresholds, colors)
    _check_area("min_area_px", min_area_px)
    blurred = cv2.GaussianBlur(img, (3, 3), 3)
    lab = cv2.cvtColor(blurred, cv2.COLOR_BGR2LAB)
    height, width = img.shape[:2]
    out: list[Detection] = []
    for name in names:
        r = thresholds[name]
        mask = cv2.inRange(lab, np.array(r.lab_min, np.uint8), np.array(r.lab_max, np.uint8))
        mask = cv2.dilate(cv2.erode(mask, _KERNEL), _KERNEL)
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        found = []
        for c in contours:
            x, y, w, h = cv2.boundingRect(c)
            if cv2.contourArea(c) >= min_area_px and not _spans_frame(x, y, w, h, width, height):
                found.append(_measure(name, c))
        found.sort(key=lambda d: -d.area_px)
        out.extend(found)
    return out


__all__ = [
    "DEFAULT_MIN_AREA_PX",
    "ColorDetector",
    "Detection",
    "normalize_yaw_deg",
    "vendor_style_detect",
]
