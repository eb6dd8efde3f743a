"""Calibration files: load and save the intrinsics and hand-eye JSON formats."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from busarm.errors import CalibrationError, ConfigError
from busarm.fileio import read_versioned_json, write_text_atomic
from busarm.units import check_int_range
from busarm.vision.calibration.camera_model import MODELS, CameraIntrinsics
from busarm.vision.calibration.core import FloatArray, _now, as_transform
from busarm.vision.calibration.handeye import HandEyeResult
from busarm.vision.calibration.intrinsics import IntrinsicsResult

__all__ = [
    "FORMAT_VERSION",
    "HAND_EYE_FORMAT",
    "INTRINSICS_FORMAT",
    "load_hand_eye",
    "load_intrinsics",
    "save_hand_eye",
    "save_intrinsics",
]


INTRINSICS_FORMAT = "busarm.camera_intrinsics"
HAND_EYE_FORMAT = "busarm.hand_eye"
FORMAT_VERSION = 1


def _dumps(data: dict[str, Any], what: str) -> str:
    try:
        return json.dumps(data, indent=1, allow_nan=False) + "\n"
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"cannot write {what}: {exc} (meta values must be JSON data)") from None


def _intrinsics_json(intr: CameraIntrinsics) -> dict[str, Any]:
    return {
        "model": intr.model, "width_px": intr.width_px, "height_px": intr.height_px,
        "camera_matrix": intr.camera_matrix.tolist(), "distortion": intr.distortion.tolist(),
        "calibrated": intr.calibrated,
    }


def save_intrinsics(
    path: Path | str, result_or_intrinsics: IntrinsicsResult | CameraIntrinsics, **meta: Any
) -> None:
    """Write intrinsics (with the calibration's rms, views and board) atomically.

    ``meta`` (JSON values) is kept under "meta"; ``board=`` sets the board description.
    """
    if isinstance(result_or_intrinsics, IntrinsicsResult):
        r = result_or_intrinsics
        intr, rms, views, board = r.intrinsics, r.rms_px, len(r.views_used), r.board
    elif isinstance(result_or_intrinsics, CameraIntrinsics):
        intr, rms, views, board = result_or_intrinsics, None, None, ""
    else:
        raise ConfigError(
            f"save_intrinsics needs an IntrinsicsResult or CameraIntrinsics, got "
            f"{type(result_or_intrinsics).__name__}"
        )
    board = str(meta.pop("board", board))
    data = {
        "format": INTRINSICS_FORMAT, "version": FORMAT_VERSION, "created": _now(),
        **_intrinsics_json(intr), "rms_px": rms, "views": views, "board": board, "meta": meta,
    }
    write_text_atomic(path, _dumps(data, f"camera intrinsics {path}"), "camera intrinsics")


def _read(path: Path | str, what: str, fmt: str) -> tuple[dict[str, Any], str]:
    return read_versioned_json(path, what, fmt, FORMAT_VERSION, CalibrationError)


def _key(data: dict[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise CalibrationError(f"{where}: missing key {key!r}")
    return data[key]


def _number_array(
    data: dict[str, Any], key: str, where: str, shape: tuple[int, ...] | None
) -> FloatArray:
    value = _key(data, key, where)

    def numbers(v: Any) -> bool:
        if isinstance(v, list):
            return all(numbers(x) for x in v)
        return isinstance(v, int | float) and not isinstance(v, bool)

    if not isinstance(value, list) or not numbers(value):
        raise CalibrationError(f"{where}: key {key!r} must be a list of numbers")
    try:
        arr = np.array(value, dtype=np.float64)
    except ValueError:
        raise CalibrationError(f"{where}: key {key!r} is not a rectangular array") from None
    if shape is not None and arr.shape != shape:
        raise CalibrationError(f"{where}: key {key!r} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise CalibrationError(f"{where}: key {key!r} has non-finite numbers")
    return arr


def _optional_number(data: dict[str, Any], key: str, where: str) -> float | None:
    value = data.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise CalibrationError(f"{where}: key {key!r} must be a finite number, got {value!r}")
    return float(value)


def _intrinsics_from_json(data: dict[str, Any], where: str) -> CameraIntrinsics:
    model = _key(data, "model", where)
    if model not in MODELS:
        raise CalibrationError(f"{where}: key 'model' is {model!r}, not one of {', '.join(MODELS)}")
    size = [
        check_int_range(
            f"{where}: key {key!r}", _key(data, key, where), 1, 100_000, "px",
            error=CalibrationError,
        )
        for key in ("width_px", "height_px")
    ]
    k = _number_array(data, "camera_matrix", where, (3, 3))
    d = _number_array(data, "distortion", where, None)
    calibrated = data.get("calibrated", True)
    if not isinstance(calibrated, bool):
        raise CalibrationError(f"{where}: key 'calibrated' must be true or false")
    try:
        return CameraIntrinsics(model, size[0], size[1], k, d, calibrated)
    except ConfigError as exc:
        raise CalibrationError(f"{where}: {exc}") from None


def load_intrinsics(
    path: Path | str, *, expect_size: tuple[int, int] | None = None
) -> CameraIntrinsics:
    """Read a ``busarm.camera_intrinsics`` file.

    ``expect_size`` (width, height): the camera's image size; a file made for another
    size raises CalibrationError saying so. Any problem names the file and the key.
    """
    data, where = _read(path, "camera intrinsics", INTRINSICS_FORMAT)
    intr = _intrinsics_from_json(data, where)
    _optional_number(data, "rms_px", where)
    if expect_size is not None and intr.size != tuple(expect_size):
        w, h = expect_size
        raise CalibrationError(
            f"{where}: made for {intr.width_px}x{intr.height_px} images (keys 'width_px', "
            f"'height_px'), but the camera delivers {w}x{h}: calibrate this camera at {w}x{h}"
        )
    return intr


def save_hand_eye(path: Path | str, result: HandEyeResult, **meta: Any) -> None:
    """Write a hand-eye calibration atomically, with the intrinsics it was made with.

    ``link=`` overrides the link name; other ``meta`` (JSON values) is kept under "meta".
    """
    if not isinstance(result, HandEyeResult):
        raise ConfigError(f"save_hand_eye needs a HandEyeResult, got {type(result).__name__}")
    link = meta.pop("link", result.link)
    if not isinstance(link, str) or not link:
        raise ConfigError(f"link must be a link name, got {link!r}")
    as_transform("cam2link", result.cam2link)
    data = {
        "format": HAND_EYE_FORMAT, "version": FORMAT_VERSION, "created": result.created or _now(),
        "link": link, "cam2link": result.cam2link.tolist(),
        "board2base": result.board2base.tolist(), "rms_px": result.rms_px,
        "per_view_rms_px": list(result.per_view_rms_px), "views_used": list(result.views_used),
        "method": result.method, "translation_std_mm": result.translation_std_mm,
        "rotation_std_deg": result.rotation_std_deg, "pose_rms_deg": result.pose_rms_deg,
        "pose_rms_mm": result.pose_rms_mm,
        "intrinsics": _intrinsics_json(result.intrinsics), "meta": meta,
    }
    write_text_atomic(path, _dumps(data, f"hand-eye {path}"), "hand-eye calibration")


def _rigid_from_json(data: dict[str, Any], key: str, where: str) -> FloatArray:
    t = _number_array(data, key, where, (4, 4))
    try:
        return as_transform(key, t)
    except ConfigError as exc:
        raise CalibrationError(f"{where}: key {key!r}: {exc}") from None


def load_hand_eye(
    path: Path | str, *, intrinsics: CameraIntrinsics | None = None
) -> HandEyeResult:
    """Read a ``busarm.hand_eye`` file.

    With ``intrinsics``: CalibrationError unless they are the ones the hand-eye was made
    with (a hand-eye is only valid with its intrinsics). Any problem names the file
    and the key.
    """
    data, where = _read(path, "hand-eye", HAND_EYE_FORMAT)
    link = _key(data, "link", where)
    if not isinstance(link, str) or not link:
        raise CalibrationError(f"{where}: key 'link' must be a link name, got {link!r}")
    c2l = _rigid_from_json(data, "cam2link", where)
    b2b = _rigid_from_json(data, "board2base", where) if "board2base" in data else np.eye(4)
    raw_intr = _key(data, "intrinsics", where)
    if not isinstance(raw_intr, dict):
        raise CalibrationError(f"{where}: key 'intrinsics' must be an object")
    file_intr = _intrinsics_from_json(raw_intr, f"{where} (key 'intrinsics')")
    if intrinsics is not None and not _same_intrinsics(file_intr, intrinsics):
        raise CalibrationError(
            f"{where}: made with other camera intrinsics (key 'intrinsics': "
            f"{file_intr.describe()}) than the ones given ({intrinsics.describe()}): redo the "
            f"hand-eye calibration with these intrinsics"
        )
    rms = _optional_number(data, "rms_px", where)
    per_view = data.get("per_view_rms_px", [])
    views = data.get("views_used", [])
    if not isinstance(per_view, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        for v in per_view
    ):
        raise CalibrationError(f"{where}: key 'per_view_rms_px' must be a list of numbers")
    if not isinstance(views, list) or not all(
        isinstance(v, int) and not isinstance(v, bool) for v in views
    ):
        raise CalibrationError(f"{where}: key 'views_used' must be a list of integers")
    method = data.get("method", "")
    return HandEyeResult(
        c2l, b2b, math.nan if rms is None else rms, tuple(float(v) for v in per_view),
        tuple(views), file_intr, link, str(method),
        _optional_number(data, "translation_std_mm", where) or 0.0,
        _optional_number(data, "rotation_std_deg", where) or 0.0,
        _optional_number(data, "pose_rms_deg", where) or 0.0,
        _optional_number(data, "pose_rms_mm", where) or 0.0, str(data.get("created", "")),
    )


def _same_intrinsics(a: CameraIntrinsics, b: CameraIntrinsics) -> bool:
    return (
        a.model == b.model and a.size == b.size and a.distortion.shape == b.distortion.shape
        and np.allclose(a.camera_matrix, b.camera_matrix, rtol=1e-9, atol=1e-9)
        and np.allclose(a.distortion, b.distortion, rtol=1e-9, atol=1e-12)
    )
