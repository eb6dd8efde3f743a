"""Colour thresholds: boxes in Lab, read from our TOML or the vendor's YAML, written as
our TOML.

Lab values are OpenCV's 8-bit ones, each 0..255: ``L = L* x 255/100``,
``a = a* + 128``, ``b = b* + 128`` (so grey is a = b = 128; red has a high a, blue a
low b). A colour is a box ``lab_min..lab_max`` (inclusive), as in the vendor's
``lab_config.yaml``. The detector that uses them is ``busarm.vision.color``.
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.units import check_int_range

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

Lab = tuple[int, int, int]

FORMAT_NAME = "busarm.colors"
FORMAT_VERSION = 1
VENDOR_SECTIONS = ("Mono", "Stereo")
DEFAULT_SECTION = "Mono"
CHANNELS = ("L", "a", "b")
NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")


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


__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "ColorRange",
    "ColorThresholds",
    "default_thresholds",
    "load_thresholds",
    "parse_color_names",
    "save_thresholds",
    "thresholds_from_toml",
    "thresholds_from_vendor_yaml",
    "thresholds_to_toml",
]
