"""The twin as an in-process transport: ``--port twin`` or ``twin://?seed=3&blocks=5``.

URL query parameters (all optional):

=========== =========================================================== ==============
``family``  the seeded scenes: ``random`` (blocks spread out) or         random
            ``clutter`` (a table like a real one: rows, clusters,
            touching blocks, distractors, a lamp's light; see
            busarm.twin.clutter), or ``arena``: the mobile robot in a
            seeded room (busarm.twin.arena_gen; its base moves with
            the board's wheels: ``board://twin?family=arena``)
``arena``   an arena file (TOML, busarm.twin.arena) instead              (none)
``chassis`` the mobile robot's chassis config (arena twins)             jetauto
``slip``    0 = the wheels never slip and the sensors are ideal         1
            (arena twins; busarm.twin.mobile.SlipModel)
``lidar_noise`` 0 = the twin's Lidar measures without noise or          1
            dropouts (busarm.twin.lidar.LidarNoise)
``seed``    seed of the seeded scene                                    0
``blocks``  how many blocks in the random scene (0..8); in a clutter    5; clutter: 8
            scene, the most it holds (0..12)
``colors``  block colours of the seeded scene, comma separated          red,green,blue;
                                                                        clutter: all four
``scene``   a scene file instead of a seeded scene                      (none)
``board``   a calibration board on the table (family=random only):      (none; then
            chessboard, charuco, tags                                   ``blocks`` is 0)
``config``  arm config name or file                                     jetauto_pro
``lens``    the camera's lens: wide (strong barrel), vendor, none          wide
``echo``    1 = the adapter echoes every byte sent                      0
``timing``  0 = no wire timing (replies at once)                        1
``pace``    how many times real time the twin may run; 1 = real time      as fast as
            (for a person watching), absent = as fast as the CPU allows   the CPU allows
``realtime`` 1 = the wall clock and a physics thread, as ``twin serve``    0
            (to compare a run with the simulated clock's)
=========== =========================================================== ==============

The twin runs on a simulated clock (``busarm.clock.SimClock``): time passes as the
programs on its bus wait, so a move takes as long as the CPU needs to simulate it and
every time reported is in simulated seconds. Closing the transport closes the twin;
``transport.twin`` is the twin, for whoever opened it (``busarm.robot`` hands it out).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any
from urllib.parse import parse_qs, urlsplit

from busarm.arm.config import ArmConfig, load_arm_config
from busarm.base.config import load_chassis_config
from busarm.clock import SimClock
from busarm.errors import ConfigError
from busarm.sim.board import board_from_query, split_board_keys
from busarm.sim.bus import SimLine, WireTiming
from busarm.sim.transport import SimTransport, query_flag, query_float
from busarm.twin.arena import Arena, load_arena
from busarm.twin.arena_gen import random_arena
from busarm.twin.boards import BOARD_SPECS, calibration_board
from busarm.twin.clutter import CLUTTER_DEFAULT_BLOCKS, CLUTTER_MAX_BLOCKS, clutter_scene
from busarm.twin.lens import lens_by_name
from busarm.twin.lidar import LidarNoise
from busarm.twin.mobile import SlipModel
from busarm.twin.scene import COLORS, MAX_BLOCKS, Scene, load_scene, random_scene
from busarm.twin.twin import CONTROL_PERIOD_S, Twin
from busarm.units import listing

__all__ = [
    "FAMILIES",
    "TwinTransport",
    "arena_from_query",
    "is_arena_query",
    "is_twin_url",
    "open_twin_board_transport",
    "open_twin_transport",
    "scene_from_query",
    "twin_behind_board",
    "twin_from_url",
    "twin_query",
]


_KNOWN = {"family", "seed", "blocks", "colors", "scene", "config", "echo", "timing", "board",
          "lens", "pace", "realtime", "arena", "chassis", "slip", "lidar_noise"}
_ARENA_KEYS = {"arena", "chassis", "slip", "lidar_noise"}
_TABLE_KEYS = {"family", "seed", "blocks", "colors", "board"}
"""The keys that draw a seeded scene (instead of ``scene=``)."""
FAMILIES = ("random", "clutter", "arena")


def twin_query(url: str) -> dict[str, str]:
    """The query of a ``twin``/``twin://?...`` URL, unknown keys refused."""
    parts = urlsplit(url) if "://" in url else None
    if parts is not None and parts.netloc:
        raise ConfigError(f"{url}: twin://HOST:PORT is a twin camera's address; for its servos "
                          "use the /dev/pts/N path `busarm twin serve` printed, or twin://?... "
                          "for a twin in this process")
    query = parts.query if parts is not None else ""
    raw = parse_qs(query, keep_blank_values=True)
    unknown = set(raw) - _KNOWN
    if unknown:
        raise ConfigError(f"twin URL: unknown parameter(s) {listing(sorted(unknown))}; "
                          f"known: {listing(sorted(_KNOWN))}")
    return {k: v[-1] for k, v in raw.items()}


def is_arena_query(q: dict[str, str]) -> bool:
    """Whether a twin URL asks for the mobile robot in an arena."""
    return q.get("family") == "arena" or "arena" in q


def arena_from_query(q: dict[str, str]) -> Arena:
    """The arena a twin URL asks for: a file (``arena=``), or ``family=arena&seed=N``."""
    if "arena" in q:
        if q.get("family", "arena") != "arena" or {"seed", "blocks", "colors", "board",
                                                     "scene"} & set(q):
            raise ConfigError("twin URL: arena=FILE is the whole arena; give no "
                              "family=/seed=/blocks=/colors=/board=/scene= with it")
        return load_arena(q["arena"])
    if {"blocks", "colors", "board", "scene"} & set(q):
        raise ConfigError("twin URL: family=arena takes seed= only (its blocks are the "
                          "arena's): no blocks=/colors=/board=/scene=")
    seed = query_float(q, "seed", 0.0, "twin URL")
    if not (seed.is_integer() and 0 <= seed <= 2**32 - 1):
        raise ConfigError(f"twin URL: seed={q['seed']!r} must be a whole number 0..{2**32 - 1}")
    return random_arena(int(seed))


def scene_from_query(q: dict[str, str]) -> Scene:
    """The scene a twin URL asks for: a file, or a seeded scene of a family."""
    if q.get("scene"):
        if _TABLE_KEYS & set(q):
            raise ConfigError("twin URL: give either scene= or "
                              "family=/seed=/blocks=/colors=/board=")
        return load_scene(q["scene"])
    family = q.get("family", "random")
    if family not in FAMILIES:
        raise ConfigError(f"twin URL: family={family!r}; allowed: {', '.join(FAMILIES)}")
    board = q.get("board")
    if board is not None and family != "random":
        raise ConfigError(f"twin URL: board= is for family=random (a bare table), not "
                          f"family={family}")
    if board is not None and board not in BOARD_SPECS:
        raise ConfigError(f"twin URL: board={board!r}; allowed: {', '.join(BOARD_SPECS)}")
    clutter = family == "clutter"
    seed = query_float(q, "seed", 0.0, "twin URL")
    default_blocks = CLUTTER_DEFAULT_BLOCKS if clutter else 0 if board else 5
    blocks = query_float(q, "blocks", float(default_blocks), "twin URL")
    max_blocks = CLUTTER_MAX_BLOCKS if clutter else MAX_BLOCKS
    for key, value, hi in (("seed", seed, 2**32 - 1), ("blocks", blocks, max_blocks)):
        if not (value.is_integer() and 0 <= value <= hi):
            raise ConfigError(f"twin URL: {key}={q[key]!r} must be a whole number 0..{hi}"
                              + (f" (family={family})" if key == "blocks" else ""))
    default_colors = ",".join(COLORS) if clutter else "red,green,blue"
    colors = [c.strip() for c in q.get("colors", default_colors).split(",") if c.strip()]
    if clutter:
        return clutter_scene(int(seed), int(blocks), colors)
    scene = random_scene(int(seed), int(blocks), colors, bins=board is None)
    if board is None:
        return scene
    return replace(scene, boards=(calibration_board(board),), source=f"{scene.source}, {board}")


def is_twin_url(port: str) -> bool:
    """Whether ``port`` names a twin in this process (``twin`` or ``twin://?...``)."""
    return port == "twin" or (port.startswith("twin://") and not urlsplit(port).netloc)


def twin_from_url(url: str, baudrate: int = 115200, *, realtime: bool = False,
                  config: ArmConfig | None = None, scene: Scene | None = None,
                  arena: Arena | None = None) -> Twin:
    """A twin configured by a ``twin://?...`` URL: on a simulated clock (paced by
    ``pace=``), or on the wall clock with ``realtime`` (``twin serve``). ``config``, if
    given, is the arm it builds (else the URL's ``config=``, else the JetAuto Pro);
    ``scene``, if given, what stands on its table (else the URL's); ``arena``, if given,
    the mobile robot's arena (the URL may still give chassis=, slip=, lidar_noise=)."""
    q = twin_query(url)
    if (scene is not None or arena is not None) and ({"scene", "arena"} | _TABLE_KEYS) & set(q):
        raise ConfigError(f"{url}: the world is given twice (in the URL and as a "
                          f"{'scene' if scene is not None else 'arena'})")
    if scene is not None and arena is not None:
        raise ConfigError("a twin has an arena (the mobile robot) or a table scene, not both")
    if arena is None and scene is None and is_arena_query(q):
        arena = arena_from_query(q)
    if arena is None and _ARENA_KEYS & set(q):
        keys = sorted(_ARENA_KEYS & set(q))
        raise ConfigError(f"twin URL: {listing(keys)} {'is' if len(keys) == 1 else 'are'} "
                          "for the mobile robot's arena (family=arena or arena=FILE)")
    scene = scene if scene is not None or arena is not None else scene_from_query(q)
    in_url = load_arm_config(q["config"]) if q.get("config") else None
    if config is not None and in_url is not None and replace(in_url, source="") != replace(
            config, source=""):
        raise ConfigError(f"twin URL: config={q['config']} is not the arm config given "
                          f"({config.source}): give one of them")
    config = config or in_url or load_arm_config("jetauto_pro")
    timing = WireTiming(baudrate, enabled=query_flag(q, "timing", True, "twin URL"))
    realtime = realtime or query_flag(q, "realtime", False, "twin URL")
    pace = query_float(q, "pace", 0.0, "twin URL") if "pace" in q else None
    if pace is not None and realtime:
        raise ConfigError("twin URL: pace= is for a twin in this process; this one follows "
                          "the wall clock")
    # Unpaced, the twin makes its own simulated clock.
    clock = None if realtime or pace is None else SimClock(step_s=CONTROL_PERIOD_S, pace=pace)
    mobile: dict[str, Any] = {}
    if arena is not None:
        mobile = {"arena": arena, "chassis": load_chassis_config(q.get("chassis", "jetauto")),
                  "slip": None if query_flag(q, "slip", True, "twin URL") else SlipModel.none()}
    twin = Twin(config, scene, lens=lens_by_name(q.get("lens", "wide")), timing=timing,
                echo=query_flag(q, "echo", False, "twin URL"), realtime=realtime,
                clock=clock, **mobile)
    if not query_flag(q, "lidar_noise", True, "twin URL"):
        twin.lidar_noise = LidarNoise.none()
    return twin


class TwinTransport(SimTransport):
    """A transport to a twin's simulated bus, or to another simulated line of it (``line``:
    a controller board in front of its servos, its Lidar); closing it closes the twin."""

    def __init__(self, twin: Twin, name: str = "twin", *, line: SimLine | None = None) -> None:
        super().__init__(line if line is not None else twin.bus, name)
        self.twin = twin

    def close(self) -> None:
        super().close()
        self.twin.close()


def open_twin_transport(url: str, baudrate: int = 115200) -> TwinTransport:
    """Entry point used by ``busarm.bus.transport.open_transport`` for ``twin``/``twin://``."""
    return TwinTransport(twin_from_url(url, baudrate), name=url)


def twin_behind_board(url: str, baudrate: int = 115200, **kwargs: Any) -> TwinTransport:
    """The twin of ``url`` (``twin://?...``, with the simulated board's own keys too)
    behind a simulated controller board; ``kwargs`` go to ``twin_from_url``."""
    inner, keys = split_board_keys(url)
    twin = twin_from_url(inner, baudrate, **kwargs)
    try:
        board = board_from_query(twin.bus, keys)
        if twin.mobile is not None:
            twin.mobile.attach(board)
        return TwinTransport(twin, name=url, line=board)
    except BaseException:
        twin.close()
        raise


def open_twin_board_transport(url: str, baudrate: int = 115200, name: str = "") -> TwinTransport:
    """Entry point of ``open_transport`` for ``board://twin?...``."""
    transport = twin_behind_board(url, baudrate)
    transport.name = name or url
    return transport
