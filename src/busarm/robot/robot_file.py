"""A robot file: the whole robot (``RobotConfig``) in TOML, written by ``busarm robot init``
and read by ``--robot FILE`` (or ``load_robot_file``).

::

    format = "busarm.robot"
    version = 1
    name = "desk robot"

    [world]                 # kind: serial (hardware), sim, twin or zenoh; then its keys
    kind = "serial"
    device = "/dev/ttyACM0"
    board = true            # the servos behind the controller board

    [arm]                   # config (a shipped name or a file), calibration (a file)
    config = "jetauto_pro"
    [arm.line]              # baudrate, echo (auto/on/off), retries, timeout_margin_s

    [base]                  # chassis (a shipped name or a file); no [base]: no base
    chassis = "jetauto"

    [lidar]                 # model, and device = "/dev/ttyUSB1" or sim = {hz = 10}
    device = "/dev/ttyUSB1"

    [camera]                # source, intrinsics, hand_eye, calibrate, folder
    source = "/dev/video0"

    [bins]                  # colour = [x_mm, y_mm]
    red = [150.0, -120.0]

A twin's ``[world]`` takes ``busarm.twin.spec.TwinSpec``'s keys, a simulator's
``SimSpec``'s, and a ``[world.controller]`` table puts a simulated controller board in
front (``BoardSettings``' keys). Paths are relative to the file's folder. Every key is
checked as the file is read: an unknown key, or a bad value, is one error naming the
file, the key, the value and what is allowed.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from busarm.bus.ports import PortSpec, SerialPort
from busarm.bus.zenoh_link import ZenohPort
from busarm.errors import ConfigError
from busarm.fileio import write_text_atomic
from busarm.robot.description import (
    ArmSpec,
    BaseSpec,
    CameraSpec,
    LidarSpec,
    RobotConfig,
    ServoLine,
)
from busarm.sim.spec import BoardSettings, SimLidarSpec, SimSpec
from busarm.tomlfile import TomlReader, parse_toml, toml_string
from busarm.twin.spec import TwinSpec
from busarm.units import changed_fields

__all__ = [
    "FORMAT_NAME",
    "FORMAT_VERSION",
    "load_robot_file",
    "robot_file_text",
    "save_robot_file",
]

FORMAT_NAME = "busarm.robot"
FORMAT_VERSION = 1
_WORLDS: dict[str, type[Any]] = {"serial": SerialPort, "sim": SimSpec, "twin": TwinSpec,
                                 "zenoh": ZenohPort}
_PATHS = {"scene", "arena", "state", "intrinsics", "hand_eye", "folder"}
_FILES = {"config", "calibration", "chassis"}
"""A shipped name or a file: a file when it has a folder or a suffix."""
_TUPLES = {"ids", "colors"}
_SECTIONS = {"format", "version", "name", "world", "arm", "base", "lidar", "camera", "bins"}


def load_robot_file(path: str | Path) -> tuple[RobotConfig, str]:
    """The robot a robot file describes, and its name."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"robot file {path}: no such file (busarm robot init writes "
                          "one)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"robot file {path}: cannot read it: {exc}") from None
    return _Reader(path).robot(parse_toml(text, what="robot file", source=str(path)))


class _Reader(TomlReader):
    def __init__(self, path: Path) -> None:
        super().__init__("robot file", str(path))
        self.folder = path.parent

    def robot(self, data: dict[str, Any]) -> tuple[RobotConfig, str]:
        self.unknown(data, "top level", _SECTIONS)
        name = self.header(data, FORMAT_NAME, FORMAT_VERSION)
        world = self.world(self.table(data, "world"))
        arm = self.optional(data, "arm")
        line = self.spec(ServoLine, self.optional(arm, "line"), "arm.line")
        arm_spec = self.spec(ArmSpec, {k: v for k, v in arm.items() if k != "line"}, "arm",
                             line=line)
        base = (self.spec(BaseSpec, self.table(data, "base"), "base") if "base" in data
                else None)
        lidar = self.lidar(self.table(data, "lidar"), world) if "lidar" in data else None
        camera = self.spec(CameraSpec, self.optional(data, "camera"), "camera")
        bins = self.bins(self.table(data, "bins")) if "bins" in data else None
        try:
            return RobotConfig(world, arm_spec, base, lidar, camera, bins), name
        except ConfigError as exc:
            raise ConfigError(f"robot file {self.source}: {exc}") from None

    def optional(self, data: dict[str, Any], key: str) -> dict[str, Any]:
        return self.table(data, key) if key in data else {}

    def world(self, table: dict[str, Any]) -> PortSpec:
        kind = table.get("kind")
        if kind not in _WORLDS:
            raise self.fail("world.kind", f"{kind!r}; allowed: {', '.join(_WORLDS)}")
        keys = {k: v for k, v in table.items() if k not in ("kind", "controller")}
        extra = {}
        if "controller" in table:
            if kind not in ("sim", "twin"):
                raise self.fail("world.controller", "a simulated board is for kind sim or "
                                "twin (hardware: kind serial with board = true)")
            extra["controller"] = self.spec(BoardSettings, self.table(table, "controller"),
                                            "world.controller")
        world: PortSpec = self.spec(_WORLDS[kind], keys, "world", **extra)
        return world

    def lidar(self, table: dict[str, Any], world: PortSpec) -> LidarSpec:
        self.unknown(table, "lidar", {"model", "device", "sim", "twin"})
        places = [k for k in ("device", "sim", "twin") if k in table]
        if len(places) != 1:
            raise self.fail("lidar", "give one of device = \"/dev/ttyUSB1\", sim = {...} or "
                            "twin = true")
        port: SerialPort | SimLidarSpec | TwinSpec
        if "device" in table:
            port = self.spec(SerialPort, {"device": table["device"]}, "lidar")
        elif "sim" in table:
            port = self.spec(SimLidarSpec, self.table(table, "sim"), "lidar.sim")
        elif table["twin"] is True and isinstance(world, TwinSpec):
            port = world
        else:
            raise self.fail("lidar.twin", "true, with a twin as the world")
        spec: LidarSpec = self.spec(LidarSpec, {"model": table.get("model", "rplidar-a1")},
                                    "lidar", port=port)
        return spec

    def bins(self, table: dict[str, Any]) -> dict[str, tuple[float, float]]:
        out = {}
        for colour, where in table.items():
            if (not isinstance(where, list) or len(where) != 2
                    or not all(isinstance(v, int | float) for v in where)):
                raise self.fail(f"bins.{colour}", f"must be [x_mm, y_mm], got {where!r}")
            out[colour] = (float(where[0]), float(where[1]))
        return out

    def spec(self, cls: type[Any], table: dict[str, Any], where: str, **given: Any) -> Any:
        """``cls`` made from ``table`` (its fields' keys), errors naming ``where``."""
        known = {f.name for f in dataclasses.fields(cls)} - {"label", *given}
        self.unknown(table, where, known)
        values = {k: self._value(k, v) for k, v in table.items()}
        try:
            return cls(**values, **given)
        except ConfigError as exc:  # its message names its part already: not twice
            raise self.fail(where, str(exc).removeprefix(f"{where.split('.')[0]}: ")) from None
        except TypeError as exc:  # a value of the wrong kind where a check did not look
            raise self.fail(where, str(exc)) from None

    def _value(self, key: str, value: Any) -> Any:
        if key in _PATHS and isinstance(value, str):
            return self.folder / value
        if key in _FILES and isinstance(value, str) and ("/" in value or "." in value):
            return self.folder / value
        if key in _TUPLES and isinstance(value, list):
            return tuple(value)
        return value


def robot_file_text(config: RobotConfig, name: str) -> str:
    """The robot file of ``config`` (its parts that differ from their defaults)."""
    lines = [f"format = {toml_string(FORMAT_NAME)}", f"version = {FORMAT_VERSION}",
             f"name = {toml_string(name)}", ""]
    world = config.world
    kind = next(k for k, cls in _WORLDS.items() if isinstance(world, cls))
    lines += ["[world]", f"kind = {toml_string(kind)}", *_keys(world, skip={"controller"})]
    controller = getattr(world, "controller", None)
    if controller is not None:
        lines += ["", "[world.controller]", *_keys(controller)]
    lines += _section("arm", _keys(config.arm, skip={"line"}))
    lines += _section("arm.line", _keys(config.arm.line))
    if config.base is not None:
        lines += ["", "[base]", f"chassis = {_toml(config.base.chassis)}"]
    if config.lidar is not None:
        lines += ["", "[lidar]", f"model = {toml_string(config.lidar.model)}",
                  *_lidar_place(config.lidar.port, world)]
    lines += _section("camera", _keys(config.camera))
    if config.bins:
        lines += ["", "[bins]", *(f"{toml_string(c)} = [{x!r}, {y!r}]"
                                  for c, (x, y) in config.bins.items())]
    return "\n".join(lines) + "\n"


def save_robot_file(path: str | Path, config: RobotConfig, name: str) -> None:
    """Write ``config`` as a robot file at ``path`` (atomically)."""
    write_text_atomic(path, robot_file_text(config, name), "robot file")


def _section(name: str, keys: list[str]) -> list[str]:
    """A table's lines, none for a table with nothing but defaults."""
    return ["", f"[{name}]", *keys] if keys else []


def _lidar_place(port: Any, world: PortSpec) -> list[str]:
    if isinstance(port, SerialPort):
        return [f"device = {toml_string(port.device)}"]
    if isinstance(port, SimLidarSpec):
        return [f"sim = {{{', '.join(_keys(port))}}}"]
    if port == world:
        return ["twin = true"]
    raise ConfigError("a robot file's Lidar is a device, the simulated A1, or the twin "
                      "that is the world")


def _keys(spec: Any, skip: frozenset[str] | set[str] = frozenset()) -> list[str]:
    """``key = value`` of the fields of ``spec`` that differ from their defaults."""
    return [f"{name} = {_toml(value, name)}" for name, value in changed_fields(spec)
            if name not in skip]


def _toml(value: Any, key: str = "") -> str:
    """``value`` as TOML; ConfigError for one that only lives in Python (a Scene object)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str | Path):
        return toml_string(str(value))
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    source = getattr(value, "source", None)
    raise ConfigError(f"{key}: a {type(value).__name__} cannot go in a robot file; give its "
                      f"file{f' ({source})' if source else ''} instead")
