"""ColorDetector's coarse colour table, indexed by each pixel's BGR565 value: a colour
gets the bits of its 32x32x32 bin (the bin centre's Lab in each colour's box), for every
BGR565 value and whatever the bits it drops."""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from busarm.vision.color import LUT_BITS, ColorDetector
from busarm.vision.color_thresholds import default_thresholds


def _bin_bits(detector: ColorDetector, image: npt.NDArray[np.uint8]) -> list[npt.NDArray[np.uint8]]:
    """Each pixel's bits, from its bin computed plainly: the bin centre's Lab tested
    against each colour's box."""
    n = 1 << LUT_BITS
    step = 256 // n
    centres = (image >> (8 - LUT_BITS)).astype(np.uint8) * step + step // 2
    lab = cv2.cvtColor(centres, cv2.COLOR_BGR2LAB)
    out = [np.zeros(image.shape[:2], np.uint8) for _ in detector._tables]
    for name, r in detector.thresholds.items():
        group, bit = detector._bits[name]
        inside = np.all((lab >= r.lab_min) & (lab <= r.lab_max), axis=2)
        out[group][inside] |= np.uint8(bit)
    return out


def test_every_colour_gets_its_bins_bits() -> None:
    detector = ColorDetector(default_thresholds())
    rng = np.random.default_rng(3)
    code = np.arange(1 << 16, dtype=np.uint32)  # every BGR565 value ...
    for _ in range(4):  # ... with the bits it drops drawn at random
        low = rng.integers(0, 256, (code.size, 3), dtype=np.uint32)
        bgr = np.stack([(code & 31) << 3 | low[:, 0] & 7, (code >> 5 & 63) << 2 | low[:, 1] & 3,
                        (code >> 11) << 3 | low[:, 2] & 7], axis=1)
        image = bgr.astype(np.uint8).reshape(256, 256, 3)
        for got, want in zip(detector._label(image), _bin_bits(detector, image), strict=True):
            np.testing.assert_array_equal(got, want)


def test_a_picture_view_is_labelled_as_its_copy() -> None:
    detector = ColorDetector(default_thresholds().select(["red", "green"]))
    rng = np.random.default_rng(5)
    image = rng.integers(0, 256, (60, 90, 3), dtype=np.uint8)
    view = image[5:45:2, 10:80]  # not contiguous
    for a, b in zip(detector._label(view), detector._label(view.copy()), strict=True):
        np.testing.assert_array_equal(a, b)
