"""Colour blocks in Lab: thresholds (our TOML or the vendor's YAML) and a fast detector.

Lab values are OpenCV's 8-bit ones, each 0..255: ``L = L* x 255/100``,
``a = a* + 128``, ``b = b* + 128`` (so grey is a = b = 128; red has a high a, blue a
low b). A colour is a box ``lab_min..lab_max`` (inclusive), as in the vendor's
``lab_config.yaml``.

:class:`ColorDetector` finds every blob of each colour in two passes:

1. **Coarse, at reduced resolution** (``downscale``, default 2: 640x480 -> 320x240 by
   ``INTER_AREA``, which also averages the noise away as the vendor's blur does). Each
   pixel's colour is one table look-up: a 32x32x32 BGR table, built once from the Lab
   boxes with ``cv2.cvtColor`` on the bin centres, holds one bit per colour (so
   overlapping boxes both match). Per colour: that bit's outer contours; specks whose
   bounding box is below the minimum area are dropped right there.
2. **Refined at full resolution**, only inside each coarse blob's bounding box (grown
   by two coarse pixels): exact Lab of those pixels, the colour's box, a 3x3 opening,
   outer contours; centroid, area and the oriented rectangle come from them. The
   table's quantisation therefore only decides whether a blob is looked at, never
   where it is, and blocks merged at the coarse scale come apart again.

On 640x480 frames with 3-6 blocks this runs about 2.5-3x the vendor's pipeline
(:func:`vendor_style_detect`, kept as the baseline) on one core, finds the same blocks,
and its centroids are within about 0.1 px of the vendor's (0.5 px at worst, on
edges aligned with the pixel grid where noise decides); ``busarm.bench_vision``
measures both.

Detections are sorted by colour (the detector's colour order), then by area, largest
first. Blobs spanning the whole frame edge to edge are not blocks (a covered lens, a
uniform or saturated frame, a background that matches) and are left out.
"""

from __future__ import annotations

import math
import re
import sys
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.units import check_int_range, check_range
from busarm.vision.camera import UInt8Image, check_bgr_image

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int32]
Lab = tuple[int, int, int]

FORMAT_NAME = "busarm.colors"
FORMAT_VERSION = 1
VENDOR_SECTIONS = ("Mono", "Stereo")
DEFAULT_SECTION = "Mono"
DEFAULT_MIN_AREA_PX = 200.0
DEFAULT_DOWNSCALE = 2
LUT_BITS = 5
"""Bits per BGR channel of the coarse colour table: 32 bins of 8 levels each."""
CHANNELS = ("L", "a", "b")
NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
_KERNEL = np.ones((3, 3), np.uint8)
_MARGIN_SMALL_PX = 2
"""Refinement window: the coarse box grown by this many coarse pixels on each side."""


# ---------------------------------------------------------------------- thresholds


def _check_lab(value: object, where: str) -> Lab:
    if isinstance(value, str | bytes) or not isinstance(value, Sequence) or len(value) != 3:
        raise ConfigError(f"{where} must be 3 integers [L, a, b] each 0..255, got {value!r}")
    out = [check_int_range(f"{where} {c}", v, 0, 255) for c, v in zip(CHANNELS, value, strict=True)]
    return out[0], out[1], out[2]


@dataclass(frozen=True)
class ColorRange:
    """One colour: a box in OpenCV 8-bit Lab, ``lab_min..lab_max`` inclusive."""

    name: str
    lab_min: Lab
    lab_max: Lab

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not NAME_RE.match(self.name):
            raise ConfigError(
                f"colour name {self.name!r} must be a letter then letters, digits, '_' or '-'"
            )
        lo = _check_lab(self.lab_min, f"colour {self.name} lab_min")
        hi = _check_lab(self.lab_max, f"colour {self.name} lab_max")
        object.__setattr__(self, "lab_min", lo)
        object.__setattr__(self, "lab_max", hi)
        for channel, a, b in zip(CHANNELS, lo, hi, strict=True):
            if a > b:
                raise ConfigError(
                    f"colour {self.name}: lab_min {channel} = {a} is above lab_max "
                    f"{channel} = {b} (lab_min {list(lo)}, lab_max {list(hi)})"
                )

    def contains(self, lab: Sequence[int]) -> bool:
        """Whether one Lab value lies in the box."""
        return all(a <= v <= b for a, v, b in zip(self.lab_min, lab, self.lab_max, strict=True))


class ColorThresholds(Mapping[str, ColorRange]):
    """Colours by name, in order, and the image size they were tuned at (if known).

    ``image_size_px`` is ``(width, height)``; ``source`` names the file they came from.
    """

    def __init__(
        self, colors: Iterable[ColorRange] | Mapping[str, ColorRange], *,
        image_size_px: tuple[int, int] | None = None, source: str = "<memory>",
    ) -> None:
        ranges = list(colors.values()) if isinstance(colors, Mapping) else list(colors)
        self._colors: dict[str, ColorRange] = {}
        for r in ranges:
            if not isinstance(r, ColorRange):
                raise ConfigError(f"thresholds {source}: {r!r} is not a ColorRange")
            if r.name in self._colors:
                raise ConfigError(f"thresholds {source}: colour {r.name} is given twice")
            self._colors[r.name] = r
        if not self._colors:
            raise ConfigError(f"thresholds {source}: no colour defined")
        if image_size_px is not None:
            w, h = image_size_px
            for what, v in (("width", w), ("height", h)):
                if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 100_000:
                    raise ConfigError(
                        f"thresholds {source}: image {what} {v!r} is out of range 1..100000 px"
                    )
            image_size_px = (int(w), int(h))
        self.image_size_px = image_size_px
        self.source = source

    def __getitem__(self, name: str) -> ColorRange:
        try:
            return self._colors[name]
        except KeyError:
            raise ConfigError(
                f"thresholds {self.source}: no colour {name!r}; colours: {', '.join(self._colors)}"
            ) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self._colors)

    def __len__(self) -> int:
        return len(self._colors)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, ColorThresholds):
            return NotImplemented
        return (list(self._colors.items()) == list(other._colors.items())
                and self.image_size_px == other.image_size_px)

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return (f"ColorThresholds({list(self._colors.values())!r}, "
                f"image_size_px={self.image_size_px!r}, source={self.source!r})")

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self._colors)

    def select(self, names: Iterable[str] | None) -> ColorThresholds:
        """Only ``names`` (in that order; all for None); ConfigError for an unknown one."""
        if names is None:
            return self
        wanted = list(dict.fromkeys(names))
        if not wanted:
            raise ConfigError(f"thresholds {self.source}: no colour asked for")
        return ColorThresholds(
            [self[n] for n in wanted], image_size_px=self.image_size_px, source=self.source
        )


def parse_color_names(text: str) -> list[str]:
    """Colour names from ``"red,green"`` (order kept, duplicates dropped)."""
    names = list(dict.fromkeys(p.strip() for p in text.split(",") if p.strip()))
    if not names:
        raise ConfigError(f"colours {text!r}: no colour name given")
    return names


# ---------------------------------------------------------------------- loading, saving


def default_thresholds() -> ColorThresholds:
    """The shipped thresholds (``busarm/vision/configs/colors.toml``): matte red, green,
    blue and yellow blocks on a light grey table under white light."""
    text = (resources.files("busarm.vision") / "configs" / "colors.toml").read_text(
        encoding="utf-8"
    )
    return thresholds_from_toml(text, "colors.toml (shipped)")


def load_thresholds(path: str | Path, *, section: str = DEFAULT_SECTION) -> ColorThresholds:
    """Thresholds from our TOML (``.toml``) or the vendor's ``lab_config.yaml``
    (``.yaml``/``.yml``, its ``section``: ``Mono`` or ``Stereo``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".toml", ".yaml", ".yml"):
        raise ConfigError(
            f"thresholds {path}: unknown kind {suffix or '(no extension)'!r}; "
            "use .toml (busarm) or .yaml/.yml (the vendor's lab_config.yaml)"
        )
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"thresholds {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"thresholds {path}: cannot read it: {exc}") from None
    if suffix == ".toml":
        return thresholds_from_toml(text, str(path))
    return thresholds_from_vendor_yaml(text, str(path), section=section)


def thresholds_from_toml(text: str, source: str = "<string>") -> ColorThresholds:
    """Parse our format::

        format = "busarm.colors"
        version = 1
        [image]              # optional: the size they were tuned at
        width_px = 640
        height_px = 480
        [colors.red]
        lab_min = [20, 150, 135]
        lab_max = [255, 255, 255]
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"thresholds {source}: not valid TOML: {exc}") from None

    def fail(key: str, message: str) -> ConfigError:
        return ConfigError(f"thresholds {source}: {key}: {message}")

    extra = sorted(set(data) - {"format", "version", "image", "colors"})
    if extra:
        raise fail("top level", f"unknown key(s) {extra}; known: format, version, image, colors")
    if data.get("format") != FORMAT_NAME:
        raise fail("format", f"must be {FORMAT_NAME!r}, got {data.get('format')!r}")
    if data.get("version") != FORMAT_VERSION:
        raise fail("version", f"{data.get('version')!r}; this busarm reads version "
                              f"{FORMAT_VERSION}")
    size: tuple[int, int] | None = None
    if "image" in data:
        image = data["image"]
        if not isinstance(image, dict) or set(image) != {"width_px", "height_px"}:
            raise fail("image", "must be a table with exactly width_px and height_px")
        size = (_int_in(image["width_px"], fail, "image.width_px", 1, 100_000),
                _int_in(image["height_px"], fail, "image.height_px", 1, 100_000))
    colors = data.get("colors")
    if not isinstance(colors, dict) or not colors:
        raise fail("colors", "missing: need at least one [colors.NAME] table")
    ranges = []
    for name, entry in colors.items():
        where = f"colors.{name}"
        if not isinstance(entry, dict):
            raise fail(where, "must be a table with lab_min and lab_max")
        unknown = sorted(set(entry) - {"lab_min", "lab_max"})
        if unknown:
            raise fail(where, f"unknown key(s) {unknown}; known: lab_min, lab_max")
        for key in ("lab_min", "lab_max"):
            if key not in entry:
                raise fail(f"{where}.{key}", "missing (3 integers [L, a, b], each 0..255)")
        ranges.append(_range(name, entry["lab_min"], entry["lab_max"], fail, where))
    return ColorThresholds(ranges, image_size_px=size, source=source)


def thresholds_from_vendor_yaml(
    text: str, source: str = "<string>", *, section: str = DEFAULT_SECTION
) -> ColorThresholds:
    """Parse the vendor's ``lab_config.yaml``:
    ``lab: {Mono: {red: {min: [L, a, b], max: [L, a, b]}}}``, ``size: {width: [640],
    height: [480]}``; one ``section`` (``Mono`` or ``Stereo``, the camera kind)."""
    import yaml  # only the vendor's format needs it

    def fail(key: str, message: str) -> ConfigError:
        return ConfigError(f"vendor thresholds {source}: {key}: {message}")

    if section not in VENDOR_SECTIONS:
        raise ConfigError(
            f"vendor thresholds section {section!r} is not one of {', '.join(VENDOR_SECTIONS)}"
        )
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        # One line: the problem and where (PyYAML's own text spans several lines).
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise ConfigError(
            f"vendor thresholds {source}: not valid YAML: {problem}{where}"
        ) from None
    if not isinstance(data, dict):
        raise fail("top level", "must be a mapping with a 'lab' key")
    lab = data.get("lab")
    if not isinstance(lab, dict):
        raise fail("lab", "missing (lab: {Mono: {red: {min: [L, a, b], max: [...]}}})")
    colors = lab.get(section)
    if not isinstance(colors, dict) or not colors:
        sections = ", ".join(str(k) for k in lab) or "none"
        raise fail(f"lab.{section}", f"missing or empty (sections: {sections})")
    ranges = []
    for name, entry in colors.items():
        where = f"lab.{section}.{name}"
        if not isinstance(entry, dict):
            raise fail(where, "must be a mapping with min and max")
        for key in ("min", "max"):
            if key not in entry:
                raise fail(f"{where}.{key}", "missing (3 integers [L, a, b], each 0..255)")
        ranges.append(_range(str(name), entry["min"], entry["max"], fail, where))
    size: tuple[int, int] | None = None
    if "size" in data:
        raw = data["size"]
        if not isinstance(raw, dict) or "width" not in raw or "height" not in raw:
            raise fail("size", "must be a mapping with width and height")
        size = (_vendor_int(raw["width"], fail, "size.width"),
                _vendor_int(raw["height"], fail, "size.height"))
    return ColorThresholds(ranges, image_size_px=size, source=source)


def _range(name: str, lo: object, hi: object, fail: Any, where: str) -> ColorRange:
    try:
        return ColorRange(name, lo, hi)  # type: ignore[arg-type]
    except ConfigError as exc:
        raise fail(where, str(exc)) from None


def _int_in(value: object, fail: Any, key: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise fail(key, f"{value!r} is not an integer in {lo}..{hi}")
    return value


def _vendor_int(value: object, fail: Any, key: str) -> int:
    # The vendor writes sizes as one-element lists: width: [640].
    if isinstance(value, list) and len(value) == 1:
        value = value[0]
    return _int_in(value, fail, key, 1, 100_000)


def thresholds_to_toml(thresholds: ColorThresholds) -> str:
    """Our TOML text for ``thresholds`` (what :func:`save_thresholds` writes)."""
    lines = [
        "# busarm colour thresholds: boxes in OpenCV 8-bit Lab, each channel 0..255",
        "# (L = L* x 255/100, a = a* + 128, b = b* + 128; grey is a = b = 128).",
        f'format = "{FORMAT_NAME}"',
        f"version = {FORMAT_VERSION}",
    ]
    if thresholds.image_size_px is not None:
        w, h = thresholds.image_size_px
        lines += ["", "[image]", f"width_px = {w}", f"height_px = {h}"]
    for r in thresholds.values():
        lines += [
            "", f"[colors.{r.name}]",
            f"lab_min = [{', '.join(map(str, r.lab_min))}]",
            f"lab_max = [{', '.join(map(str, r.lab_max))}]",
        ]
    return "\n".join(lines) + "\n"


def save_thresholds(path: str | Path, thresholds: ColorThresholds) -> None:
    """Write ``thresholds`` as our TOML, atomically."""
    write_text_atomic(path, thresholds_to_toml(thresholds), what="thresholds")


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


def _measure(color: str, contour: npt.NDArray[Any], scale: int = 1) -> Detection:
    """A Detection from an outline (every point, CHAIN_APPROX_NONE) on a grid ``scale``
    times coarser than the image.

    Coarse pixel i covers full pixels scale*i .. scale*i + scale - 1, whose centre is
    ``scale*i + (scale - 1)/2``. The pixels inside a lattice outline number its area
    plus half its steps plus one (Pick's theorem; a one-pixel spike walked out and back
    counts right too): the polygon area alone misses half the outline.
    """
    pts = contour.reshape(-1, 2)
    offset = (scale - 1) / 2.0
    m = cv2.moments(pts)
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
        self._channel_luts = _channel_luts()

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
        # Bin index (b >> 3) << 10 | (g >> 3) << 5 | r >> 3 from three 256-entry tables.
        b, g, r = cv2.split(small)
        lb, lg, lr = self._channel_luts
        index = np.asarray(
            cv2.add(cv2.add(cv2.LUT(b, lb), cv2.LUT(g, lg)), cv2.LUT(r, lr)), dtype=np.uint16
        )
        return [np.take(table, index) for table in self._tables]

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
        chosen: list[npt.NDArray[Any]] = []
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
                chosen.append(c)
                clipped = clipped or (bx <= x0 < x * f) or (by <= y0 < y * f) or (
                    bx + bw >= x1 > (x + w) * f) or (by + bh >= y1 > (y + h) * f)
            if not clipped:
                break
            margin *= 4  # the blob is larger at full resolution: look again, wider
        return [_measure(name, c, 1) for c in chosen]


def _check_area(name: str, value: object) -> None:
    """An area in pixels, 0..1e9."""
    check_range(name, value, 0.0, 1e9, "px")


def _channel_luts() -> tuple[npt.NDArray[np.uint16], ...]:
    level = (np.arange(256) >> (8 - LUT_BITS)).reshape(1, 256)
    return tuple(
        np.ascontiguousarray(level << shift, dtype=np.uint16)
        for shift in (2 * LUT_BITS, LUT_BITS, 0)
    )


def _build_tables(
    thresholds: ColorThresholds,
) -> tuple[list[UInt8Image], dict[str, tuple[int, int]]]:
    """One uint8 table per 8 colours over the 32x32x32 BGR bins: bit k set when the bin
    centre's Lab lies in colour k's box."""
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
    return tables, bits


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
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "ColorDetector",
    "ColorRange",
    "ColorThresholds",
    "Detection",
    "default_thresholds",
    "load_thresholds",
    "normalize_yaw_deg",
    "parse_color_names",
    "save_thresholds",
    "thresholds_from_toml",
    "thresholds_from_vendor_yaml",
    "thresholds_to_toml",
    "vendor_style_detect",
]
