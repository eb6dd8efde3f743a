"""``busarm map show`` on a map written as map_server writes them, through the real CLI."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from busarm.base.odometry import Pose2D
from busarm.nav.grid import GridSpec, OccupancyGrid
from busarm.nav.map_files import save_map


def busarm(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "busarm", *args], capture_output=True,
                          text=True, timeout=60)


def test_map_show_describes_and_draws_a_map(tmp_path: Path) -> None:
    grid = OccupancyGrid(GridSpec.covering(-1.5, 1.5, -1.0, 1.0, 0.05))
    bearings = np.linspace(0, 2 * math.pi, 360, endpoint=False)
    c, s = np.cos(bearings), np.sin(bearings)
    with np.errstate(divide="ignore"):
        ranges = np.minimum(np.abs(1.0 / c), np.abs(0.8 / s))
    for _ in range(4):
        grid.insert(Pose2D(), bearings, ranges)
    save_map(tmp_path / "room.yaml", grid)
    done = busarm("map", "show", str(tmp_path / "room.yaml"), "--png", str(tmp_path / "room.png"))
    assert done.returncode == 0, done.stderr
    assert "60 x 40 cells of 5 cm (3.00 x 2.00 m)" in done.stdout
    assert "lower-left corner at x -1.500 m, y -1.000 m" in done.stdout
    free = float(done.stdout.split("free ")[1].split("%")[0])
    assert 40 < free < 60  # the room's inside (2 x 1.6 m of 3 x 2 m), less its walls
    picture = cv2.imread(str(tmp_path / "room.png"))
    assert picture is not None and picture.shape[:2] == (400, 600)  # enlarged 10 times
    # The room's inside is free (254, as in the PGM), beyond its walls unknown (205).
    assert (picture[120, 150] == 254).all() and (picture[5, 5] == 205).all()


def test_map_show_of_a_bad_file_is_one_error(tmp_path: Path) -> None:
    (tmp_path / "bad.yaml").write_text("image: bad.pgm\nresolution: 2\norigin: [0, 0, 0]\n")
    for path, said in ((tmp_path / "bad.yaml", "resolution = 2; allowed: a number 0.005..1"),
                       (tmp_path / "none.yaml", "cannot read it")):
        done = busarm("map", "show", str(path))
        assert done.returncode == 2, done.stdout
        lines = done.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: map file") and said in lines[0]
