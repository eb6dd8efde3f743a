"""The dashboard's WebSocket messages: JSON objects with a ``type``, as dataclasses.

Pure: no I/O. ``parse_request`` turns the text a page sent into one typed request, or
raises RequestError naming the bad field and what is allowed; the server answers that
with an ``error`` message and moves nothing. Ranges here are the message's own (a jog's
speed fraction, a servo ID); the robot's limits are checked where the move is made,
through the same checks as the command line.

Page -> server (``type``: fields):

============= =============================================================== ==========
heartbeat     (none): sent every 100 ms; a jog stops when none came for 300 ms
drive         take the driver's seat (``take_over``: true to take it from another page)
release       leave it
jog           ``joint`` (a joint name) or ``axis`` (x, y, z, pitch), ``direction``
              (+1/-1), ``speed`` (0.05..1 of the jog speed): move until ``jog_stop``,
              or until the driver falls silent (no message for 300 ms: the deadman)
jog_stop      stop a jog now (the key or button was released, the page lost focus)
move_pose     ``name``: go to a named pose (the config's or saved ones)
save_pose     ``name``: keep the present joints under that name
gripper       ``action``: open, or close (until the fingers meet or hold something)
torque        ``servo`` (an arm servo's ID) and ``on`` (bool)
play          ``group``: an action group (a shipped sample or a recorded one) by name
record        ``action``: start, frame (the present pose, ``duration_ms`` after the last),
              save (``name``), or cancel
pick_sort     ``colors`` (list), ``order`` (nearest, colors), ``by`` (color, size, tag:
              what decides a block's bin)
transport     ``pick``, ``place`` (named points; default pick, place), ``color``
              (optional): fetch a block from one point and deliver it to the other (a
              twin in an arena with no points file explores to map it first)
base_drive    ``vx_m_s`` (forward), ``vy_m_s`` (left), ``wz_rad_s`` (counter-clockwise),
              within the base's limits (the robot's ``base`` in ``welcome``): drive
              at that twist until ``base_stop``, or until the driver falls silent
              (no message for 250 ms: the deadman; the wheels stop)
base_stop     stop the wheels now (the key or button was released)
name_point    ``name``, ``x_m``, ``y_m``, ``yaw_deg``: a named point on the map (for
              transport), kept in the points file
localise      find where the base stands on the map (it does not move): near ``x_m``,
              ``y_m``, ``yaw_deg`` (a person's guess, all three), else near where the
              odometry has carried it since a job last knew
line_follow   ``laps`` (0.05..100), ``speed_m_s`` (0.01..0.5), ``colors`` (list, maybe
              empty: block colours cleared off the line)
stop          stop the job and any motion, holding (not latched)
estop         halt: MOVE_STOP to every servo, cancel the job, latched until ``rearm``
rearm         allow motion again after an e-stop
============= =============================================================== ==========

Server -> page: ``welcome`` (the robot's description and this page's role), ``state``
(live values, about 20 times a second; ``map``: the number of the newest map picture,
``GET /map.png``), ``log`` (what happened), ``error`` (a request refused, and why),
``role`` (this page drives or watches), ``job`` (a job's progress and end).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from busarm.errors import ConfigError

__all__ = [
    "DEFAULT_CLEAR_COLORS",
    "GRIPPER_ACTIONS",
    "JOG_AXES",
    "LAPS_RANGE",
    "LINE_SPEED_RANGE_M_S",
    "MAX_BASE_NUMBER",
    "MAX_MESSAGE_BYTES",
    "MIN_JOG_SPEED",
    "NAME_CHARS",
    "PICK_BY",
    "PICK_ORDERS",
    "RECORD_ACTIONS",
    "BaseDrive",
    "Drive",
    "Gripper",
    "Jog",
    "LineFollow",
    "Localise",
    "NamePoint",
    "Named",
    "NavTransport",
    "PickSort",
    "Record",
    "Request",
    "RequestError",
    "Torque",
    "message",
    "parse_request",
    "request_type",
]


MAX_MESSAGE_BYTES = 4096
"""A request longer than this is refused unread (no request needs more)."""
JOG_AXES = ("x", "y", "z", "pitch")
GRIPPER_ACTIONS = ("open", "close")
RECORD_ACTIONS = ("start", "frame", "save", "cancel")
PICK_ORDERS = ("nearest", "colors")
PICK_BY = ("color", "size", "tag")
"""What decides a block's bin (``busarm.apps.pick_sort.rules.SORT_BY``)."""
LAPS_RANGE = (0.05, 100.0)
LINE_SPEED_RANGE_M_S = (0.01, 0.5)
DEFAULT_CLEAR_COLORS = ("red", "green", "blue")
MIN_JOG_SPEED = 0.05
MAX_BASE_NUMBER = 1e3
"""A base request's numbers beyond this are refused as nonsense here; the base's own
limits are checked where the wheels are driven (busarm.dashboard.service)."""
NAME_CHARS = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-."


class RequestError(ConfigError):
    """A message from a page that is not a valid request (the text says why)."""


@dataclass(frozen=True)
class Request:
    """Any request; ``type`` is its wire name."""

    type: str


@dataclass(frozen=True)
class Drive(Request):
    take_over: bool = False


@dataclass(frozen=True)
class Jog(Request):
    joint: str | None
    axis: str | None
    direction: int
    speed: float


@dataclass(frozen=True)
class BaseDrive(Request):
    """``base_drive``: the base at this twist (m/s forward and left, rad/s)."""

    vx_m_s: float
    vy_m_s: float
    wz_rad_s: float


@dataclass(frozen=True)
class NamePoint(Request):
    """``name_point``: a named point on the map (m, its frame; heading in deg)."""

    name: str
    x_m: float
    y_m: float
    yaw_deg: float = 0.0


@dataclass(frozen=True)
class Localise(Request):
    """``localise``: where the base is on the map, near ``near`` (m, m, deg) if given."""

    near: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Named(Request):
    """``move_pose``, ``save_pose`` and ``play``: a request naming a thing."""

    name: str


@dataclass(frozen=True)
class Gripper(Request):
    action: str


@dataclass(frozen=True)
class Torque(Request):
    servo: int
    on: bool


@dataclass(frozen=True)
class Record(Request):
    action: str
    name: str | None = None
    duration_ms: int = 1000


@dataclass(frozen=True)
class PickSort(Request):
    colors: tuple[str, ...] = ("red", "green", "blue")
    order: str = "nearest"
    by: str = "color"


@dataclass(frozen=True)
class NavTransport(Request):
    """``transport``: a block fetched from point ``pick`` and delivered to ``place``."""

    pick: str = "pick"
    place: str = "place"
    color: str | None = None


@dataclass(frozen=True)
class LineFollow(Request):
    """``line_follow``: round the floor loop ``laps`` times, clearing ``colors`` blocks."""

    laps: float = 1.0
    speed_m_s: float = 0.2
    colors: tuple[str, ...] = DEFAULT_CLEAR_COLORS


_BARE = ("heartbeat", "release", "jog_stop", "base_stop", "stop", "estop", "rearm")


def parse_request(text: str | bytes, joint_names: tuple[str, ...]) -> Request:
    """One request from a page's message (``joint_names``: the arm's, for ``jog``)."""
    if len(text) > MAX_MESSAGE_BYTES:
        raise RequestError(f"message of {len(text)} bytes; at most {MAX_MESSAGE_BYTES}")
    try:
        message = json.loads(text)
    except (ValueError, UnicodeDecodeError) as exc:
        raise RequestError(f"not JSON: {exc}") from None
    if not isinstance(message, dict):
        raise RequestError(f"expected a JSON object with a type, got {_show(message)}")
    kind = message.get("type")
    if not isinstance(kind, str) or kind not in _PARSERS:
        raise RequestError(f"type {_show(kind)}: unknown; allowed: {', '.join(_PARSERS)}")
    fields = {k: v for k, v in message.items() if k != "type"}
    return _PARSERS[kind](kind, fields, joint_names)


def request_type(text: str | bytes) -> str:
    """The ``type`` a message names, if it is readable at all (for naming a refusal)."""
    try:
        kind = json.loads(text).get("type") if len(text) <= MAX_MESSAGE_BYTES else None
    except (ValueError, UnicodeDecodeError, AttributeError):
        return "?"
    return kind if isinstance(kind, str) and kind in _PARSERS else "?"


def _show(value: object) -> str:
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _take(fields: dict[str, Any], kind: str, allowed: tuple[str, ...]) -> dict[str, Any]:
    extra = sorted(set(fields) - set(allowed))
    if extra:
        raise RequestError(f"{kind}: unknown field(s) {', '.join(extra)}; allowed: "
                           f"{', '.join(allowed) or 'none'}")
    return fields


def _choice(kind: str, key: str, value: object, allowed: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise RequestError(f"{kind}: {key} = {_show(value)}; allowed: {', '.join(allowed)}")
    return value


def _name(kind: str, value: object, key: str = "name") -> str:
    if not (isinstance(value, str) and 0 < len(value) <= 64
            and all(c in NAME_CHARS for c in value)):
        raise RequestError(f"{kind}: {key} = {_show(value)}; expected 1..64 letters, digits, "
                           "'_', '-' or '.'")
    return value


def _number(kind: str, key: str, value: object, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
            value) or not lo <= value <= hi:
        raise RequestError(f"{kind}: {key} = {_show(value)}; allowed: a number {lo:g}..{hi:g}")
    return float(value)


def _bare(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    _take(fields, kind, ())
    return Request(kind)


def _drive(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    take_over = _take(fields, kind, ("take_over",)).get("take_over", False)
    if not isinstance(take_over, bool):
        raise RequestError(f"drive: take_over = {_show(take_over)}; allowed: true, false")
    return Drive(kind, take_over)


def _jog(kind: str, fields: dict[str, Any], joints: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("joint", "axis", "direction", "speed"))
    if ("joint" in f) == ("axis" in f):
        raise RequestError("jog: give a joint (" + ", ".join(joints) + ") or an axis ("
                           + ", ".join(JOG_AXES) + "), one of them")
    joint = _choice(kind, "joint", f["joint"], joints) if "joint" in f else None
    axis = _choice(kind, "axis", f["axis"], JOG_AXES) if "axis" in f else None
    direction = f.get("direction")
    if direction not in (1, -1) or isinstance(direction, bool):
        raise RequestError(f"jog: direction = {_show(direction)}; allowed: 1, -1")
    speed = _number(kind, "speed", f.get("speed", 1.0), MIN_JOG_SPEED, 1.0)
    return Jog(kind, joint, axis, int(direction), speed)


def _base_drive(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("vx_m_s", "vy_m_s", "wz_rad_s"))
    vx, vy, wz = (_number(kind, key, f.get(key, 0.0), -MAX_BASE_NUMBER, MAX_BASE_NUMBER)
                  for key in ("vx_m_s", "vy_m_s", "wz_rad_s"))
    return BaseDrive(kind, vx, vy, wz)


def _name_point(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("name", "x_m", "y_m", "yaw_deg"))
    name = _name(kind, f.get("name"))
    x, y = (_number(kind, key, f.get(key), -MAX_BASE_NUMBER, MAX_BASE_NUMBER)
            for key in ("x_m", "y_m"))
    return NamePoint(kind, name, x, y, _number(kind, "yaw_deg", f.get("yaw_deg", 0.0),
                                               -180.0, 180.0))


def _localise(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("x_m", "y_m", "yaw_deg"))
    if not f:
        return Localise(kind)
    if len(f) != 3:
        raise RequestError("localise: give x_m, y_m and yaw_deg (where the base is about), "
                           "all three, or none")
    x, y = (_number(kind, key, f[key], -MAX_BASE_NUMBER, MAX_BASE_NUMBER)
            for key in ("x_m", "y_m"))
    return Localise(kind, (x, y, _number(kind, "yaw_deg", f["yaw_deg"], -180.0, 180.0)))


def _named(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    key = "group" if kind == "play" else "name"
    f = _take(fields, kind, (key,))
    return Named(kind, _name(kind, f.get(key), key))


def _gripper(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("action",))
    return Gripper(kind, _choice(kind, "action", f.get("action"), GRIPPER_ACTIONS))


def _torque(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("servo", "on"))
    servo = f.get("servo")
    if isinstance(servo, bool) or not isinstance(servo, int) or not 0 <= servo <= 253:
        raise RequestError(f"torque: servo = {_show(servo)}; allowed: a servo ID 0..253")
    if not isinstance(f.get("on"), bool):
        raise RequestError(f"torque: on = {_show(f.get('on'))}; allowed: true, false")
    return Torque(kind, servo, f["on"])


def _record(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("action", "name", "duration_ms"))
    action = _choice(kind, "action", f.get("action"), RECORD_ACTIONS)
    name = _name(kind, f["name"]) if "name" in f else None
    if action == "save" and name is None:
        raise RequestError("record: save needs a name")
    duration = _number(kind, "duration_ms", f.get("duration_ms", 1000), 20, 30000)
    if not duration.is_integer():
        raise RequestError(f"record: duration_ms = {_show(f['duration_ms'])}; allowed: a "
                           "whole number 20..30000")
    return Record(kind, action, name, int(duration))


def _pick_sort(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("colors", "order", "by"))
    colors = f.get("colors", ["red", "green", "blue"])
    if not isinstance(colors, list) or not 0 < len(colors) <= 8:
        raise RequestError(f"pick_sort: colors = {_show(colors)}; expected a list of 1..8 "
                           "colour names")
    names = tuple(_name(kind, c, "colors") for c in colors)
    return PickSort(kind, names, _choice(kind, "order", f.get("order", "nearest"), PICK_ORDERS),
                    _choice(kind, "by", f.get("by", "color"), PICK_BY))


def _transport(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("pick", "place", "color"))
    pick = _name(kind, f.get("pick", "pick"), "pick")
    place = _name(kind, f.get("place", "place"), "place")
    if pick == place:
        raise RequestError(f"transport: pick and place are both {pick!r}; give two "
                           "different points")
    color = f.get("color")
    return NavTransport(kind, pick, place, None if color is None else _name(kind, color,
                                                                             "color"))


def _line_follow(kind: str, fields: dict[str, Any], _: tuple[str, ...]) -> Request:
    f = _take(fields, kind, ("laps", "speed_m_s", "colors"))
    laps = _number(kind, "laps", f.get("laps", 1.0), *LAPS_RANGE)
    speed = _number(kind, "speed_m_s", f.get("speed_m_s", 0.2), *LINE_SPEED_RANGE_M_S)
    colors = f.get("colors", list(DEFAULT_CLEAR_COLORS))
    if not isinstance(colors, list) or len(colors) > 8:
        raise RequestError(f"line_follow: colors = {_show(colors)}; expected a list of 0..8 "
                           "colour names (empty: clear no block)")
    return LineFollow(kind, laps, speed, tuple(_name(kind, c, "colors") for c in colors))


_PARSERS = {
    **{kind: _bare for kind in _BARE},
    "drive": _drive, "jog": _jog, "base_drive": _base_drive, "name_point": _name_point,
    "localise": _localise,
    "move_pose": _named, "save_pose": _named,
    "gripper": _gripper, "torque": _torque, "play": _named, "record": _record,
    "pick_sort": _pick_sort, "transport": _transport, "line_follow": _line_follow,
}


def message(kind: str, **fields: Any) -> str:
    """A server message as JSON text (NaN and infinities become null: valid JSON)."""
    return json.dumps({"type": kind, **_finite(fields)}, separators=(",", ":"))


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value
