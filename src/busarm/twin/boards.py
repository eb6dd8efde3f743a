"""Calibration boards on the twin's table: the printable images of busarm.vision's
board specs, laid flat where the scene says, with their true pose for tests.

A board's own frame (busarm.vision.calibration): origin at its first corner, x along
the image columns, y along the rows, z = x cross y. Printed face up on the table and
read from above without a mirror, that makes y point the other way from the table's
left (y_board = -y_table at yaw 0) and z point down into the table.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from busarm.errors import ConfigError
from busarm.twin.scene import BASE_CLEARANCE_MM, Board, Scene
from busarm.units import place_text
from busarm.vision.calibration.boards import (
    BoardSpec,
    CharucoSpec,
    ChessboardSpec,
    TagBoardSpec,
    board_image_frame,
)

__all__ = [
    "BOARD_SPECS",
    "CALIBRATION_BOARD_CENTRE_MM",
    "PX_PER_MM",
    "FloatArray",
    "board2base",
    "board_spec",
    "board_texture",
    "calibration_board",
    "check_boards_fit",
    "scene_textures",
]


FloatArray = npt.NDArray[np.float64]

BOARD_SPECS: dict[str, BoardSpec] = {
    "chessboard": ChessboardSpec(inner_cols=9, inner_rows=6, square_mm=16.0),
    "charuco": CharucoSpec(squares_x=8, squares_y=6, square_mm=25.0, marker_mm=18.0),
    "tags": TagBoardSpec(cols=5, rows=4, tag_mm=30.0, gap_mm=10.0),
}
"""The boards the twin can print: the same specs the calibration flows look for."""

PX_PER_MM = 8.0


def board_spec(kind: str) -> BoardSpec:
    return BOARD_SPECS[kind]


def board2base(board: Board, table_z_mm: float) -> FloatArray:
    """Where a board lying on the table puts its own frame, in the base frame (mm)."""
    yaw = math.radians(board.yaw_deg)
    c, s = math.cos(yaw), math.sin(yaw)
    out = np.eye(4)
    out[:3, 0] = (c, s, 0.0)
    out[:3, 1] = (s, -c, 0.0)
    out[:3, 2] = (0.0, 0.0, -1.0)
    out[:3, 3] = (board.x_mm, board.y_mm, table_z_mm)
    return out


def board_texture(board: Board, index: int, table_z_mm: float
                  ) -> tuple[str, bytes, float, float, FloatArray]:
    """(file name, PNG bytes, width mm, height mm, image2base) of one board's print.

    ``image2base`` places the print's centre and axes: its x along the image columns,
    its y along the rows *upward in the picture* (the way MuJoCo lays a 2D texture on a
    plane: the first image row at the plane's +y edge).
    """
    spec = board_spec(board.kind)
    x_min, y_min, width_px, height_px = board_image_frame(spec, PX_PER_MM)
    image = spec.board_image(PX_PER_MM)
    ok, png = cv2.imencode(".png", image)
    assert ok
    w_mm, h_mm = width_px / PX_PER_MM, height_px / PX_PER_MM
    b2b = board2base(board, table_z_mm)
    centre_board = np.array([x_min + w_mm / 2, y_min + h_mm / 2, 0.0, 1.0])
    image2base = np.eye(4)
    image2base[:3, 0] = b2b[:3, 0]
    image2base[:3, 1] = -b2b[:3, 1]   # image rows run along board +y, drawn top to bottom
    image2base[:3, 2] = (0.0, 0.0, 1.0)
    image2base[:3, 3] = (b2b @ centre_board)[:3]
    return f"board{index}.png", png.tobytes(), w_mm, h_mm, image2base


def scene_textures(scene: Scene, table_z_mm: float
                   ) -> list[tuple[str, bytes, float, float, FloatArray]]:
    return [board_texture(b, i, table_z_mm) for i, b in enumerate(scene.boards)]


CALIBRATION_BOARD_CENTRE_MM = (210.0, 0.0)
"""Where the calibration flows expect a board (its pattern's centre) unless told."""


def calibration_board(kind: str, centre_mm: tuple[float, float] = CALIBRATION_BOARD_CENTRE_MM,
                      yaw_deg: float = 90.0) -> Board:
    """A board of ``kind`` whose pattern is centred at ``centre_mm`` on the table."""
    w, h = board_spec(kind).extent_mm
    yaw = math.radians(yaw_deg)
    x_b, y_b = np.array([math.cos(yaw), math.sin(yaw)]), np.array([math.sin(yaw), -math.cos(yaw)])
    origin = np.asarray(centre_mm) - x_b * w / 2 - y_b * h / 2
    return Board(kind, float(origin[0]), float(origin[1]), yaw_deg)


def check_boards_fit(scene: Scene, table_z_mm: float) -> None:
    """Raise ConfigError for a board that hangs off the table or lies on the arm base."""
    for i, board in enumerate(scene.boards):
        w, h = board_spec(board.kind).extent_mm
        b2b = board2base(board, table_z_mm)
        corners = b2b @ np.array([[0, 0, 0, 1], [w, 0, 0, 1], [w, h, 0, 1], [0, h, 0, 1]],
                                 dtype=float).T
        for x, y in corners[:2].T:
            if not scene.table.contains(float(x), float(y)):
                raise ConfigError(f"scene {scene.source}: boards[{i}] ({board.kind}, "
                                  f"{w:g}x{h:g} mm) hangs off the table at {place_text((x, y))}")
        # The base is a disc around (0, 0): the board's nearest point must clear it.
        nearest = _nearest_on_rectangle(b2b, w, h)
        if nearest < BASE_CLEARANCE_MM:
            raise ConfigError(f"scene {scene.source}: boards[{i}] ({board.kind}) lies on the "
                              f"arm base: keep it {BASE_CLEARANCE_MM:g} mm from (0, 0)")


def _nearest_on_rectangle(b2b: FloatArray, w: float, h: float) -> float:
    """Distance from the base axis to the nearest point of a board lying on the table."""
    local = np.linalg.inv(b2b) @ np.array([0.0, 0.0, b2b[2, 3], 1.0])
    u = min(max(float(local[0]), 0.0), w)
    v = min(max(float(local[1]), 0.0), h)
    return float(np.hypot(float(local[0]) - u, float(local[1]) - v))
