"""AprilTags printed on the top face of the twin's blocks (``Block.tag_id``).

A tagged block's top face carries a white label with a 36h11 tag on it, the sides keep
the block's colour. The tag's black square (8 x 8 cells: the black border and 6 x 6
data cells) is ``TAG_SIDE_FRACTION`` of the block's side; the white label around it is
one cell wider on every side (the tag's quiet zone), leaving a thin rim of the block's
colour at the top face's edge.

In the model the label and the black cells are thin boxes in the block's own body
(touching nothing, weighing nothing), so the tag moves with the block. No texture file
is needed: the cells are drawn as boxes, each run of black cells in a row merged, and
runs of the same span in consecutive rows merged again.

Tag frame (as ``busarm.vision.tags`` has it: x towards the tag's right edge, y towards
its top edge, z out of the face): the block's own frame moved up to the centre of its
top face. The printed tag's first row lies at the block's +y side, its first column at
its -x side.
"""

from __future__ import annotations

import functools

import numpy as np

from busarm.vision.tags import tag_image

__all__ = [
    "TAG_BLACK_RGB",
    "TAG_CELLS",
    "TAG_INK_MM",
    "TAG_LABEL_MM",
    "TAG_SIDE_FRACTION",
    "TAG_WHITE_RGB",
    "tag_black_cells",
    "tag_geoms",
    "tag_rects",
    "tag_square_mm",
]

TAG_SIDE_FRACTION = 0.75
"""The tag's black square over the block's side (a 30 mm block carries a 22.5 mm tag)."""
TAG_CELLS = 8
"""Cells across the black square: one of black border on each side, 6 of data."""
TAG_LABEL_MM = 0.2
"""Thickness of the white label on the top face."""
TAG_INK_MM = 0.1
"""Thickness of the black cells on the label."""
TAG_WHITE_RGB = (0.90, 0.90, 0.88)
"""Matte paper."""
TAG_BLACK_RGB = (0.04, 0.04, 0.04)
"""Matte ink."""


def tag_square_mm(block_size_mm: float) -> float:
    """Side of the black square on a block of ``block_size_mm`` (the size for tag_pose)."""
    return block_size_mm * TAG_SIDE_FRACTION


@functools.lru_cache(maxsize=64)
def tag_black_cells(tag_id: int) -> tuple[tuple[bool, ...], ...]:
    """The 8 x 8 cells of tag ``tag_id`` as printed (row 0 at the top), True = black.
    ConfigError for an id outside 0..586 (36h11)."""
    cells = tag_image(tag_id, TAG_CELLS, 0) < 128
    return tuple(tuple(bool(v) for v in row) for row in np.asarray(cells))


def tag_rects(tag_id: int) -> list[tuple[int, int, int, int]]:
    """The tag's black cells as few rectangles: (first row, first column, rows, columns)."""
    open_runs: dict[tuple[int, int], list[int]] = {}  # (col, cols) -> [row0, rows]
    out: list[tuple[int, int, int, int]] = []
    for r, row in enumerate(tag_black_cells(tag_id)):
        runs, c = [], 0
        while c < TAG_CELLS:
            if row[c]:
                start = c
                while c < TAG_CELLS and row[c]:
                    c += 1
                runs.append((start, c - start))
            c += 1
        for key in list(open_runs):  # a run that does not go on into this row ends
            if key not in runs:
                row0, rows = open_runs.pop(key)
                out.append((row0, key[0], rows, key[1]))
        for key in runs:
            if key in open_runs:
                open_runs[key][1] += 1
            else:
                open_runs[key] = [r, 1]
    out += [(row0, col, rows, cols) for (col, cols), (row0, rows) in open_runs.items()]
    return sorted(out)


def _fmt(*values: float) -> str:
    return " ".join(f"{v:.9g}" for v in values)


def tag_geoms(tag_id: int, block_size_mm: float, indent: str) -> list[str]:
    """MJCF geoms of the label and the tag on a block's top face, in the block's body frame
    (metres); they use the materials ``tag_white`` and ``tag_black``."""
    m = 0.001
    half = block_size_mm / 2 * m
    cell = tag_square_mm(block_size_mm) / TAG_CELLS * m
    label_half = (TAG_CELLS + 2) * cell / 2
    visual = 'contype="0" conaffinity="0" density="0"'
    label_z = half + TAG_LABEL_MM / 2 * m
    ink_z = half + (TAG_LABEL_MM + TAG_INK_MM / 2) * m
    label_size = _fmt(label_half, label_half, TAG_LABEL_MM / 2 * m)
    out = [f'{indent}<geom type="box" {visual} material="tag_white" '
           f'pos="{_fmt(0, 0, label_z)}" size="{label_size}"/>']
    for row0, col0, rows, cols in tag_rects(tag_id):
        # Cell (r, c) centre: x = (c - 3.5) cells, y = (3.5 - r) cells (row 0 at +y).
        x = (col0 + cols / 2 - TAG_CELLS / 2) * cell
        y = (TAG_CELLS / 2 - row0 - rows / 2) * cell
        out.append(f'{indent}<geom type="box" {visual} material="tag_black" '
                   f'pos="{_fmt(x, y, ink_z)}" '
                   f'size="{_fmt(cols * cell / 2, rows * cell / 2, TAG_INK_MM / 2 * m)}"/>')
    return out
