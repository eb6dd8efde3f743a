"""Where a robot's camera calibration is kept between runs, and what it was made for.

Each robot has a folder in the user's configuration directory,
``$XDG_CONFIG_HOME/busarm/<robot>/`` (``~/.config/busarm/<robot>/`` when XDG_CONFIG_HOME
is not set), holding ``camera.json`` (the intrinsics, ``busarm camera calibrate``) and
``hand_eye.json`` (``busarm camera handeye``), written atomically. ``pick-sort``,
``vision locate`` and the camera commands use them when no file is given; on a twin,
``pick-sort`` makes them when they are missing or stale.

The robot's key (its port's ``robot_key``) is what tells robots apart: ``twin`` for a twin in
this process (whatever stands on its table), ``sim`` for the servo simulator, and for a
serial device its stable name under ``/dev/serial/by-id`` if the system has one (the
USB adapter's own name, the same whichever ``ttyUSBn`` it got), else its path under
``/dev`` (``ttyUSB0``, ``pts-3``); a URL is made safe (``socket-host-4000``).

Every file records what it was made for under ``meta.made_for``: this store's version,
the robot, the picture size, and on a twin its lens; a hand-eye file also the arm (its
config's name and a digest of its geometry, joint zeros and camera mount) and on a twin
where its camera sits. A kept calibration whose record differs from the robot at hand,
or whose file format this busarm does not read, is stale: it is refused, saying what
differs and how to make it again (a twin makes it again itself).
"""

from __future__ import annotations

import hashlib
import json
import shlex
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from busarm.arm.config import ArmConfig
from busarm.bus.ports import PortSpec
from busarm.errors import CalibrationError, ConfigError
from busarm.fileio import read_versioned_json, robot_folder
from busarm.twin.camera import RemoteTwinCamera, TwinOptics
from busarm.twin.lens import LENSES, LensSpec
from busarm.twin.twin import Twin

if TYPE_CHECKING:
    from busarm.robot.twin_calibration import TwinCalibration
from busarm.vision.calibration import (
    FORMAT_VERSION,
    HAND_EYE_FORMAT,
    INTRINSICS_FORMAT,
    CameraIntrinsics,
    HandEyeResult,
    load_hand_eye,
    load_intrinsics,
)
from busarm.vision.camera import CameraSource

STORE_VERSION = 1
"""Bumped when what a kept calibration must match changes: older ones are then stale."""
INTRINSICS_FILE = "camera.json"
HAND_EYE_FILE = "hand_eye.json"


def _arm_record(config: ArmConfig) -> dict[str, str]:
    """The arm as a hand-eye depends on it: its name and a digest of its geometry, its
    joints' zeros and directions, and where its config puts the camera."""
    shape = {"geometry": asdict(config.geometry),
             "joints": [[j.name, j.servo_id, j.angle_at_center_deg, j.direction]
                        for j in config.joints],
             "camera": asdict(config.camera) if config.camera is not None else None}
    text = json.dumps(shape, sort_keys=True)
    return {"config": config.name, "digest": hashlib.sha256(text.encode()).hexdigest()[:16]}


def _jsonable(value: Any) -> Any:
    """``value`` as it reads back from a JSON file (tuples become lists)."""
    return json.loads(json.dumps(value))


@dataclass(frozen=True)
class MadeFor:
    """What a calibration is made for: the record it keeps, and the one it is checked
    against."""

    robot: str
    image_px: tuple[int, int]
    arm: dict[str, str]
    twin_lens: dict[str, Any] | None = None
    twin_mount: list[list[float]] | None = None

    @classmethod
    def for_camera(cls, robot: str, camera: CameraSource, config: ArmConfig,
                   twin: Twin | None = None) -> MadeFor:
        """The record for ``camera`` on ``config``'s arm: a twin's camera (``twin``'s, or
        a served twin's, whose server tells its optics) is recorded with its optics."""
        optics = twin if twin is not None else (
            camera.optics if isinstance(camera, RemoteTwinCamera) else None)
        return cls.of(robot, (camera.width_px, camera.height_px), config, optics)

    @classmethod
    def of(cls, robot: str, image_px: tuple[int, int], config: ArmConfig,
           twin: Twin | TwinOptics | None = None) -> MadeFor:
        """The record for ``robot``'s camera giving ``image_px`` pictures, on ``config``'s
        arm, on ``twin`` (its optics) if it is one."""
        lens = mount = None
        if twin is not None:
            lens = _lens_record(twin.lens)
            mount = [[round(float(v), 6) for v in row] for row in twin.mount.cam2link]
        return cls(robot, (int(image_px[0]), int(image_px[1])), _arm_record(config),
                   _jsonable(lens), mount)

    def intrinsics(self) -> dict[str, Any]:
        """The record a ``camera.json`` keeps."""
        record: dict[str, Any] = _jsonable({"store_version": STORE_VERSION, "robot": self.robot,
                                            "image_px": self.image_px,
                                            "twin_lens": self.twin_lens})
        return record

    def hand_eye(self) -> dict[str, Any]:
        """The record a ``hand_eye.json`` keeps."""
        return {**self.intrinsics(), "arm": self.arm, "twin_mount": self.twin_mount}


class StaleCalibration(CalibrationError):
    """A kept calibration that is not for the robot at hand (or unreadable); the message
    says why and how to make it again, ``why`` only why."""

    def __init__(self, why: str, how: str) -> None:
        super().__init__(f"{why}; {how}")
        self.why = why


def _lens_record(lens: LensSpec) -> dict[str, Any]:
    return {k: getattr(lens, k) for k in ("width_px", "height_px", "fx_px", "fy_px", "cx_px",
                                          "cy_px", "distortion", "oversample")}


def _lens_text(lens: Any) -> str:
    if lens is None:
        return "a camera that is not a twin's"
    for name, spec in LENSES.items():
        if _jsonable(_lens_record(spec)) == lens:
            return f"the twin's {name!r} lens (twin://?lens={name})"
    k1 = lens["distortion"][0] if lens.get("distortion") else 0.0
    return f"a twin lens with fx {lens.get('fx_px')} px, k1 {k1}"


def _describe(key: str, value: Any) -> str:
    """``value`` of a made-for record's ``key`` in words (its repr if it is malformed)."""
    try:
        if key == "robot":
            return f"robot {value!r}"
        if key == "image_px":
            return f"{value[0]}x{value[1]} pictures"
        if key == "twin_lens":
            return _lens_text(value)
        if key == "arm":
            return f"arm config {value['config']!r} (digest {value['digest']})"
        if value is None:
            return "a camera that is not a twin's"
        return (f"a twin camera mounted at ({value[0][3]:.1f}, {value[1][3]:.1f}, "
                f"{value[2][3]:.1f}) mm on its link")
    except (TypeError, IndexError, KeyError, ValueError):
        return repr(value)


def _difference(found: dict[str, Any], wanted: dict[str, Any]) -> str | None:
    """Why a file made for ``found`` does not fit ``wanted``; None if it does."""
    if found.get("store_version") != wanted["store_version"]:
        return (f"it was kept by another busarm (store version {found.get('store_version')}; "
                f"this one keeps version {wanted['store_version']})")
    for key in ("robot", "image_px", "twin_lens", "arm", "twin_mount"):
        if key in wanted and found.get(key) != wanted[key]:
            return (f"it was made for {_describe(key, found.get(key))}, this is "
                    f"{_describe(key, wanted[key])}")
    return None


@dataclass(frozen=True)
class CameraCalibration:
    """The wrist camera's lens (intrinsics) and where it sits on the arm (hand-eye)."""

    intrinsics: CameraIntrinsics
    hand_eye: HandEyeResult
    source: str
    """Where it came from: the files given, "kept in FOLDER", or "calibrated in the twin"."""
    twin_run: TwinCalibration | None = None
    """When it was made in the twin: what that found (errors against the twin's truth)."""

    def __repr__(self) -> str:
        i = self.intrinsics
        return f"CameraCalibration({i.width_px}x{i.height_px}, {self.source})"


class CalibrationStore:
    """A robot's folder of kept camera calibrations (see the module docstring)."""

    def __init__(self, robot: str, folder: Path, port: str | None = None) -> None:
        self.robot = robot
        self.folder = folder
        self.port = port if port is not None else robot
        """The ``--port`` the remaking commands are given in messages."""

    def __repr__(self) -> str:
        return f"CalibrationStore({self.robot!r} in {self.folder})"

    @classmethod
    def for_port(cls, port: PortSpec) -> CalibrationStore:
        """The store of the robot on ``port``, in the user's configuration directory."""
        return cls.for_robot(port.robot_key, port.name)

    @classmethod
    def for_robot(cls, key: str, port: str) -> CalibrationStore:
        """The store of the robot ``key`` (a port's ``robot_key``) in the user's
        configuration directory; ``port`` is how its remaking commands name it."""
        return cls(key, robot_folder(key), port)

    @property
    def intrinsics_path(self) -> Path:
        return self.folder / INTRINSICS_FILE

    @property
    def hand_eye_path(self) -> Path:
        return self.folder / HAND_EYE_FILE

    def has_calibration(self) -> bool:
        """Whether both files are there (not whether they fit: see ``load``)."""
        return self.intrinsics_path.is_file() and self.hand_eye_path.is_file()

    def make_folder(self) -> Path:
        """The folder, made if missing; ConfigError if it cannot be."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(f"cannot make the calibration folder {self.folder}: "
                              f"{exc.strerror or exc}") from None
        return self.folder

    def command(self, step: str) -> str:
        """The command that makes ``step`` (``calibrate`` or ``handeye``) for this robot."""
        return f"busarm --port {shlex.quote(self.port)} camera {step}"

    def how_to_make(self, *, hand_eye_only: bool = False) -> str:
        """Which commands make the calibration (``hand_eye_only``: its second half)."""
        both = (f"`{self.command('handeye')}`" if hand_eye_only else
                f"`{self.command('calibrate')}`, then `{self.command('handeye')}`")
        return f"make it with {both}, or give --intrinsics FILE --hand-eye FILE"

    def missing(self) -> str:
        """What to say when there is no calibration kept for this robot."""
        return (f"no camera calibration is kept for robot {self.robot!r} in {self.folder}/ "
                f"({INTRINSICS_FILE}, {HAND_EYE_FILE}): " + self.how_to_make())

    def _check(self, path: Path, what: str, fmt: str, wanted: dict[str, Any]) -> str:
        """The file's creation time; StaleCalibration if it does not fit ``wanted``."""
        try:
            data, _ = read_versioned_json(path, what, fmt, FORMAT_VERSION, CalibrationError)
        except CalibrationError as exc:
            raise self._stale(str(exc), fmt == HAND_EYE_FORMAT) from None
        meta = data.get("meta")
        found = meta.get("made_for") if isinstance(meta, dict) else None
        if not isinstance(found, dict):
            raise self._stale(f"{what} {path} does not say what it was made for (no "
                              "meta.made_for)", fmt == HAND_EYE_FORMAT)
        why = _difference(found, wanted)
        if why is not None:
            raise self._stale(f"{what} {path} is stale: {why}", fmt == HAND_EYE_FORMAT)
        return str(data.get("created", "?"))

    def _stale(self, why: str, hand_eye_only: bool) -> StaleCalibration:
        return StaleCalibration(why, self.how_to_make(hand_eye_only=hand_eye_only))

    def load_intrinsics(self, made_for: MadeFor) -> CameraIntrinsics:
        """The kept intrinsics; StaleCalibration if they are not for ``made_for``,
        ConfigError if there are none."""
        if not self.intrinsics_path.is_file():
            raise ConfigError(f"no camera intrinsics are kept for robot {self.robot!r} (looked "
                              f"for {self.intrinsics_path}): make them with "
                              f"`{self.command('calibrate')}` (or give --intrinsics FILE)")
        self._check(self.intrinsics_path, "camera intrinsics", INTRINSICS_FORMAT,
                    made_for.intrinsics())
        try:
            return load_intrinsics(self.intrinsics_path)
        except CalibrationError as exc:
            raise self._stale(str(exc), False) from None

    def load(self, made_for: MadeFor) -> tuple[CameraIntrinsics, HandEyeResult, str] | None:
        """The kept intrinsics and hand-eye and when the hand-eye was made; None if there
        are none; StaleCalibration if they are not for ``made_for``."""
        if not self.has_calibration():
            return None
        intr = self.load_intrinsics(made_for)
        created = self._check(self.hand_eye_path, "hand-eye", HAND_EYE_FORMAT,
                              made_for.hand_eye())
        try:
            return intr, load_hand_eye(self.hand_eye_path, intrinsics=intr), created
        except CalibrationError as exc:  # made with other intrinsics, or broken
            raise self._stale(str(exc), True) from None


__all__ = ["HAND_EYE_FILE", "INTRINSICS_FILE", "STORE_VERSION", "CalibrationStore",
           "CameraCalibration", "MadeFor", "StaleCalibration"]
