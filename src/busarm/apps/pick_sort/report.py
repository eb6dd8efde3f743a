"""The pick-and-sort run report: a folder a person can read.

``report.json`` (every block: colour, where found, where placed, attempts, time,
outcome and reason; the totals), ``before.png`` and ``after.png`` (the table from above),
``picks/NN-colour.png`` (the annotated camera picture each pick started from) and
``camera.gif`` (the arm camera through the run). Every file is written atomically.
"""

from __future__ import annotations

import io
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from busarm.apps.pick_sort.sorter import RunReport
from busarm.errors import ConfigError
from busarm.fileio import write_bytes_atomic, write_text_atomic
from busarm.vision.annotate import save_image

__all__ = [
    "GIF_FRAME_S",
    "GIF_WIDTH_PX",
    "Image",
    "gif_bytes",
    "write_report",
]


Image = npt.NDArray[np.uint8]
GIF_WIDTH_PX = 320
GIF_FRAME_S = 0.25


def write_report(folder: Path, report: RunReport, *, before: Image | None = None,
                 after: Image | None = None, picks: Sequence[tuple[str, Image]] = (),
                 camera_frames: Sequence[Image] = (),
                 extra: dict[str, Any] | None = None) -> Path:
    """Write the run's folder; returns the path of report.json."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot make the report folder {folder}: {exc.strerror}") from exc
    _clear_pictures(folder)
    data = {"format": "busarm.pick_sort_report", "version": 1,
            "totals": report.totals(), "blocks": [b.to_dict() for b in report.blocks],
            **({"stopped": report.stopped, "gripper": report.gripper} if report.stopped else {}),
            **(extra or {})}
    path = folder / "report.json"
    write_text_atomic(path, json.dumps(data, indent=2) + "\n", "report")
    if before is not None:
        save_image(folder / "before.png", before)
    if after is not None:
        save_image(folder / "after.png", after)
    if picks:
        (folder / "picks").mkdir(exist_ok=True)
        for i, (name, image) in enumerate(picks):
            save_image(folder / "picks" / f"{i + 1:02d}-{name}.png", image)
    if camera_frames:
        write_bytes_atomic(folder / "camera.gif", gif_bytes(camera_frames), "animation")
    return path


def _clear_pictures(folder: Path) -> None:
    """Remove an earlier run's pictures, so the folder shows this run's only."""
    old = [folder / name for name in ("before.png", "after.png", "camera.gif")]
    for path in [*old, *sorted((folder / "picks").glob("*.png"))]:
        path.unlink(missing_ok=True)


def gif_bytes(frames: Sequence[Image], width_px: int = GIF_WIDTH_PX,
              frame_s: float = GIF_FRAME_S) -> bytes:
    """An animated GIF of BGR frames, scaled to ``width_px`` wide."""
    from PIL import Image as PILImage

    pictures = []
    for frame in frames:
        h, w = frame.shape[:2]
        small = cv2.resize(frame, (width_px, round(h * width_px / w)),
                           interpolation=cv2.INTER_AREA)
        pictures.append(PILImage.fromarray(cv2.cvtColor(small, cv2.COLOR_BGR2RGB)))
    out = io.BytesIO()
    pictures[0].save(out, format="GIF", save_all=True, append_images=pictures[1:],
                     duration=round(frame_s * 1000), loop=0)
    return out.getvalue()
