"""Occupancy grids as ROS map_server files: a PGM picture and a YAML description.

The format every ROS navigation tool reads (map_server, nav2_map_server, RViz via them):
the YAML names the image, ``resolution`` (m a pixel), ``origin`` ([x, y, yaw] of the
lower-left pixel), ``negate`` (0), ``occupied_thresh`` and ``free_thresh`` (of the
probability read from a pixel: p = (255 - value) / 255) and ``mode`` (``trinary``). The
PGM (binary P5, 8 bit) has its first row at the top: the highest y. Written here as
map_saver writes them: 0 occupied, 254 free, 205 unknown. Both files are written
atomically; a file that is not such a map is one error naming what is wrong.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.fileio import atomic_path, write_text_atomic
from busarm.nav.grid import CLAMP_LOG_ODDS, GridSpec, OccupancyGrid

__all__ = [
    "FREE_THRESH",
    "OCCUPIED_THRESH",
    "grid_pixels",
    "load_map",
    "read_pgm",
    "save_map",
    "trinary_cells",
]


OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196
PIXEL_OCCUPIED, PIXEL_FREE, PIXEL_UNKNOWN = 0, 254, 205


def grid_pixels(grid: OccupancyGrid) -> npt.NDArray[np.uint8]:
    """The map's picture as map_saver draws it (first row: the highest y)."""
    p = grid.probability
    out = np.full(p.shape, PIXEL_UNKNOWN, dtype=np.uint8)
    out[p >= OCCUPIED_THRESH] = PIXEL_OCCUPIED
    out[p <= FREE_THRESH] = PIXEL_FREE
    return np.ascontiguousarray(out[::-1])


def trinary_cells(grid: OccupancyGrid) -> npt.NDArray[np.int8]:
    """Each cell as map_server publishes it: 100 occupied, 0 free, -1 unknown (by the map
    file's thresholds); rows as the grid's, the first one at the origin."""
    p = grid.probability
    out = np.full(p.shape, -1, dtype=np.int8)
    out[p >= OCCUPIED_THRESH] = 100
    out[p <= FREE_THRESH] = 0
    return out


def save_map(yaml_path: str | Path, grid: OccupancyGrid) -> Path:
    """Write ``NAME.yaml`` and ``NAME.pgm`` beside it; returns the PGM's path."""
    yaml_path = Path(yaml_path)
    if yaml_path.suffix.lower() not in (".yaml", ".yml"):
        raise ConfigError(f"map file {yaml_path}: name it NAME.yaml (its picture is NAME.pgm)")
    pgm_path = yaml_path.with_suffix(".pgm")
    pixels = grid_pixels(grid)
    h, w = pixels.shape
    with atomic_path(pgm_path, "map picture") as tmp:
        tmp.write_bytes(f"P5\n# busarm map\n{w} {h}\n255\n".encode("ascii") + pixels.tobytes())
    s = grid.spec
    # Plain floats: a numpy scalar's repr (a cropped grid's origin) is np.float64(...).
    write_text_atomic(yaml_path, (
        f"image: {pgm_path.name}\n"
        f"mode: trinary\n"
        f"resolution: {float(s.resolution_m)!r}\n"
        f"origin: [{float(s.origin_x_m)!r}, {float(s.origin_y_m)!r}, 0.0]\n"
        f"negate: 0\n"
        f"occupied_thresh: {OCCUPIED_THRESH}\n"
        f"free_thresh: {FREE_THRESH}\n"), "map file")
    return pgm_path


def _fail(path: Path, what: str) -> ConfigError:
    return ConfigError(f"map file {path}: {what}")


def _number(path: Path, data: dict[str, Any], key: str, lo: float, hi: float) -> float:
    value = data.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            math.isfinite(value) and lo <= value <= hi):
        raise _fail(path, f"{key} = {value!r}; allowed: a number {lo:g}..{hi:g}")
    return float(value)


def read_pgm(path: Path) -> npt.NDArray[np.uint8]:
    """An 8-bit binary PGM (P5) as rows of pixels."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise _fail(path, f"cannot read it: {exc}") from None
    fields: list[bytes] = []
    i = 0
    while len(fields) < 4:
        while i < len(raw) and raw[i:i + 1].isspace():
            i += 1
        if raw[i:i + 1] == b"#":
            i = raw.find(b"\n", i) + 1 if raw.find(b"\n", i) >= 0 else len(raw)
            continue
        j = i
        while j < len(raw) and not raw[j:j + 1].isspace():
            j += 1
        if j == i:
            raise _fail(path, "not a binary PGM (P5) picture: its header ends early")
        fields.append(raw[i:j])
        i = j
    magic, width, height, maxval = fields
    if magic != b"P5" or not (width.isdigit() and height.isdigit()) or maxval != b"255":
        raise _fail(path, f"not an 8-bit binary PGM (P5, maxval 255): header {b' '.join(fields)!r}")
    w, h = int(width), int(height)
    body = raw[i + 1:]
    if not (0 < w * h <= 4000 * 4000) or len(body) < w * h:
        raise _fail(path, f"{w} x {h} pixels, but {len(body)} bytes of them")
    return np.frombuffer(body[:w * h], dtype=np.uint8).reshape(h, w)


def load_map(yaml_path: str | Path) -> OccupancyGrid:
    """A map_server map (YAML + its picture) as an occupancy grid (occupied, free and
    unknown cells at the clamped log-odds, 0 for unknown)."""
    import yaml

    path = Path(yaml_path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise _fail(path, f"cannot read it: {exc}") from None
    except yaml.YAMLError as exc:
        raise _fail(path, f"not valid YAML: {exc}") from None
    if not isinstance(data, dict) or not isinstance(data.get("image"), str):
        raise _fail(path, "not a map_server map (needs image:, resolution:, origin:)")
    resolution = _number(path, data, "resolution", 0.005, 1.0)
    origin = data.get("origin")
    if not (isinstance(origin, list) and len(origin) == 3 and all(
            isinstance(v, int | float) and math.isfinite(v) for v in origin)):
        raise _fail(path, f"origin = {origin!r}; allowed: [x, y, yaw] in m and rad")
    if origin[2] != 0:
        raise _fail(path, f"origin yaw {origin[2]!r}: only maps with yaw 0 are read")
    occupied = _number(path, data, "occupied_thresh", 0.0, 1.0)
    free = _number(path, data, "free_thresh", 0.0, 1.0)
    if data.get("negate", 0) not in (0, 1):
        raise _fail(path, f"negate = {data.get('negate')!r}; allowed: 0 or 1")
    pixels = read_pgm(path.parent / data["image"])
    p = pixels.astype(np.float64) / 255.0 if data.get("negate", 0) else (
        255.0 - pixels.astype(np.float64)) / 255.0
    log_odds = np.zeros(p.shape)
    log_odds[p > occupied] = CLAMP_LOG_ODDS
    log_odds[p < free] = -CLAMP_LOG_ODDS
    h, w = pixels.shape
    spec = GridSpec(float(origin[0]), float(origin[1]), resolution, w, h)
    return OccupancyGrid(spec, log_odds[::-1].copy())
