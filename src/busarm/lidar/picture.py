"""A polar picture of one scan, drawn with OpenCV: the Lidar at the centre, forward up,
left to the left (counter-clockwise bearings), range rings in metres."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.fileio import write_bytes_atomic
from busarm.lidar.scan import LaserScan

__all__ = [
    "SIZE_PX",
    "Image",
    "render_scan",
    "write_scan_png",
]


SIZE_PX = 640
_MARGIN_PX = 50
_CAPTION_PX = 46
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_GRID = (200, 200, 200)
_TEXT = (40, 40, 40)
_POINT = (30, 30, 200)  # BGR: red
_NEAREST = (0, 140, 255)

Image = npt.NDArray[np.uint8]


def _ring_step_m(span_m: float) -> float:
    for step in (0.25, 0.5, 1.0, 2.0, 5.0):
        if span_m / step <= 6:
            return step
    return 5.0


def render_scan(scan: LaserScan, title: str) -> Image:
    """The picture as a BGR image (SIZE_PX wide, a caption strip above)."""
    image = np.full((SIZE_PX + _CAPTION_PX, SIZE_PX, 3), 255, dtype=np.uint8)
    valid = scan.valid
    far = float(np.nanmax(scan.ranges_m)) if valid.any() else 1.0
    step = _ring_step_m(far)
    span_m = max(step, math.ceil(far / step) * step)
    cx, cy = SIZE_PX // 2, _CAPTION_PX + SIZE_PX // 2
    px_per_m = (SIZE_PX / 2 - _MARGIN_PX) / span_m

    def at(range_m: float, bearing: float) -> tuple[int, int]:
        # Forward (bearing 0) is up; counter-clockwise bearings turn to the left.
        return (round(cx - px_per_m * range_m * math.sin(bearing)),
                round(cy - px_per_m * range_m * math.cos(bearing)))

    ring = step
    while ring <= span_m + 1e-9:
        cv2.circle(image, (cx, cy), round(ring * px_per_m), _GRID, 1, cv2.LINE_AA)
        cv2.putText(image, f"{ring:g} m", (cx + 3, round(cy - ring * px_per_m) - 3), _FONT,
                    0.4, _TEXT, 1, cv2.LINE_AA)
        ring += step
    for deg in range(0, 360, 30):
        cv2.line(image, (cx, cy), at(span_m, math.radians(deg)), _GRID, 1, cv2.LINE_AA)
        lx, ly = at(span_m + 18 / px_per_m, math.radians(deg))
        label = f"{deg if deg <= 180 else deg - 360}"
        cv2.putText(image, label, (lx - 12, ly + 4), _FONT, 0.4, _TEXT, 1, cv2.LINE_AA)
    for range_m, bearing in zip(scan.ranges_m[valid], scan.angles_rad[valid], strict=True):
        cv2.circle(image, at(float(range_m), float(bearing)), 2, _POINT, -1, cv2.LINE_AA)
    nearest = scan.nearest()
    if nearest is not None:
        cv2.circle(image, at(*nearest), 7, _NEAREST, 2, cv2.LINE_AA)
    cv2.drawMarker(image, (cx, cy), (0, 0, 0), cv2.MARKER_TRIANGLE_UP, 12, 2)
    cv2.putText(image, title, (8, 18), _FONT, 0.5, _TEXT, 1, cv2.LINE_AA)
    cv2.putText(image, "bearings in deg, counter-clockwise; forward up; orange: nearest",
                (8, 38), _FONT, 0.4, _TEXT, 1, cv2.LINE_AA)
    return image


def write_scan_png(scan: LaserScan, path: Path | str, title: str) -> None:
    """Write the polar picture to ``path`` (PNG) atomically."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ConfigError(f"cannot write scan picture {path}: extension "
                          f"{path.suffix or '(none)'!r} is not .png")
    ok, encoded = cv2.imencode(".png", render_scan(scan, title))
    if not ok:
        raise ConfigError(f"cannot encode scan picture {path} as PNG")
    write_bytes_atomic(path, encoded.tobytes(), "scan picture")
