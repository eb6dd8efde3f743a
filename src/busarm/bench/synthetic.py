"""Synthetic top-down pictures of blocks, with their truth, for the detection bench and
the vision tests.

``synthetic_frames`` makes 640x480 test scenes: matte blocks in the digital twin's
colours on its table, with lighting falloff, a dark arm edge, noise and a slight blur,
each with the true block poses. ``render_blocks`` draws given blocks at sub-pixel
positions.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from busarm.twin.model import TABLE_RGB
from busarm.twin.scene import COLORS
from busarm.vision.camera import UInt8Image

# The twin's materials (linear RGB 0..1), as rendered under white light.
BLOCK_RGB: dict[str, tuple[float, float, float]] = COLORS
ARM_RGB = (0.12, 0.12, 0.13)


@dataclass(frozen=True)
class Block:
    """A square block seen from above: colour, centre (u, v) px, side px, yaw deg."""

    color: str
    center_px: tuple[float, float]
    side_px: float
    yaw_deg: float

    def corners_px(self) -> np.ndarray[Any, np.dtype[np.float64]]:
        """The 4 x 2 corners in pixel coordinates (integer = pixel centre)."""
        pts = cv2.boxPoints((self.center_px, (self.side_px, self.side_px), self.yaw_deg))
        return np.asarray(pts, dtype=np.float64)


def bgr_from_rgb(rgb: Sequence[float], gain: float = 1.0) -> tuple[int, int, int]:
    """8-bit BGR of a 0..1 RGB colour times ``gain`` (clipped)."""
    return tuple(int(np.clip(round(c * gain * 255.0), 0, 255)) for c in rgb[::-1])  # type: ignore[return-value]


def render_blocks(
    blocks: Iterable[Block], width_px: int = 640, height_px: int = 480, *,
    noise_sigma: float = 3.0, blur: bool = True, lighting: float = 0.0, arm: bool = False,
    seed: int = 0, palette: dict[str, tuple[float, float, float]] | None = None,
) -> UInt8Image:
    """A table-coloured frame with ``blocks`` drawn anti-aliased at sub-pixel positions.

    ``lighting`` (0..0.5) darkens the frame towards one corner by up to that fraction,
    ``arm`` adds a dark bar along the top edge (the gripper in view), ``noise_sigma`` is
    Gaussian sensor noise in levels, ``blur`` a slight 3x3 lens blur.
    """
    palette = BLOCK_RGB if palette is None else palette
    image = np.empty((height_px, width_px, 3), np.uint8)
    image[:] = bgr_from_rgb(TABLE_RGB)
    if arm:
        cv2.rectangle(image, (width_px // 3, 0), (2 * width_px // 3, height_px // 12),
                      bgr_from_rgb(ARM_RGB), cv2.FILLED)
    for block in blocks:
        pts = np.rint(block.corners_px() * 16.0).astype(np.int32)  # 4 fractional bits
        cv2.fillPoly(image, [pts], bgr_from_rgb(palette[block.color]), cv2.LINE_AA, shift=4)
    out = image.astype(np.float32)
    if lighting > 0:
        yy, xx = np.mgrid[0:height_px, 0:width_px].astype(np.float32)
        falloff = 1.0 - lighting * (xx / width_px + yy / height_px) / 2.0
        out *= falloff[..., None]
    if noise_sigma > 0:
        out += np.random.default_rng(seed).normal(0.0, noise_sigma, out.shape).astype(np.float32)
    result = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    if blur:
        result = np.asarray(cv2.GaussianBlur(result, (3, 3), 0.6), dtype=np.uint8)
    return result


def random_blocks(
    rng: np.random.Generator, count: int, width_px: int = 640, height_px: int = 480, *,
    colors: Sequence[str] = ("red", "green", "blue"), side_px: tuple[float, float] = (36, 90),
) -> list[Block]:
    """``count`` blocks of random colour, side, yaw and place, apart from each other and
    the frame's edges (so each stays one blob)."""
    blocks: list[Block] = []
    for _ in range(count * 200):
        if len(blocks) == count:
            break
        side = float(rng.uniform(*side_px))
        reach = side * math.sqrt(0.5) + 4.0
        u = float(rng.uniform(reach, width_px - reach))
        v = float(rng.uniform(reach + height_px / 12.0, height_px - reach))
        if all(math.dist((u, v), b.center_px) > reach + b.side_px * math.sqrt(0.5) + 10
               for b in blocks):
            blocks.append(Block(str(colors[int(rng.integers(len(colors)))]), (u, v), side,
                                float(rng.uniform(-45.0, 45.0))))
    return blocks


def synthetic_frames(
    count: int, *, seed: int = 0, width_px: int = 640, height_px: int = 480,
    blocks: tuple[int, int] = (3, 6), colors: Sequence[str] = ("red", "green", "blue"),
) -> list[tuple[UInt8Image, list[Block]]]:
    """``count`` scenes with 3..6 blocks each (seeded), and the blocks in each."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        n = int(rng.integers(blocks[0], blocks[1] + 1))
        scene = random_blocks(rng, n, width_px, height_px, colors=colors)
        image = render_blocks(scene, width_px, height_px, seed=seed * 100_003 + i,
                              lighting=float(rng.uniform(0.0, 0.3)), arm=bool(i % 2))
        out.append((image, scene))
    return out


__all__ = [
    "ARM_RGB",
    "BLOCK_RGB",
    "TABLE_RGB",
    "Block",
    "bgr_from_rgb",
    "random_blocks",
    "render_blocks",
    "synthetic_frames",
]
