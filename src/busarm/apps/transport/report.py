"""The transport run's report: a folder a person can read.

``report.json`` (the phases with their times and outcomes, the trips, where the block was
put, whether it was delivered and why not), ``map.png`` (the map with the named points,
the paths planned and driven, and where the block was put), and ``seen-COLOUR.png`` (what
the wrist camera saw at the pick point). Every file is written atomically.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from busarm.apps.transport.job import TransportReport
from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.nav.grid import OccupancyGrid
from busarm.nav.map_picture import map_picture
from busarm.nav.points import NamedPoints
from busarm.vision.annotate import save_image

__all__ = [
    "Image",
    "transport_picture",
    "write_transport_report",
]


Image = npt.NDArray[np.uint8]


def transport_picture(grid: OccupancyGrid, report: TransportReport,
                      points: NamedPoints) -> Image:
    """The map with the points, every plan (grey), the path driven (blue) and the spot the
    block was put at."""
    marks = {name: (p.pose.x_m, p.pose.y_m) for name, p in points.points.items()
             if name in (report.pick, report.place)}
    if report.placed_at_m is not None:
        marks["block"] = report.placed_at_m
    path = [(p.x_m, p.y_m) for trip in report.trips for p in trip.path]
    plans = [trip.plans[0] for trip in report.trips if trip.plans]
    return map_picture(grid, path=path, plans=plans, marks=marks)


def write_transport_report(folder: Path, report: TransportReport, grid: OccupancyGrid,
                           points: NamedPoints, pictures: Sequence[tuple[str, Image]] = (),
                           extra: dict[str, Any] | None = None) -> Path:
    """Write the run's folder; returns the path of report.json."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot make the report folder {folder}: {exc.strerror}") from exc
    for old in folder.glob("seen-*.png"):
        old.unlink(missing_ok=True)
    data = {"format": "busarm.transport_report", "version": 1, **report.to_dict(),
            **(extra or {})}
    path = folder / "report.json"
    write_text_atomic(path, json.dumps(data, indent=2) + "\n", "report")
    save_image(folder / "map.png", transport_picture(grid, report, points))
    for name, image in pictures:
        save_image(folder / f"{name}.png", image)
    return path
