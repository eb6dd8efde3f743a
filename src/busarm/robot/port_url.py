"""The command line's port strings, read once into typed ports: the only place a port URL
is parsed (a test keeps it so).

=============================== ==========================================================
``/dev/ttyUSB0``, ``COM3``      a serial device (``SerialPort``); a pyserial URL
                                (``socket://HOST:PORT``, ``rfc2217://``, ``loop://``) too
``sim``, ``sim://?KEY=V&...``   simulated servos (``SimSpec``; its keys)
``twin``, ``twin://?KEY=V&...`` the twin in this process (``TwinSpec``; its keys)
``board://DEVICE``              the servos behind the controller board on DEVICE
``board://sim?...``,            the simulated controller board in front of the simulator
``board://twin?...``            or the twin (``BoardSettings``' keys beside theirs)
``zenoh://HOST[:PORT][?robot=]`` a robot served on another computer (``ZenohPort``)
``lidar://sim?...``             (Lidar ports only) a simulated A1 (``SimLidarSpec``)
=============================== ==========================================================

Flags are ``0`` or ``1``; lists are comma separated. A key that is unknown, or a value
that is not of its kind, is one ConfigError naming the key, the value and what is allowed;
the ranges are the ports' own checks.
"""

from __future__ import annotations

import difflib
import os
from dataclasses import fields
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from busarm.bus.ports import PortSpec, SerialPort
from busarm.bus.zenoh_link import DEFAULT_ROBOT, ZenohPort
from busarm.bus.zenoh_session import DEFAULT_PORT
from busarm.errors import ConfigError
from busarm.robot.description import LidarPort
from busarm.sim.spec import BoardSettings, SimLidarSpec, SimSpec
from busarm.twin.spec import TwinSpec
from busarm.units import listing, parse_ids

__all__ = [
    "SIM_LIDAR",
    "parse_lidar_port",
    "parse_port",
    "port_text",
]

SIM_LIDAR = "lidar://sim"
"""The simulated A1, the command line's default Lidar on the servo simulator."""
_BOARD = "board://"
_FLAGS = {"echo", "timing", "block", "realtime", "slip", "lidar_noise", "silent", "encoders"}
_INTS = {"seed", "blocks", "board_seed", "health"}
_PATHS = {"state", "scene", "arena"}
_LISTS = {"colors"}
_BOARD_KEYS = {f.name for f in fields(BoardSettings)}
_SIM_KEYS = {f.name for f in fields(SimSpec)} - {"controller", "label"}
_TWIN_KEYS = {f.name for f in fields(TwinSpec)} - {"controller", "label"}
_LIDAR_KEYS = {f.name for f in fields(SimLidarSpec)} - {"label"}


def parse_port(text: str) -> PortSpec:
    """The port ``text`` names (the module's table); ConfigError if it names none."""
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"port must be a device path, a URL, 'sim' or 'twin', got {text!r}")
    if text.startswith(_BOARD):
        return _board_port(text)
    kind, query = _split(text)
    if kind == "sim":
        return _sim(_pairs(query), text, None)
    if kind == "twin":
        return _twin(_pairs(query), text, None)
    if kind == "zenoh":
        return _zenoh(text)
    _check_device_name(text)
    return SerialPort(text, label=text)


def parse_lidar_port(text: str) -> LidarPort:
    """The Lidar ``text`` names: a device or pyserial URL, ``lidar://sim?...``, or a twin
    with an arena (``twin://?family=arena&seed=3``: a twin made for it)."""
    if not isinstance(text, str) or not text.strip():
        raise ConfigError(f"Lidar port must be a device path, a URL or lidar://sim, got "
                          f"{text!r}")
    if text.startswith("lidar://"):
        if not (text == "lidar://sim" or text.startswith("lidar://sim?")):
            raise ConfigError(f"Lidar port {text!r}: the only lidar:// port is "
                              "lidar://sim[?hz=...]")
        values = _values(_pairs(urlsplit(text).query), "lidar URL", _LIDAR_KEYS)
        return SimLidarSpec(**values, label=text)
    port = parse_port(text)
    if isinstance(port, TwinSpec) and port.controller is None:
        if not port.mobile:
            raise ConfigError(f"Lidar port {text!r}: this twin is an arm on a table, with no "
                              "Lidar; give twin://?family=arena[&seed=N] or arena=FILE")
        return port
    if not isinstance(port, SerialPort) or port.board:
        raise ConfigError(f"Lidar port {text!r} is the servo simulator, twin or controller "
                          "board, not a Lidar; give the Lidar's device or lidar://sim")
    return port


def _split(text: str) -> tuple[str, str]:
    """(kind, query) of a ``sim``/``twin``/``zenoh`` port, or ("", "") for a device."""
    for kind in ("sim", "twin", "zenoh"):
        if text == kind or text.startswith(kind + "://"):
            parts = urlsplit(text)
            if kind == "twin" and parts.netloc:
                raise ConfigError(f"{text}: twin://HOST:PORT is a twin camera's address; for "
                                  "its servos use the /dev/pts/N path `busarm twin serve` "
                                  "printed, or twin://?... for a twin in this process")
            if kind == "sim" and parts.netloc:
                raise ConfigError(f"{text}: a sim port has no host; give sim://?KEY=VALUE")
            return kind, parts.query
    return "", ""


def _board_port(text: str) -> PortSpec:
    inner = text[len(_BOARD):]
    for kind in ("sim", "twin"):
        if inner == kind or inner.startswith((kind + "?", kind + "://")):
            pairs = _pairs(inner.split("?", 1)[1] if "?" in inner else "")
            board = BoardSettings(**_values({k: v for k, v in pairs.items()
                                             if k in _BOARD_KEYS}, "board URL", _BOARD_KEYS))
            rest = {k: v for k, v in pairs.items() if k not in _BOARD_KEYS}
            return (_sim if kind == "sim" else _twin)(rest, text, board)
    if not inner:
        raise ConfigError(f"{text!r}: give the board's device after board://, e.g. "
                          "board:///dev/ttyACM0 (or board://sim, board://twin)")
    return SerialPort(inner, board=True, label=text)


def _sim(pairs: dict[str, list[str]], text: str, board: BoardSettings | None) -> SimSpec:
    values = _values(pairs, "sim URL", _SIM_KEYS)
    if "ids" in values:
        values["ids"] = tuple(values["ids"])
    return SimSpec(**values, controller=board, label=text)


def _twin(pairs: dict[str, list[str]], text: str, board: BoardSettings | None) -> TwinSpec:
    values = _values(pairs, "twin URL", _TWIN_KEYS)
    if "colors" in values:
        values["colors"] = tuple(values["colors"])
    for key in ("config", "chassis"):  # given empty: the default
        if key in values and not values[key]:
            del values[key]
    return TwinSpec(**values, controller=board, label=text)


def _zenoh(text: str) -> ZenohPort:
    parts = urlsplit(text)
    if not parts.hostname:
        raise ConfigError(f"{text!r}: give zenoh://HOST[:PORT][?robot=NAME], e.g. "
                          "zenoh://127.0.0.1")
    query = parse_qs(parts.query)
    unknown = set(query) - {"robot"}
    if unknown:
        raise ConfigError(f"{text!r}: unknown key(s) {', '.join(sorted(unknown))}; "
                          "allowed: robot")
    try:
        tcp_port = parts.port or DEFAULT_PORT
    except ValueError as exc:
        raise ConfigError(f"{text!r}: the port must be 1..65535") from exc
    return ZenohPort(parts.hostname, tcp_port, query.get("robot", [DEFAULT_ROBOT])[-1],
                     label=text)


def _pairs(query: str) -> dict[str, list[str]]:
    """A query's keys and their values (blank ones kept: ``scene=`` is a key given)."""
    return parse_qs(query, keep_blank_values=True)


def _values(raw: dict[str, list[str]], what: str, known: set[str]) -> dict[str, Any]:
    """The keys of a query as their fields' kinds; ConfigError naming a bad key or value."""
    unknown = set(raw) - known
    if unknown:
        raise ConfigError(f"{what}: unknown parameter(s) {listing(sorted(unknown))}; "
                          f"known: {listing(sorted(known))}")
    return {key: _value(what, key, values[-1]) for key, values in raw.items()}


def _value(what: str, key: str, text: str) -> Any:
    if key in _FLAGS:
        if text not in ("0", "1"):
            raise ConfigError(f"{what}: {key}={text!r}; allowed: 0 or 1")
        return text == "1"
    if key == "ids":
        return parse_ids(text)
    if key in _LISTS:
        return [c.strip() for c in text.split(",") if c.strip()]
    if key in _PATHS:
        return Path(text) if text else None
    if key in ("lens", "board", "family", "config", "chassis"):
        return text
    try:
        number = float(text)
    except ValueError:
        raise ConfigError(f"{what}: {key}={text!r} is not a number") from None
    if key in _INTS:
        if not number.is_integer():
            raise ConfigError(f"{what}: {key}={text!r} must be a whole number")
        return int(number)
    return number


def port_text(port: ZenohPort) -> str:
    """``port`` as the command line's ``--port`` takes it (for a program that runs another
    busarm command against it)."""
    host = f"[{port.host}]" if ":" in port.host else port.host
    robot = "" if port.robot == DEFAULT_ROBOT else f"?robot={port.robot}"
    return f"zenoh://{host}:{port.port}{robot}"


def _check_device_name(text: str) -> None:
    """On POSIX a device is a path (/dev/...) or a pyserial URL: anything else is a port
    misspelt (``twn``, ``twin?seed=3``), said as such rather than as a missing adapter."""
    if os.name != "posix" or text.startswith("/") or "://" in text:
        return
    head = text.split("?", 1)[0]
    near = difflib.get_close_matches(head, ["sim", "twin"], n=1, cutoff=0.5)
    hint = (f"; did you mean {near[0]}" + ("://?" + text.split("?", 1)[1] if "?" in text
                                          else "") + "?") if near else ""
    raise ConfigError(f"port {text!r} is not a device path (/dev/ttyUSB0), a pyserial URL "
                      f"(socket://HOST:PORT), sim[://?...], twin[://?...], board://... or "
                      f"zenoh://HOST{hint}")
