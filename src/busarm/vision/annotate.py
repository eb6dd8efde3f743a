"""Pictures for people: detections and tags drawn on a copy of the frame, and saving.

Boxes are drawn in the detected colour (white for unknown names) with a dark outline
so they stand out on any background; text has a dark halo for the same reason.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.fileio import write_bytes_atomic
from busarm.vision.camera import UInt8Image, check_bgr_image
from busarm.vision.color import Detection
from busarm.vision.tags import TagDetection

# BGR used to draw each colour name; others are drawn white.
DRAW_BGR: dict[str, tuple[int, int, int]] = {
    "red": (40, 40, 230),
    "green": (40, 200, 40),
    "blue": (230, 120, 30),
    "yellow": (0, 220, 240),
    "white": (245, 245, 245),
    "black": (60, 60, 60),
}
TAG_BGR = (255, 0, 255)
DARK = (20, 20, 20)
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")
JPEG_QUALITY = 95
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_SHIFT = 4  # draw at 1/16 px so sub-pixel positions are not rounded away
_ONE = 1 << _SHIFT


def _fixed(points: npt.ArrayLike) -> npt.NDArray[np.int32]:
    return np.rint(np.asarray(points, np.float64) * _ONE).astype(np.int32)


def _text(image: UInt8Image, text: str, org: tuple[int, int], color: tuple[int, int, int],
          scale: float = 0.45) -> None:
    cv2.putText(image, text, org, _FONT, scale, DARK, 3, cv2.LINE_AA)
    cv2.putText(image, text, org, _FONT, scale, color, 1, cv2.LINE_AA)


def _cross(image: UInt8Image, center: tuple[float, float], color: tuple[int, int, int],
           arm_px: float = 5.0) -> None:
    u, v = center
    for (a, b), (c, d) in (((u - arm_px, v), (u + arm_px, v)), ((u, v - arm_px), (u, v + arm_px))):
        p0 = (round(a * _ONE), round(b * _ONE))
        p1 = (round(c * _ONE), round(d * _ONE))
        cv2.line(image, p0, p1, DARK, 3, cv2.LINE_AA, _SHIFT)
        cv2.line(image, p0, p1, color, 1, cv2.LINE_AA, _SHIFT)


def annotate(
    image: UInt8Image, detections: Iterable[Detection] = (),
    tags: Iterable[TagDetection] = (), text_lines: Iterable[str] = (),
) -> UInt8Image:
    """A copy of ``image`` (BGR, or grey which is made BGR) with each detection's
    oriented box, centroid and "colour yaw area" label, each tag's outline, corner 0
    and id, and ``text_lines`` at the top left."""
    if isinstance(image, np.ndarray) and image.ndim == 2 and image.dtype == np.uint8:
        out = np.asarray(cv2.cvtColor(image, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    else:
        out = check_bgr_image(image).copy()
    height, width = out.shape[:2]
    for det in detections:
        color = DRAW_BGR.get(det.color, (255, 255, 255))
        box = [_fixed(det.box_px)]
        cv2.polylines(out, box, True, DARK, 3, cv2.LINE_AA, _SHIFT)
        cv2.polylines(out, box, True, color, 1, cv2.LINE_AA, _SHIFT)
        _cross(out, det.centroid_px, color)
        label = f"{det.color} {det.yaw_deg:+.1f}deg {det.area_px:.0f}px"
        top = float(np.min(det.box_px[:, 1]))
        u = int(np.clip(det.centroid_px[0] - 4 * len(label), 2, max(2, width - 8 * len(label))))
        v = int(np.clip(top - 6, 12, height - 4))
        _text(out, label, (u, v), color)
    for tag in tags:
        quad = [_fixed(tag.corners_px)]
        cv2.polylines(out, quad, True, DARK, 3, cv2.LINE_AA, _SHIFT)
        cv2.polylines(out, quad, True, TAG_BGR, 1, cv2.LINE_AA, _SHIFT)
        c0 = tag.corners_px[0]
        cv2.circle(out, (round(c0[0] * _ONE), round(c0[1] * _ONE)), 3 * _ONE, TAG_BGR, 1,
                   cv2.LINE_AA, _SHIFT)
        _cross(out, tag.center_px, TAG_BGR)
        u = int(np.clip(tag.center_px[0] + 6, 2, max(2, width - 60)))
        v = int(np.clip(tag.center_px[1] - 6, 12, height - 4))
        _text(out, f"id {tag.tag_id}", (u, v), TAG_BGR)
    for i, line in enumerate(text_lines):
        _text(out, line, (6, 18 + 18 * i), (255, 255, 255), 0.5)
    return out


def save_image(path: str | Path, image: UInt8Image) -> None:
    """Write ``image`` (BGR or grey uint8) as PNG or JPEG (by extension), atomically.

    ConfigError for another extension, an image that cannot be encoded, or a path that
    cannot be written (a missing folder, no permission).
    """
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in IMAGE_EXTENSIONS:
        raise ConfigError(
            f"cannot save image {path}: extension {ext or '(none)'!r} is not one of "
            f"{', '.join(IMAGE_EXTENSIONS)}"
        )
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or not (
        image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)
    ):
        raise ConfigError(
            f"cannot save image {path}: need an H x W x 3 or H x W uint8 array, got shape "
            f"{getattr(image, 'shape', None)} dtype {getattr(image, 'dtype', type(image))}"
        )
    params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if ext != ".png" else []
    ok, encoded = cv2.imencode(ext, image, params)
    if not ok:
        raise ConfigError(f"cannot save image {path}: OpenCV could not encode it as {ext}")
    write_bytes_atomic(path, encoded.tobytes(), what="image")


__all__ = ["DRAW_BGR", "IMAGE_EXTENSIONS", "annotate", "save_image"]
