"""Per-arm joint calibration: where each servo reads when its joint is at a known angle.

A horn is never mounted exactly: at the reference pose (all joints upright) a servo
reads a little off its nominal position. Calibration measures that error per joint and
cancels it, with the servo's own angle offset (+-30 deg, 0.24 deg steps, kept in its
EEPROM) where it fits and the rest, or all of it, in software:

    servo_deg (as read, after the hardware offset)
        = direction * (joint_deg - angle_at_center_deg) + software_offset_deg

File (JSON, written atomically)::

    {"format": "busarm.calibration", "version": 1, "arm": "JetAuto Pro arm",
     "created": "2026-11-22T10:00:00+00:00", "reference_pose_deg": [0, -90, 0, -90, 0],
     "joints": [{"name": "base_yaw", "servo_id": 1, "hardware_offset_pulses": 3,
                 "software_offset_deg": 0.04}, ...]}

At connect the arm checks the file against its config (same joints and servo IDs) and
against each servo's stored offset, so a replaced or re-zeroed servo is caught.
"""

from __future__ import annotations

import datetime as _dt
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TypeGuard

from busarm.arm.config import ArmConfig
from busarm.errors import CalibrationError
from busarm.fileio import read_versioned_json, write_text_atomic
from busarm.protocol.lx_units import DEG_PER_PULSE, OFFSET_MAX_PULSES, OFFSET_MIN_PULSES
from busarm.units import check_int_range, check_range

FORMAT_NAME = "busarm.calibration"
FORMAT_VERSION = 1
SOFTWARE_OFFSET_MAX_DEG = 90.0
"""A larger error means the horn sits on the wrong spline tooth or the wrong joint."""
PLAUSIBLE_ERROR_DEG = 20.0
"""The largest error a horn's mounting plausibly has: a few degrees, or one spline tooth
off (about 14 deg on a 25-tooth spline) and a few more. A joint reading farther from the
reference pose is most likely not in it; ``far_from_reference`` names such joints."""


@dataclass(frozen=True)
class JointCalibration:
    name: str
    servo_id: int
    hardware_offset_pulses: int = 0
    software_offset_deg: float = 0.0

    @property
    def hardware_offset_deg(self) -> float:
        return self.hardware_offset_pulses * DEG_PER_PULSE


@dataclass(frozen=True)
class Calibration:
    """The calibration of one arm: one entry per joint, in the config's order."""

    arm: str
    joints: tuple[JointCalibration, ...]
    reference_pose_deg: tuple[float, ...] = ()
    created: str = ""

    @classmethod
    def identity(cls, config: ArmConfig) -> Calibration:
        """No correction: every servo reads its nominal position."""
        return cls(
            config.name, tuple(JointCalibration(j.name, j.servo_id) for j in config.joints)
        )

    def check_against(self, config: ArmConfig, source: str = "calibration") -> None:
        """Raise CalibrationError unless the joints and servo IDs are the config's."""
        mine = [(j.name, j.servo_id) for j in self.joints]
        theirs = [(j.name, j.servo_id) for j in config.joints]
        if mine != theirs:
            raise CalibrationError(
                f"{source} is for joints {mine}, but the arm config {config.source} has "
                f"{theirs}: calibrate this arm with `busarm arm calibrate`"
            )

    def to_json(self) -> str:
        return json.dumps(
            {
                "format": FORMAT_NAME, "version": FORMAT_VERSION, "arm": self.arm,
                "created": self.created, "reference_pose_deg": list(self.reference_pose_deg),
                "joints": [
                    {"name": j.name, "servo_id": j.servo_id,
                     "hardware_offset_pulses": j.hardware_offset_pulses,
                     "software_offset_deg": round(j.software_offset_deg, 6)}
                    for j in self.joints
                ],
            },
            indent=1, allow_nan=False,
        ) + "\n"


def save_calibration(path: Path | str, calibration: Calibration) -> None:
    """Write ``calibration`` to ``path`` atomically."""
    write_text_atomic(path, calibration.to_json(), "calibration")


def load_calibration(path: Path | str) -> Calibration:
    """Read a calibration file; CalibrationError naming the file and the problem."""
    data, where = read_versioned_json(path, "calibration", FORMAT_NAME, FORMAT_VERSION,
                                      CalibrationError)
    arm = data.get("arm")
    raw_joints = data.get("joints")
    if not isinstance(arm, str) or not isinstance(raw_joints, list):
        raise CalibrationError(f"{where}: needs 'arm' (text) and 'joints' (a list)")
    joints = []
    for i, raw in enumerate(raw_joints, start=1):
        if not isinstance(raw, dict):
            raise CalibrationError(f"{where}: joints[{i}] must be an object")
        name, sid = raw.get("name"), raw.get("servo_id")
        hw, sw = raw.get("hardware_offset_pulses", 0), raw.get("software_offset_deg", 0.0)
        if not isinstance(name, str) or not _is_int(sid) or not 0 <= sid <= 253:
            raise CalibrationError(f"{where}: joints[{i}] needs a name and a servo_id 0..253")
        joint = f"{where}: joints[{i}] ({name})"
        hw = check_int_range(
            f"{joint} hardware_offset_pulses", hw, OFFSET_MIN_PULSES, OFFSET_MAX_PULSES,
            error=CalibrationError,
        )
        sw = check_range(
            f"{joint} software_offset_deg", sw, -SOFTWARE_OFFSET_MAX_DEG, SOFTWARE_OFFSET_MAX_DEG,
            error=CalibrationError,
        )
        joints.append(JointCalibration(name, sid, hw, sw))
    ref = data.get("reference_pose_deg", [])
    if not isinstance(ref, list) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in ref
    ):
        raise CalibrationError(f"{where}: reference_pose_deg must be a list of numbers")
    created = data.get("created", "")
    return Calibration(arm, tuple(joints), tuple(float(v) for v in ref), str(created))


def solve_calibration(
    config: ArmConfig,
    reference_pose_deg: Sequence[float],
    measured_servo_deg: Mapping[int, float],
    present_hardware_offset_pulses: Mapping[int, int],
    *,
    use_hardware_offset: bool = True,
) -> Calibration:
    """The calibration that makes the measured reference pose read as ``reference_pose_deg``.

    ``measured_servo_deg``: each joint servo's reading (degrees from its mid-point)
    with the arm held at the reference pose, taken under the servo's present hardware
    offset. The error goes into the hardware offset if it fits in +-30 deg (and
    ``use_hardware_offset``), the rounding rest into the software offset; otherwise all
    of it into the software offset with the hardware offset 0.
    """
    reference = config.check_joints(reference_pose_deg)
    joints = []
    for j, ref in zip(config.joints, reference, strict=True):
        if j.servo_id not in measured_servo_deg:
            raise CalibrationError(f"no reading for {j.name} (servo {j.servo_id})")
        present_hw = present_hardware_offset_pulses.get(j.servo_id, 0)
        # The horn's reading with no offset at all, and the reading we want there.
        raw_deg = measured_servo_deg[j.servo_id] + present_hw * DEG_PER_PULSE
        want_deg = j.servo_deg_from_angle_deg(ref)
        error_deg = raw_deg - want_deg
        if abs(error_deg) > SOFTWARE_OFFSET_MAX_DEG:
            raise CalibrationError(
                f"{j.name} (servo {j.servo_id}) reads {error_deg:+.1f} deg off its reference "
                f"angle {ref:g} deg: more than {SOFTWARE_OFFSET_MAX_DEG:g} deg means the arm is "
                f"not in the reference pose or the horn is on the wrong spline tooth"
            )
        hw = round(error_deg / DEG_PER_PULSE)
        if not use_hardware_offset or not OFFSET_MIN_PULSES <= hw <= OFFSET_MAX_PULSES:
            hw = 0
        joints.append(
            JointCalibration(j.name, j.servo_id, hw, error_deg - hw * DEG_PER_PULSE)
        )
    created = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    return Calibration(config.name, tuple(joints), reference, created)


def far_from_reference(
    config: ArmConfig, calibration: Calibration, threshold_deg: float = PLAUSIBLE_ERROR_DEG,
) -> list[str]:
    """Each joint whose correction in ``calibration`` exceeds ``threshold_deg``, as text:
    the joint, the angle its servo reads (with no offset), the reference angle."""
    out = []
    reference = calibration.reference_pose_deg
    for j, c, ref in zip(config.joints, calibration.joints, reference, strict=True):
        error_deg = c.hardware_offset_deg + c.software_offset_deg  # in servo degrees
        if abs(error_deg) > threshold_deg:
            read_deg = ref + j.direction * error_deg  # the joint angle the servo reads
            out.append(f"{j.name} (servo {j.servo_id}) reads {read_deg:.1f} deg, the "
                       f"reference pose has {ref:g} deg: {abs(error_deg):.1f} deg off")
    return out


def _is_int(value: object) -> TypeGuard[int]:
    return isinstance(value, int) and not isinstance(value, bool)


__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "PLAUSIBLE_ERROR_DEG",
    "Calibration",
    "JointCalibration",
    "far_from_reference",
    "load_calibration",
    "save_calibration",
    "solve_calibration",
]
