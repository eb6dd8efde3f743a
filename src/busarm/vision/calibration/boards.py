"""Calibration boards: chessboard, ChArUco and tag-board specs and their printable images."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Union

import cv2
import numpy as np

from busarm.errors import ConfigError
from busarm.units import check_int_range, check_range
from busarm.vision.calibration.core import FloatArray, UInt8Array

__all__ = [
    "TAG_DICTIONARY",
    "BoardSpec",
    "CharucoSpec",
    "ChessboardSpec",
    "TagBoardSpec",
    "board_image_frame",
]


TAG_DICTIONARY = "DICT_APRILTAG_36h11"
"""The tag family of ``TagBoardSpec`` (the vendor's AprilTags are 36h11 as well)."""


def _check_length(name: str, value: float, lo: float = 0.01, hi: float = 10_000.0) -> None:
    """A board length in mm, 0.01..10000 unless told."""
    check_range(name, value, lo, hi, "mm")


def _dictionary(name: str) -> cv2.aruco.Dictionary:
    code = getattr(cv2.aruco, name, None) if name.startswith("DICT_") else None
    if not isinstance(code, int):
        raise ConfigError(f"dictionary {name!r} is not an OpenCV ArUco dictionary (DICT_...)")
    return cv2.aruco.getPredefinedDictionary(code)


def _dictionary_size(name: str) -> int:
    return int(_dictionary(name).bytesList.shape[0])


@dataclass(frozen=True)
class ChessboardSpec:
    """A chessboard with ``inner_cols`` x ``inner_rows`` inner corners.

    Squares: (inner_cols + 1) x (inner_rows + 1), the top-left one black. Inner corner
    (i, j) is at ((i + 1) s, (j + 1) s, 0) in the board frame (s = ``square_mm``).
    Only for intrinsics: its pose is ambiguous under a half turn.
    """

    inner_cols: int
    inner_rows: int
    square_mm: float

    def __post_init__(self) -> None:
        check_int_range("inner_cols", self.inner_cols, 2, 100)
        check_int_range("inner_rows", self.inner_rows, 2, 100)
        _check_length("square_mm", self.square_mm)

    @property
    def object_points(self) -> FloatArray:
        """(N, 3) inner corners, row by row (the order OpenCV reports them)."""
        j, i = np.mgrid[0 : self.inner_rows, 0 : self.inner_cols]
        s = self.square_mm
        return np.stack([(i.ravel() + 1) * s, (j.ravel() + 1) * s, np.zeros(i.size)], axis=1)

    @property
    def extent_mm(self) -> tuple[float, float]:
        """Width and height of the square grid."""
        return ((self.inner_cols + 1) * self.square_mm, (self.inner_rows + 1) * self.square_mm)

    def describe(self) -> str:
        return (
            f"chessboard {self.inner_cols}x{self.inner_rows} inner corners, "
            f"{self.square_mm:g} mm squares"
        )

    def default_margin_mm(self) -> float:
        return self.square_mm

    def board_image(self, px_per_mm: float, margin_mm: float | None = None) -> UInt8Array:
        """The printable image (see ``board_image_frame``); white margin, black squares."""
        frame = _image_frame(self, px_per_mm, margin_mm)
        s = self.square_mm
        rects = [
            (a * s, b * s, (a + 1) * s, (b + 1) * s)
            for b in range(self.inner_rows + 1) for a in range(self.inner_cols + 1)
            if (a + b) % 2 == 0
        ]
        return _raster(frame, px_per_mm, rects, [])


@dataclass(frozen=True)
class CharucoSpec:
    """A ChArUco board (OpenCV's current layout: the top-left square is black).

    ``squares_x`` x ``squares_y`` squares of ``square_mm``; ArUco markers of
    ``marker_mm`` (centred in the white squares) from ``dictionary``, ids 0, 1, ...
    row by row. Corner id k is at ((k % (squares_x-1) + 1) s, (k // (squares_x-1) + 1) s).
    Keep ``marker_mm`` near 0.6 ``square_mm``: OpenCV refines each corner in a window
    that larger markers reach into, which scatters the corners (0.2 px rms at 0.75).
    """

    squares_x: int
    squares_y: int
    square_mm: float
    marker_mm: float
    dictionary: str = "DICT_5X5_100"

    def __post_init__(self) -> None:
        check_int_range("squares_x", self.squares_x, 3, 100)
        check_int_range("squares_y", self.squares_y, 3, 100)
        _check_length("square_mm", self.square_mm)
        _check_length("marker_mm", self.marker_mm, 0.01, 0.95 * self.square_mm)
        need = self.squares_x * self.squares_y // 2
        have = _dictionary_size(self.dictionary)
        if need > have:
            raise ConfigError(
                f"a {self.squares_x}x{self.squares_y} ChArUco board needs {need} markers; "
                f"{self.dictionary} has {have}"
            )

    @property
    def object_points(self) -> FloatArray:
        """(N, 3) chessboard corners by id."""
        return np.asarray(_charuco_board(self).getChessboardCorners(), np.float64).reshape(-1, 3)

    @property
    def extent_mm(self) -> tuple[float, float]:
        return (self.squares_x * self.square_mm, self.squares_y * self.square_mm)

    def describe(self) -> str:
        return (
            f"charuco {self.squares_x}x{self.squares_y} squares, {self.square_mm:g} mm squares, "
            f"{self.marker_mm:g} mm markers, {self.dictionary}"
        )

    def default_margin_mm(self) -> float:
        return self.square_mm / 2.0

    def board_image(self, px_per_mm: float, margin_mm: float | None = None) -> UInt8Array:
        """The printable image (see ``board_image_frame``)."""
        frame = _image_frame(self, px_per_mm, margin_mm)
        board = _cv_board(self)
        markers = _marker_quads(board, self.dictionary)
        s = self.square_mm
        with_marker = {(int(m[0] // s), int(m[1] // s)) for m, _, _ in markers}
        rects = [
            (a * s, b * s, (a + 1) * s, (b + 1) * s)
            for b in range(self.squares_y) for a in range(self.squares_x)
            if (a, b) not in with_marker
        ]
        return _raster(frame, px_per_mm, rects, markers)


@dataclass(frozen=True)
class TagBoardSpec:
    """A grid of AprilTag 36h11 markers (OpenCV's ``aruco.GridBoard``), for hand-eye.

    ``cols`` x ``rows`` tags of ``tag_mm`` (the black border's outer edge) with
    ``gap_mm`` of white between them; ids ``first_id`` + k, row by row. Tag k's corners
    (top-left, top-right, bottom-right, bottom-left as printed) start at
    ((k % cols) p, (k // cols) p) with p = tag_mm + gap_mm.
    """

    cols: int
    rows: int
    tag_mm: float
    gap_mm: float
    first_id: int = 0

    def __post_init__(self) -> None:
        check_int_range("cols", self.cols, 1, 50)
        check_int_range("rows", self.rows, 1, 50)
        _check_length("tag_mm", self.tag_mm)
        # The detector needs a white quiet zone of at least one tag cell (1/8 of the tag).
        _check_length("gap_mm", self.gap_mm, self.tag_mm / 8.0, 10_000.0)
        size = _dictionary_size(TAG_DICTIONARY)
        check_int_range("first_id", self.first_id, 0, size - self.cols * self.rows)

    @property
    def object_points(self) -> FloatArray:
        """(4 N, 3): the corners of every tag, in id order."""
        return np.concatenate(
            [np.asarray(q, np.float64) for q in _cv_board(self).getObjPoints()]
        ).reshape(-1, 3)

    @property
    def extent_mm(self) -> tuple[float, float]:
        p = self.tag_mm + self.gap_mm
        return (self.cols * p - self.gap_mm, self.rows * p - self.gap_mm)

    def describe(self) -> str:
        return (
            f"tag board {self.cols}x{self.rows} AprilTag 36h11, {self.tag_mm:g} mm tags, "
            f"{self.gap_mm:g} mm gaps, ids {self.first_id}.."
            f"{self.first_id + self.cols * self.rows - 1}"
        )

    def default_margin_mm(self) -> float:
        return max(self.gap_mm, self.tag_mm / 4.0)

    def board_image(self, px_per_mm: float, margin_mm: float | None = None) -> UInt8Array:
        """The printable image (see ``board_image_frame``)."""
        frame = _image_frame(self, px_per_mm, margin_mm)
        return _raster(frame, px_per_mm, [], _marker_quads(_cv_board(self), TAG_DICTIONARY))


BoardSpec = Union[ChessboardSpec, CharucoSpec, TagBoardSpec]  # noqa: UP007 (runtime alias, 3.10)


def board_image_frame(
    spec: BoardSpec, px_per_mm: float, margin_mm: float | None = None
) -> tuple[float, float, int, int]:
    """(x_min_mm, y_min_mm, width_px, height_px) of ``spec.board_image(px_per_mm, margin_mm)``.

    The image's rows run along the board's +y, its columns along +x. The *outer corner*
    of pixel (0, 0) (its top-left corner, not its centre) is the board point
    (x_min, y_min, 0) = (-margin, -margin, 0); pixel (u, v) covers board x in
    [x_min + u / px_per_mm, x_min + (u + 1) / px_per_mm) and y likewise, and is black
    when its centre falls on a black cell. So the image is exact when the cells are a
    whole number of pixels, and within half a pixel otherwise. Width and height are the
    pattern plus a margin on every side, rounded up to whole pixels.
    """
    return _image_frame(spec, px_per_mm, margin_mm)


def _image_frame(
    spec: BoardSpec, px_per_mm: float, margin_mm: float | None
) -> tuple[float, float, int, int]:
    check_range("px_per_mm", px_per_mm, 0.01, 1000.0)
    margin = spec.default_margin_mm() if margin_mm is None else margin_mm
    _check_length("margin_mm", margin, 0.0, 10_000.0)
    w, h = spec.extent_mm
    width = math.ceil((w + 2 * margin) * px_per_mm - 1e-9)
    height = math.ceil((h + 2 * margin) * px_per_mm - 1e-9)
    if width * height > 200_000_000:
        raise ConfigError(f"board image {width}x{height} px is too large; lower px_per_mm")
    return (-float(margin), -float(margin), width, height)


_Quad = tuple[tuple[float, float], float, UInt8Array]
"""A marker: top-left corner (x, y) mm, side mm, cell image (1 px per cell)."""


def _marker_quads(board: cv2.aruco.Board, dictionary: str) -> list[_Quad]:
    d = _dictionary(dictionary)
    cells = int(d.markerSize) + 2
    out: list[_Quad] = []
    ids = np.asarray(board.getIds()).ravel()
    for corners, marker_id in zip(board.getObjPoints(), ids, strict=True):
        q = np.asarray(corners, np.float64).reshape(4, 3)
        side = float(q[1, 0] - q[0, 0])
        # OpenCV's planar boards: corner 0 top-left, 1 to its +x, 3 to its +y.
        assert q[3, 1] - q[0, 1] == side and q[1, 1] == q[0, 1], "unexpected marker layout"
        bits = cv2.aruco.generateImageMarker(d, int(marker_id), cells, borderBits=1)
        out.append(((float(q[0, 0]), float(q[0, 1])), side, np.asarray(bits, np.uint8)))
    return out


def _raster(
    frame: tuple[float, float, int, int], px_per_mm: float,
    rects: list[tuple[float, float, float, float]], markers: list[_Quad],
) -> UInt8Array:
    """Point-sample black rectangles and markers at pixel centres (see board_image_frame)."""
    x_min, y_min, width, height = frame
    xs = x_min + (np.arange(width) + 0.5) / px_per_mm
    ys = y_min + (np.arange(height) + 0.5) / px_per_mm
    img = np.full((height, width), 255, np.uint8)
    for x0, y0, x1, y1 in rects:
        cols = np.flatnonzero((xs >= x0) & (xs < x1))
        rows = np.flatnonzero((ys >= y0) & (ys < y1))
        img[np.ix_(rows, cols)] = 0
    for (x0, y0), side, bits in markers:
        n = bits.shape[0]
        i = np.floor((xs - x0) / side * n).astype(np.int64)
        j = np.floor((ys - y0) / side * n).astype(np.int64)
        cols = np.flatnonzero((i >= 0) & (i < n))
        rows = np.flatnonzero((j >= 0) & (j < n))
        img[np.ix_(rows, cols)] = bits[np.ix_(j[rows], i[cols])]
    return img


@functools.lru_cache(maxsize=64)
def _cv_board(spec: CharucoSpec | TagBoardSpec) -> cv2.aruco.Board:
    if isinstance(spec, CharucoSpec):
        return _charuco_board(spec)
    ids = np.arange(spec.first_id, spec.first_id + spec.cols * spec.rows, dtype=np.int32)
    grid: cv2.aruco.Board = cv2.aruco.GridBoard(
        (spec.cols, spec.rows), float(spec.tag_mm), float(spec.gap_mm),
        _dictionary(TAG_DICTIONARY), ids,
    )
    return grid


@functools.lru_cache(maxsize=64)
def _charuco_board(spec: CharucoSpec) -> cv2.aruco.CharucoBoard:
    return cv2.aruco.CharucoBoard(
        (spec.squares_x, spec.squares_y), float(spec.square_mm), float(spec.marker_mm),
        _dictionary(spec.dictionary),
    )
