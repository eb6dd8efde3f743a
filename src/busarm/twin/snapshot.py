"""Pictures of the twin for people: the overview with the arm's base frame (origin, x and
y axes, ticks every ``TICK_MM``) and each bin marked in its colour, and the snapshot (arm
camera beside the overview) with a caption saying what it shows.

The marks are drawn on the rendered picture; the scene itself is not changed, so the
wrist camera (and the colour detector looking through it) keeps seeing grey trays. The
overview camera sees the whole room; the marked overview is cropped to the table and
enlarged, so the marks have room.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from busarm.twin.twin import Twin
from busarm.vision.annotate import (
    DARK,
    DRAW_BGR,
    LABEL_BG,
    draw_label,
    draw_leader,
    label_size,
    place_labels,
)

FloatArray = npt.NDArray[np.float64]
Image = npt.NDArray[np.uint8]
Color = tuple[int, int, int]

AXIS_MM = 200.0
"""How long the drawn x and y axes are."""
TICK_MM = 50.0
"""The scale's ticks along the axes."""
AXIS_BGR: dict[str, Color] = {"x": (60, 60, 235), "y": (60, 200, 60)}
"""x red, y green, as 3D tools draw them."""
BIN_TINT = 0.6
"""How much of a bin's floor is painted in its colour (the rest is the render)."""
OVERVIEW_PX = (640, 480)
CROP_MARGIN_PX = 12
CAPTION_PAD_PX = 4


def camera_pixels(twin: Twin, points_mm: npt.ArrayLike, camera: str = "overview") -> FloatArray:
    """Where points of the base frame (N x 3, mm) land in ``camera``'s ideal picture
    (N x 2 px, OpenCV pixel centres); NaN for points behind the camera."""
    pts = np.atleast_2d(np.asarray(points_mm, dtype=np.float64))
    cam2base = twin.cam2base_from_mujoco(camera)
    p_cam = (pts - cam2base[:3, 3]) @ cam2base[:3, :3]
    width, height = OVERVIEW_PX if camera == "overview" else (twin.lens.width_px,
                                                                twin.lens.height_px)
    fovy = math.radians(float(twin.model.cam_fovy[twin.model.camera(camera).id]))
    f = height / 2 / math.tan(fovy / 2)
    z = np.where(p_cam[:, 2] > 1.0, p_cam[:, 2], np.nan)
    out: FloatArray = np.stack([f * p_cam[:, 0] / z + width / 2 - 0.5,
                                f * p_cam[:, 1] / z + height / 2 - 0.5], axis=1)
    return out


class OverviewView:
    """The overview cropped to the table and enlarged (``image()``), and where points of
    the base frame (mm) land in it (``px``)."""

    def __init__(self, twin: Twin) -> None:
        self.twin = twin
        t, z = twin.scene.table, twin.config.table_z_mm
        corners = camera_pixels(twin, [(x, y, z) for x in (t.x_min_mm, t.x_max_mm)
                                       for y in (t.y_min_mm, t.y_max_mm)])
        w, h = OVERVIEW_PX
        lo = np.nanmin(corners, axis=0) - CROP_MARGIN_PX
        hi = np.nanmax(corners, axis=0) + CROP_MARGIN_PX
        width = min(float(w), max(hi[0] - lo[0], (hi[1] - lo[1]) * w / h))  # 4:3, as shot
        self.size = (round(width), round(width * h / w))
        centre = (lo + hi) / 2
        self.origin = np.array([np.clip(round(centre[0] - self.size[0] / 2), 0, w - self.size[0]),
                                np.clip(round(centre[1] - self.size[1] / 2), 0, h - self.size[1])],
                               dtype=np.float64)
        self.scale = np.array([w / self.size[0], h / self.size[1]])

    def image(self) -> Image:
        """The overview camera's picture, cropped and enlarged."""
        x0, y0 = (int(v) for v in self.origin)
        crop = self.twin.render_overview()[y0:y0 + self.size[1], x0:x0 + self.size[0]]
        return np.ascontiguousarray(cv2.resize(crop, OVERVIEW_PX, interpolation=cv2.INTER_CUBIC),
                                    dtype=np.uint8)

    def px(self, points_mm: npt.ArrayLike) -> FloatArray:
        """Where base-frame points (N x 3, mm) land in ``image()`` (N x 2 px)."""
        out: FloatArray = (camera_pixels(self.twin, points_mm) - self.origin) * self.scale
        return out

    def poly(self, points_mm: Sequence[Sequence[float]]) -> npt.NDArray[np.int32]:
        return np.rint(self.px(points_mm)).astype(np.int32)


Label = tuple[str, tuple[float, float, float, float], Color | None]


def _draw_bins(image: Image, view: OverviewView) -> list[Label]:
    z = view.twin.config.table_z_mm
    labels: list[Label] = []
    for tray in view.twin.scene.bins:
        color = DRAW_BGR.get(tray.color, (255, 255, 255))
        s = tray.size_mm / 2
        corners = [(tray.x_mm + dx * s, tray.y_mm + dy * s)
                   for dx, dy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        floor = view.poly([(x, y, z + 2.0) for x, y in corners])
        rim = view.poly([(x, y, z + tray.wall_mm) for x, y in corners])
        tinted = image.copy()
        cv2.fillPoly(tinted, [floor], color, cv2.LINE_AA)
        cv2.addWeighted(tinted, BIN_TINT, image, 1 - BIN_TINT, 0, dst=image)
        cv2.polylines(image, [rim], True, DARK, 4, cv2.LINE_AA)
        cv2.polylines(image, [rim], True, color, 2, cv2.LINE_AA)
        both = np.vstack([floor, rim])
        (u0, v0), (u1, v1) = both.min(axis=0), both.max(axis=0)
        labels.append((f"{tray.color} bin", (u0, v0, u1, v1), color))
    return labels


def _draw_axes(image: Image, view: OverviewView) -> list[Label]:
    z = view.twin.config.table_z_mm
    labels: list[Label] = []
    for name, (ux, uy) in (("x", (1.0, 0.0)), ("y", (0.0, 1.0))):
        color = AXIS_BGR[name]
        px = view.px([(ux * d, uy * d, z) for d in
                      np.arange(0.0, AXIS_MM + 1e-9, TICK_MM).tolist()])
        start, end = np.rint(px[0]).astype(int), np.rint(px[-1]).astype(int)
        for c, width in ((DARK, 5), (color, 2)):
            cv2.arrowedLine(image, (int(start[0]), int(start[1])), (int(end[0]), int(end[1])),
                            c, width, cv2.LINE_AA, tipLength=0.08)
        across = np.array([-(px[-1] - px[0])[1], (px[-1] - px[0])[0]])
        across *= 6.0 / (float(np.linalg.norm(across)) or 1.0)
        for p in px[1:-1]:
            a, b = np.rint(p - across).astype(int), np.rint(p + across).astype(int)
            for c, width in ((DARK, 4), (color, 2)):
                cv2.line(image, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), c, width,
                         cv2.LINE_AA)
        tip = view.px([(ux * (AXIS_MM + 15), uy * (AXIS_MM + 15), z)])[0]
        labels.append((f"{name} (mm)", (tip[0], tip[1], tip[0], tip[1]), color))
    o = view.px([(0.0, 0.0, z)])[0]
    centre = (round(float(o[0])), round(float(o[1])))
    cv2.circle(image, centre, 6, DARK, -1, cv2.LINE_AA)
    cv2.circle(image, centre, 4, (255, 255, 255), -1, cv2.LINE_AA)
    labels.append(("base origin (0, 0)", (o[0] - 4, o[1] - 4, o[0] + 4, o[1] + 4), None))
    return labels


def marked_overview(twin: Twin) -> Image:
    """The overview camera's picture of the table, enlarged, with each bin tinted and
    outlined in its colour and the base frame's origin and x/y axes (ticks every
    ``TICK_MM``), every mark labelled."""
    view = OverviewView(twin)
    image = view.image()
    labels = _draw_bins(image, view) + _draw_axes(image, view)
    sizes = [label_size(text, swatch=color is not None) for text, _, color in labels]
    title = f"overview: base frame (ticks every {TICK_MM:g} mm), bins in their colours"
    w, h = label_size(title, swatch=False)
    header = (2, 2, 2 + w, 2 + h)
    rects = place_labels([(b, size) for (_, b, _), size in zip(labels, sizes, strict=True)],
                         OVERVIEW_PX, [header])
    draw_label(image, title, header)
    for (_, bounds, color), rect in zip(labels, rects, strict=True):
        draw_leader(image, rect, bounds, color or (255, 255, 255))
    for (text, _, color), rect in zip(labels, rects, strict=True):  # over every leader
        draw_label(image, text, rect, color)
    return image


def titled(image: Image, title: str) -> Image:
    """A copy of ``image`` with ``title`` in a label at its top left."""
    out = image.copy()
    w, h = label_size(title, swatch=False)
    draw_label(out, title, (2, 2, 2 + w, 2 + h))
    return out


def _wrapped(lines: Sequence[str], width_px: int) -> list[str]:
    out: list[str] = []
    for line in lines:
        current = ""
        for word in line.split(" "):
            longer = f"{current} {word}" if current else word
            if current and label_size(longer, swatch=False)[0] > width_px:
                out.append(current)
                longer = word
            current = longer
        out.append(current)
    return out


def with_caption(image: Image, lines: Sequence[str]) -> Image:
    """``image`` with a dark bar under it holding ``lines`` of white text, wrapped to the
    picture's width."""
    lines = _wrapped(lines, image.shape[1] - 2 * CAPTION_PAD_PX)
    heights = [label_size(line, swatch=False)[1] for line in lines]
    bar = np.empty((sum(heights) + 2 * CAPTION_PAD_PX, image.shape[1], 3), np.uint8)
    bar[:] = LABEL_BG
    y = CAPTION_PAD_PX
    for line, h in zip(lines, heights, strict=True):
        w, _ = label_size(line, swatch=False)
        draw_label(bar, line, (CAPTION_PAD_PX, y, CAPTION_PAD_PX + w, y + h))
        y += h
    return np.vstack([image, bar])


__all__ = ["AXIS_BGR", "AXIS_MM", "TICK_MM", "OverviewView", "camera_pixels", "marked_overview",
           "titled", "with_caption"]
