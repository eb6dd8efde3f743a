"""The arm's description from a TOML file: joints, servo IDs, pulse maps, limits, links.

One file describes one arm of the family (base yaw, shoulder, elbow and wrist pitch,
wrist roll, gripper). ``load_arm_config("jetauto_pro")`` gives the shipped JetAuto Pro
arm; any other path is read as a file. Every value is checked when the file is read,
and an error names the file, the key, the bad value and the allowed range.

Conventions (docs/design.md, "Arm"): joint angles are the thetas of the modified-DH
model in degrees; the servo position of a joint is
``pulses = 500 + direction * (angle_deg - angle_at_center_deg) / 0.24``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from busarm.errors import ConfigError, LimitError
from busarm.protocol.lx_units import (
    CENTER_PULSES,
    DEG_PER_PULSE,
    MOVE_TIME_MAX_MS,
    POSITION_MAX_DEG,
    POSITION_MAX_PULSES,
    POSITION_MIN_DEG,
    POSITION_MIN_PULSES,
)
from busarm.tomlfile import TomlReader, load_toml, parse_toml
from busarm.units import plain_number, range_text, shown

FORMAT_NAME = "busarm.arm"
FORMAT_VERSION = 1
JOINT_COUNT = 5
JOINT_ROLES = ("base yaw", "shoulder pitch", "elbow pitch", "wrist pitch", "wrist roll")
SHIPPED = ("jetauto_pro",)
DEFAULT_ARM = "jetauto_pro"
BASE_KEEPOUT_RADIUS_MM = 70.0
"""Default radius of the keep-out round the base axis (``[workspace]``
``base_keepout_radius_mm``): the twin's base disc is 45 mm across the axis, plus 25 mm
for the finger pads beside the tool point. Blocks stand 90 mm or more from the axis (the
twin's scene rule), so every block the arm can take stays outside it."""


CAMERA_JOINT_INDEX = 3
"""The wrist camera rides the link of the fourth joint, the wrist pitch (DH frame 4)."""

@dataclass(frozen=True)
class JointConfig:
    """One joint: its servo, the pulse map and the limits, in degrees."""

    name: str
    servo_id: int
    angle_at_center_deg: float
    direction: int
    min_deg: float
    max_deg: float
    max_speed_deg_s: float

    def servo_deg_from_angle_deg(self, angle_deg: float) -> float:
        """The servo's angle from its mid-point (uncalibrated) for a joint angle."""
        return self.direction * (angle_deg - self.angle_at_center_deg)

    def angle_deg_from_servo_deg(self, servo_deg: float) -> float:
        """The joint angle for the servo's angle from its mid-point (uncalibrated)."""
        return self.angle_at_center_deg + self.direction * servo_deg

    def pulses_from_angle_deg(self, angle_deg: float) -> float:
        """Servo position in (fractional) pulses for a joint angle, uncalibrated."""
        return CENTER_PULSES + self.servo_deg_from_angle_deg(angle_deg) / DEG_PER_PULSE

    def angle_deg_from_pulses(self, position_pulses: float) -> float:
        """Joint angle for a servo position in pulses, uncalibrated."""
        return self.angle_deg_from_servo_deg((position_pulses - CENTER_PULSES) * DEG_PER_PULSE)

    def check_angle(self, angle_deg: float, tolerance_deg: float = 1e-9) -> None:
        """Raise LimitError naming the joint if ``angle_deg`` is outside its limits."""
        if isinstance(angle_deg, bool) or not isinstance(angle_deg, int | float):
            raise ConfigError(f"{self.name} angle must be a number of degrees, got "
                              f"{shown(angle_deg)}")
        if not math.isfinite(angle_deg):
            raise LimitError(f"{self.name} = {angle_deg} is not a finite number of degrees")
        if not (
            self.min_deg - tolerance_deg <= angle_deg <= self.max_deg + tolerance_deg
        ):
            raise LimitError(
                f"{self.name} = {angle_deg:.3f} deg is outside its limits "
                f"{range_text(self.min_deg, self.max_deg, 'deg')}"
            )


@dataclass(frozen=True)
class GripperConfig:
    """The gripper servo: open and closed positions in pulses."""

    servo_id: int
    open_pulses: int
    closed_pulses: int
    grip_time_s: float
    holding_margin_pulses: int
    gap_mm_per_pulse: float = 0.1875
    """How much the fingers' gap changes per pulse; the fingers touch at ``closed_pulses``."""
    pad_mm: tuple[float, float, float] = (10.0, 16.0, 36.0)
    """One finger pad's thickness (along the closing axis), width and length (along the
    tool): what a grasp must find room for beside a block."""

    @property
    def min_pulses(self) -> int:
        return min(self.open_pulses, self.closed_pulses)

    @property
    def max_pulses(self) -> int:
        return max(self.open_pulses, self.closed_pulses)

    def pulses_for_gap_mm(self, gap_mm: float) -> int:
        """The position that opens the fingers ``gap_mm`` apart (rounded toward wider),
        within open..closed."""
        if not (isinstance(gap_mm, int | float) and math.isfinite(gap_mm) and gap_mm >= 0):
            raise ConfigError(f"gripper gap {gap_mm!r} mm must be a number >= 0")
        sign = 1 if self.closed_pulses >= self.open_pulses else -1
        pulses = self.closed_pulses - sign * math.ceil(gap_mm / self.gap_mm_per_pulse)
        return min(self.max_pulses, max(self.min_pulses, pulses))

    def gap_mm_at(self, position_pulses: float) -> float:
        """How far apart the fingers are at ``position_pulses`` (0 at closed or beyond)."""
        sign = 1.0 if self.closed_pulses >= self.open_pulses else -1.0
        return max(0.0, sign * (self.closed_pulses - position_pulses) * self.gap_mm_per_pulse)

    @property
    def widest_gap_mm(self) -> float:
        """The fingers' gap at ``open_pulses``: as wide as the gripper is told to open."""
        return self.gap_mm_at(self.open_pulses)

    def check_pulses(self, position_pulses: int) -> None:
        """Raise LimitError if a gripper position is outside open..closed."""
        if isinstance(position_pulses, bool) or not isinstance(position_pulses, int):
            raise ConfigError(f"gripper position must be whole pulses, got {position_pulses!r}")
        if not self.min_pulses <= position_pulses <= self.max_pulses:
            raise LimitError(
                f"gripper position {position_pulses} pulses is outside "
                f"{self.min_pulses}..{self.max_pulses} (open {self.open_pulses}, "
                f"closed {self.closed_pulses})"
            )


@dataclass(frozen=True)
class Geometry:
    """Link lengths in millimetres (see the DH table in docs/design.md)."""

    base_height_mm: float
    upper_arm_mm: float
    forearm_mm: float
    wrist_mm: float
    tool_mm: float

    @property
    def wrist_to_tip_mm(self) -> float:
        """Wrist pitch axis to the tool point, along the tool axis."""
        return self.wrist_mm + self.tool_mm


@dataclass(frozen=True)
class CameraConfig:
    """Where the wrist camera sits as drawn (``[camera]``): fixed to ``link``'s frame (the
    wrist pitch joint's), ``behind_mm`` behind and ``above_mm`` above its axis, looking
    along the tool and tilted ``tilt_deg`` toward it. For planning views and building the
    twin; where a real camera sits comes from hand-eye calibration."""

    link: str
    behind_mm: float
    above_mm: float
    tilt_deg: float = 0.0


@dataclass(frozen=True)
class ArmConfig:
    """A whole arm, as read from its TOML file."""

    name: str
    geometry: Geometry
    joints: tuple[JointConfig, ...]
    gripper: GripperConfig
    table_z_mm: float = 0.0
    preferred_pitch_deg: float = -90.0
    base_keepout_radius_mm: float = BASE_KEEPOUT_RADIUS_MM
    """The tool point keeps at least this far from the base axis below
    ``base_keepout_top_z_mm``: the base, its column and the shoulder servo stand there."""
    base_keepout_top_z_mm: float | None = None
    """The top of that keep-out cylinder in the base frame; None: the shoulder axis
    (``geometry.base_height_mm``)."""
    poses_deg: dict[str, tuple[float, ...]] = field(default_factory=dict)
    action_columns: tuple[int, ...] = ()
    source: str = "<memory>"
    camera: CameraConfig | None = None
    """The wrist camera's mount, if the arm has one."""

    @property
    def joint_ids(self) -> tuple[int, ...]:
        return tuple(j.servo_id for j in self.joints)

    @property
    def base_keepout_mm(self) -> tuple[float, float]:
        """(radius, top z) of the cylinder round the base axis the tool point keeps out of."""
        top = self.base_keepout_top_z_mm
        return (self.base_keepout_radius_mm,
                self.geometry.base_height_mm if top is None else top)

    @property
    def servo_ids(self) -> tuple[int, ...]:
        """Every servo of the arm: the joints, then the gripper."""
        return (*self.joint_ids, self.gripper.servo_id)

    @property
    def limits_deg(self) -> tuple[tuple[float, float], ...]:
        return tuple((j.min_deg, j.max_deg) for j in self.joints)

    def servo_range_deg(self, servo_id: int) -> tuple[str, float, float] | None:
        """What this arm allows servo ``servo_id`` as a servo angle (deg from its mid-point,
        uncalibrated): the part's name (a joint's, or ``gripper``) and min..max; None if the
        servo is not one of the arm's."""
        for j in self.joints:
            if j.servo_id == servo_id:
                a, b = j.servo_deg_from_angle_deg(j.min_deg), j.servo_deg_from_angle_deg(j.max_deg)
                return (j.name, max(min(a, b), POSITION_MIN_DEG), min(max(a, b), POSITION_MAX_DEG))
        g = self.gripper
        if g.servo_id == servo_id:
            return ("gripper", (g.min_pulses - CENTER_PULSES) * DEG_PER_PULSE,
                    (g.max_pulses - CENTER_PULSES) * DEG_PER_PULSE)
        return None

    def joint(self, name_or_index: str | int) -> JointConfig:
        """A joint by name or by 1-based number (1 = base yaw)."""
        if isinstance(name_or_index, int) and not isinstance(name_or_index, bool):
            if not 1 <= name_or_index <= len(self.joints):
                raise ConfigError(
                    f"joint number {name_or_index} is out of range 1..{len(self.joints)}"
                )
            return self.joints[name_or_index - 1]
        for j in self.joints:
            if j.name == name_or_index:
                return j
        raise ConfigError(
            f"no joint named {name_or_index!r}; joints: {', '.join(j.name for j in self.joints)}"
        )

    def pose(self, name: str) -> tuple[float, ...]:
        """A named joint pose from the file's [poses] table (``home``, ``upright``...)."""
        try:
            return self.poses_deg[name]
        except KeyError:
            raise ConfigError(
                f"no pose named {name!r} in {self.source}; poses: {', '.join(self.poses_deg)}"
            ) from None

    def check_joints(self, angles_deg: object) -> tuple[float, ...]:
        """Return five joint angles as floats, or raise naming the first bad one."""
        if isinstance(angles_deg, str | bytes) or not hasattr(angles_deg, "__len__"):
            raise ConfigError(f"joint angles must be {JOINT_COUNT} numbers, got "
                              f"{shown(angles_deg)}")
        values = list(angles_deg)  # type: ignore[call-overload]
        if len(values) != len(self.joints):
            given = ", ".join(plain_number(v) if isinstance(v, int | float) else shown(v)
                              for v in values)
            raise ConfigError(f"expected {len(self.joints)} joint angles in deg, got "
                              f"{len(values)}: {given}")
        for j, v in zip(self.joints, values, strict=True):
            j.check_angle(v)
        return tuple(float(v) for v in values)


# ---------------------------------------------------------------------- loading


def deck_mounted(config: ArmConfig, joint: str = "shoulder_pitch") -> ArmConfig:
    """The arm on the mobile base's deck: ``joint`` may turn down to its servo's end.

    The table arm's shoulder stops at horizontal (the vendor's IK limit there: below it the
    arm would reach under its own table). On the JetAuto's deck, 145 mm above the floor,
    the fingertips reach the floor only with the shoulder below horizontal, as the
    vendor's floor games do: up to the servo's end (pulse 0 or 1000, +30 deg here)."""
    def widened(j: JointConfig) -> JointConfig:
        if j.name != joint:
            return j
        ends = sorted(j.angle_deg_from_pulses(p) for p in (POSITION_MIN_PULSES,
                                                          POSITION_MAX_PULSES))
        return replace(j, max_deg=max(j.max_deg, ends[1]))  # downward: the floor ahead

    names = [j.name for j in config.joints]
    if joint not in names:
        raise ConfigError(f"{config.name} has no joint {joint!r}; its joints: {', '.join(names)}")
    return replace(config, joints=tuple(widened(j) for j in config.joints))


def load_arm_config(name_or_path: str | Path = DEFAULT_ARM) -> ArmConfig:
    """A shipped arm by name (``jetauto_pro``) or any TOML file by path."""
    data, source = load_toml(name_or_path, what="arm config", package="busarm.arm",
                             shipped=SHIPPED)
    return _Reader(source).arm(data)


def arm_config_from_toml(text: str, source: str = "<string>") -> ArmConfig:
    """Parse and check an arm description; errors name ``source`` and the key."""
    return _Reader(source).arm(parse_toml(text, what="arm config", source=source))


class _Reader(TomlReader):
    def __init__(self, source: str) -> None:
        super().__init__("arm config", source)

    def arm(self, data: dict[str, Any]) -> ArmConfig:
        self.unknown(
            data, "top level",
            {"format", "version", "name", "geometry", "workspace", "joints", "gripper", "poses",
             "action_groups", "camera"},
        )
        name = self.header(data, FORMAT_NAME, FORMAT_VERSION)
        geometry = self.geometry(self.table(data, "geometry"))
        workspace = data.get("workspace", {})
        if not isinstance(workspace, dict):
            raise self.fail("workspace", "must be a table")
        self.unknown(workspace, "workspace", {"table_z_mm", "preferred_pitch_deg",
                                              "base_keepout_radius_mm", "base_keepout_top_z_mm"})
        table_z = self.number(workspace, "table_z_mm", "workspace", -1000, 1000, 0.0)
        preferred = self.number(workspace, "preferred_pitch_deg", "workspace", -180, 180, -90.0)
        # An older config without these keeps the default cylinder (up to the shoulder axis).
        keepout_r = self.number(workspace, "base_keepout_radius_mm", "workspace", 0, 500,
                                BASE_KEEPOUT_RADIUS_MM)
        keepout_top = (self.number(workspace, "base_keepout_top_z_mm", "workspace", -1000, 1000)
                       if "base_keepout_top_z_mm" in workspace else None)
        joints = self.joints(data.get("joints"))
        gripper = self.gripper(self.table(data, "gripper"))
        ids = [j.servo_id for j in joints] + [gripper.servo_id]
        if len(set(ids)) != len(ids):
            raise self.fail("servo_id", f"servo IDs must be distinct, got {ids}")
        poses = self.poses(data.get("poses", {}), joints)
        columns = self.columns(data.get("action_groups", {}), ids)
        camera = self.camera(data["camera"], joints) if "camera" in data else None
        if geometry.base_height_mm <= geometry.upper_arm_mm:
            # Then the elbow could reach the table plane, which the IK does not check.
            raise self.fail(
                "geometry.base_height_mm",
                f"{geometry.base_height_mm:g} must exceed upper_arm_mm "
                f"{geometry.upper_arm_mm:g} (the elbow must stay above the base plane)",
            )
        return ArmConfig(
            name=name.strip(), geometry=geometry, joints=tuple(joints), gripper=gripper,
            table_z_mm=table_z, preferred_pitch_deg=preferred, poses_deg=poses,
            base_keepout_radius_mm=keepout_r, base_keepout_top_z_mm=keepout_top,
            action_columns=columns, source=self.source, camera=camera,
        )

    def camera(self, data: object, joints: list[JointConfig]) -> CameraConfig:
        if not isinstance(data, dict):
            raise self.fail("camera", "must be a table")
        self.unknown(data, "camera", {"link", "behind_mm", "above_mm", "tilt_deg"})
        # The camera's frame is the wrist pitch joint's (DH frame 4): the tool axis and
        # "above" are defined there (busarm.arm.camera_mount).
        wrist = joints[CAMERA_JOINT_INDEX].name
        if data.get("link") != wrist:
            raise self.fail("camera.link", f"{data.get('link')!r}; the wrist camera rides the "
                                           f"wrist pitch joint's link: {wrist!r}")
        return CameraConfig(
            link=wrist, behind_mm=self.number(data, "behind_mm", "camera", -300.0, 300.0),
            above_mm=self.number(data, "above_mm", "camera", -300.0, 300.0),
            tilt_deg=self.number(data, "tilt_deg", "camera", -90.0, 90.0, 0.0))

    def geometry(self, data: dict[str, Any]) -> Geometry:
        keys = ("base_height_mm", "upper_arm_mm", "forearm_mm", "wrist_mm", "tool_mm")
        self.unknown(data, "geometry", set(keys))
        values = {k: self.number(data, k, "geometry", 0.0, 2000.0) for k in keys}
        for k in ("upper_arm_mm", "forearm_mm", "tool_mm"):
            if values[k] <= 0:
                raise self.fail(f"geometry.{k}", f"{values[k]:g} must be > 0")
        return Geometry(**values)

    def joints(self, data: object) -> list[JointConfig]:
        if not isinstance(data, list) or len(data) != JOINT_COUNT:
            raise self.fail(
                "joints",
                f"need exactly {JOINT_COUNT} [[joints]] tables in order: {', '.join(JOINT_ROLES)}",
            )
        out = []
        names: set[str] = set()
        keys = {"name", "servo_id", "angle_at_center_deg", "direction", "min_deg", "max_deg",
                "max_speed_deg_s"}
        for i, raw in enumerate(data, start=1):
            where = f"joints[{i}] ({JOINT_ROLES[i - 1]})"
            if not isinstance(raw, dict):
                raise self.fail(where, "must be a table")
            self.unknown(raw, where, keys)
            name = raw.get("name", f"joint{i}")
            if not isinstance(name, str) or not name or name in names:
                raise self.fail(
                    f"{where}.name", f"must be a distinct non-empty string, got {name!r}"
                )
            names.add(name)
            direction = raw.get("direction")
            if direction not in (1, -1) or isinstance(direction, bool):
                raise self.fail(f"{where}.direction", f"must be 1 or -1, got {shown(direction)}")
            joint = JointConfig(
                name=name,
                servo_id=self.integer(raw, "servo_id", where, 0, 253),
                angle_at_center_deg=self.number(raw, "angle_at_center_deg", where, -360, 360),
                direction=direction,
                min_deg=self.number(raw, "min_deg", where, -360, 360),
                max_deg=self.number(raw, "max_deg", where, -360, 360),
                max_speed_deg_s=self.number(raw, "max_speed_deg_s", where, 1.0, 1000.0),
            )
            if joint.min_deg >= joint.max_deg:
                raise self.fail(
                    where, f"min_deg {joint.min_deg:g} must be less than max_deg {joint.max_deg:g}"
                )
            for limit in (joint.min_deg, joint.max_deg):
                p = joint.pulses_from_angle_deg(limit)
                if not POSITION_MIN_PULSES - 1e-9 <= p <= POSITION_MAX_PULSES + 1e-9:
                    raise self.fail(
                        where,
                        f"limit {limit:g} deg maps to {p:.1f} pulses, outside the servo's "
                        f"{POSITION_MIN_PULSES}..{POSITION_MAX_PULSES}",
                    )
            out.append(joint)
        return out

    def gripper(self, data: dict[str, Any]) -> GripperConfig:
        keys = {"servo_id", "open_pulses", "closed_pulses", "grip_time_s", "holding_margin_pulses",
                "gap_mm_per_pulse", "pad_thickness_mm", "pad_width_mm", "pad_length_mm"}
        self.unknown(data, "gripper", keys)
        g = GripperConfig(
            servo_id=self.integer(data, "servo_id", "gripper", 0, 253),
            open_pulses=self.integer(
                data, "open_pulses", "gripper", POSITION_MIN_PULSES, POSITION_MAX_PULSES
            ),
            closed_pulses=self.integer(
                data, "closed_pulses", "gripper", POSITION_MIN_PULSES, POSITION_MAX_PULSES
            ),
            grip_time_s=self.number(data, "grip_time_s", "gripper", 0.05, MOVE_TIME_MAX_MS / 1000),
            holding_margin_pulses=self.integer(
                data, "holding_margin_pulses", "gripper", 1, 500, 20
            ),
            gap_mm_per_pulse=self.number(data, "gap_mm_per_pulse", "gripper", 0.01, 5.0, 0.1875),
            pad_mm=(self.number(data, "pad_thickness_mm", "gripper", 1.0, 50.0, 10.0),
                    self.number(data, "pad_width_mm", "gripper", 1.0, 100.0, 16.0),
                    self.number(data, "pad_length_mm", "gripper", 1.0, 200.0, 36.0)),
        )
        if abs(g.open_pulses - g.closed_pulses) <= g.holding_margin_pulses:
            raise self.fail(
                "gripper",
                f"open_pulses {g.open_pulses} and closed_pulses {g.closed_pulses} must be more "
                f"than holding_margin_pulses {g.holding_margin_pulses} apart",
            )
        return g

    def poses(
        self, data: object, joints: list[JointConfig]
    ) -> dict[str, tuple[float, ...]]:
        if not isinstance(data, dict):
            raise self.fail("poses", "must be a table")
        out: dict[str, tuple[float, ...]] = {}
        for key, value in data.items():
            if not key.endswith("_deg"):
                raise self.fail(f"poses.{key}", "pose names end in _deg (joint angles in degrees)")
            if not isinstance(value, list) or len(value) != len(joints) or not all(
                isinstance(v, int | float) and not isinstance(v, bool) for v in value
            ):
                raise self.fail(f"poses.{key}", f"must be {len(joints)} numbers, got {value!r}")
            for j, v in zip(joints, value, strict=True):
                try:
                    j.check_angle(float(v))
                except ConfigError as exc:
                    raise self.fail(f"poses.{key}", str(exc)) from None
            out[key.removesuffix("_deg")] = tuple(float(v) for v in value)
        if "home" not in out:
            raise self.fail("poses.home_deg", "missing (the pose `busarm arm home` goes to)")
        return out

    def columns(self, data: object, ids: list[int]) -> tuple[int, ...]:
        if not isinstance(data, dict):
            raise self.fail("action_groups", "must be a table")
        self.unknown(data, "action_groups", {"columns"})
        columns = data.get("columns", ids)
        if not isinstance(columns, list) or not columns or not all(
            isinstance(c, int) and not isinstance(c, bool) for c in columns
        ):
            raise self.fail(
                "action_groups.columns", f"must be a list of servo IDs, got {columns!r}"
            )
        unknown = [c for c in columns if c not in ids]
        if unknown or len(set(columns)) != len(columns):
            raise self.fail(
                "action_groups.columns",
                f"{columns} must be distinct servo IDs of this arm ({ids})",
            )
        return tuple(columns)


__all__ = [
    "DEFAULT_ARM",
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "JOINT_COUNT",
    "SHIPPED",
    "ArmConfig",
    "CameraConfig",
    "Geometry",
    "GripperConfig",
    "JointConfig",
    "arm_config_from_toml",
    "deck_mounted",
    "load_arm_config",
]
