"""Pictures for people: detections and tags drawn on a copy of the frame, and saving.

Boxes are drawn in the detected colour (white for unknown names) with a dark outline
so they stand out on any background. Labels are white text on a dark box (``LABEL_BG``)
with a swatch of the item's colour, so red text never sits on a red block; they are
placed by :func:`place_labels` so that no two overlap (a label pushed away from its item
gets a thin leader line to it).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
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
LABEL_BG = (48, 40, 36)
"""The box behind every label (BGR): dark, and drawn nowhere else."""
LABEL_FG = (255, 255, 255)
LABEL_SCALE = 0.42
LABEL_PAD_PX = 3
LABEL_GAP_PX = 2
"""Labels are kept at least this far apart, so each one reads as its own box."""
Rect = tuple[int, int, int, int]
"""x0, y0, x1, y1 in pixels (x1 and y1 excluded)."""
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg")
JPEG_QUALITY = 95
_FONT = cv2.FONT_HERSHEY_SIMPLEX
_SHIFT = 4  # draw at 1/16 px so sub-pixel positions are not rounded away
_ONE = 1 << _SHIFT


def _fixed(points: npt.ArrayLike) -> npt.NDArray[np.int32]:
    return np.rint(np.asarray(points, np.float64) * _ONE).astype(np.int32)


def label_size(text: str, scale: float = LABEL_SCALE, swatch: bool = True) -> tuple[int, int]:
    """The (width, height) in pixels of ``text``'s label box: the text, its padding and
    (``swatch``) the colour swatch before it."""
    (w, h), baseline = cv2.getTextSize(text, _FONT, scale, 1)
    inner = h + baseline
    return w + (inner + LABEL_PAD_PX if swatch else 0) + 2 * LABEL_PAD_PX, inner + 2 * LABEL_PAD_PX


def _overlap(a: Rect, b: Rect, gap: int = 0) -> bool:
    return (a[0] < b[2] + gap and b[0] < a[2] + gap and a[1] < b[3] + gap
            and b[1] < a[3] + gap)


def place_labels(items: Sequence[tuple[tuple[float, float, float, float], tuple[int, int]]],
                 image_size: tuple[int, int], taken: Sequence[Rect] = ()) -> list[Rect]:
    """Where to draw each label: ``items`` are (the item's bounds x0, y0, x1, y1; the
    label's width, height), ``image_size`` (width, height).

    A label goes centred just above its item, else just below, else stacked farther up
    or down in label-height steps: the nearest spot inside the picture that overlaps no
    label placed before (nor ``taken``), and if it can, no other item. Only when the
    picture is full does a label overlap another.
    """
    width, height = image_size
    placed: list[Rect] = list(taken)
    bounds: list[Rect] = [(round(b[0]), round(b[1]), round(b[2]), round(b[3])) for b, _ in items]
    out: list[Rect] = []
    for index, ((bx0, by0, bx1, by1), (w, h)) in enumerate(items):
        x0 = int(np.clip(round((bx0 + bx1) / 2 - w / 2), 0, max(0, width - w)))
        above, below = round(by0) - 3 - h, round(by1) + 3
        step = h + LABEL_GAP_PX
        ys = sorted({int(np.clip(y, 0, max(0, height - h)))
                     for k in range(height // step + 2)
                     for y in (above - k * step, below + k * step)},
                    key=lambda y: (min(abs(y - above), abs(y - below) + 1)))
        others = [b for i, b in enumerate(bounds) if i != index]
        spots = [(x0, y, x0 + w, y + h) for y in ys]
        free = [r for r in spots if not any(_overlap(r, p, LABEL_GAP_PX) for p in placed)]
        clear = [r for r in free if not any(_overlap(r, o) for o in others)]
        rect = (clear or free or spots)[0]
        placed.append(rect)
        out.append(rect)
    return out


def draw_label(image: UInt8Image, text: str, rect: Rect,
               color: tuple[int, int, int] | None = None, scale: float = LABEL_SCALE) -> None:
    """White ``text`` on a dark box at ``rect`` (sized by :func:`label_size`), after a
    swatch of ``color`` if one is given."""
    x0, y0, x1, y1 = rect
    cv2.rectangle(image, (x0, y0), (x1 - 1, y1 - 1), LABEL_BG, cv2.FILLED)
    left = x0 + LABEL_PAD_PX
    if color is not None:
        side = y1 - y0 - 2 * LABEL_PAD_PX
        cv2.rectangle(image, (left, y0 + LABEL_PAD_PX), (left + side - 1, y1 - LABEL_PAD_PX - 1),
                      color, cv2.FILLED)
        left += side + LABEL_PAD_PX
    _, baseline = cv2.getTextSize(text, _FONT, scale, 1)
    cv2.putText(image, text, (left, y1 - LABEL_PAD_PX - baseline), _FONT, scale, LABEL_FG, 1,
                cv2.LINE_AA)


def draw_leader(image: UInt8Image, rect: Rect, bounds: tuple[float, float, float, float],
            color: tuple[int, int, int]) -> None:
    """A thin line from a label that was pushed away to its item."""
    x0, y0, x1, y1 = rect
    bx0, by0, bx1, by1 = (round(v) for v in bounds)
    if y1 <= by0 - 6:
        start, end = ((x0 + x1) // 2, y1), ((bx0 + bx1) // 2, by0)
    elif y0 >= by1 + 6:
        start, end = ((x0 + x1) // 2, y0), ((bx0 + bx1) // 2, by1)
    else:
        return  # next to its item (or over it): no line needed
    cv2.line(image, start, end, DARK, 3, cv2.LINE_AA)
    cv2.line(image, start, end, color, 1, cv2.LINE_AA)


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
    # (text, item bounds, colour) of every label, in drawing order.
    labels: list[tuple[str, tuple[float, float, float, float], tuple[int, int, int]]] = []
    for det in detections:
        color = DRAW_BGR.get(det.color, (255, 255, 255))
        box = [_fixed(det.box_px)]
        cv2.polylines(out, box, True, DARK, 3, cv2.LINE_AA, _SHIFT)
        cv2.polylines(out, box, True, color, 1, cv2.LINE_AA, _SHIFT)
        _cross(out, det.centroid_px, color)
        (u0, v0), (u1, v1) = det.box_px.min(axis=0), det.box_px.max(axis=0)
        labels.append((f"{det.color} {det.yaw_deg:+.1f}deg {det.area_px:.0f}px",
                       (float(u0), float(v0), float(u1), float(v1)), color))
    for tag in tags:
        quad = [_fixed(tag.corners_px)]
        cv2.polylines(out, quad, True, DARK, 3, cv2.LINE_AA, _SHIFT)
        cv2.polylines(out, quad, True, TAG_BGR, 1, cv2.LINE_AA, _SHIFT)
        c0 = tag.corners_px[0]
        cv2.circle(out, (round(c0[0] * _ONE), round(c0[1] * _ONE)), 3 * _ONE, TAG_BGR, 1,
                   cv2.LINE_AA, _SHIFT)
        _cross(out, tag.center_px, TAG_BGR)
        (u0, v0), (u1, v1) = tag.corners_px.min(axis=0), tag.corners_px.max(axis=0)
        labels.append((f"id {tag.tag_id}", (float(u0), float(v0), float(u1), float(v1)),
                       TAG_BGR))
    header: list[Rect] = []
    y = 2
    for line in text_lines:  # the caption lines, top left, stacked
        w, h = label_size(line, swatch=False)
        header.append((2, y, 2 + w, y + h))
        draw_label(out, line, header[-1])
        y += h + LABEL_GAP_PX
    rects = place_labels([(b, label_size(t)) for t, b, _ in labels], (width, height), header)
    for (_, bounds, color), rect in zip(labels, rects, strict=True):
        draw_leader(out, rect, bounds, color)
    for (text, _, color), rect in zip(labels, rects, strict=True):
        draw_label(out, text, rect, color)
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


__all__ = ["DRAW_BGR", "IMAGE_EXTENSIONS", "LABEL_BG", "annotate", "draw_label", "draw_leader",
           "label_size", "place_labels", "save_image"]
