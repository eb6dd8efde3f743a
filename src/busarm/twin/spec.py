"""The twin as a port, typed: ``TwinSpec`` says which twin, checked once when made.

=============== ============================================================ =============
``family``      the seeded scenes: ``random`` (blocks spread out) or          random
                ``clutter`` (a table like a real one: rows, clusters,
                touching blocks, distractors, a lamp's light; see
                busarm.twin.clutter), or ``arena``: the mobile robot in a
                seeded room (busarm.twin.arena_gen; its base moves with the
                board's wheels: give ``controller``)
``seed``        seed of the seeded scene or arena                             0
``blocks``      how many blocks in the random scene (0..8); in a clutter      5; clutter: 8
                scene, the most it holds (0..12)
``colors``      block colours of the seeded scene                             red, green,
                                                                              blue; clutter:
                                                                              all four
``scene``       a scene (or its file) instead of a seeded scene               (none)
``board``       a calibration board on the table (family random only):        (none; then
                chessboard, charuco, tags                                     blocks is 0)
``arena``       an arena (or its TOML file) instead of family arena           (none)
``chassis``     the mobile robot's chassis config (arena twins)               jetauto
``slip``        false: the wheels never slip, the sensors are ideal (arenas)  true
``lidar_noise`` false: the twin's Lidar measures without noise or dropouts    true
``config``      the arm: an ArmConfig, its name or file                       jetauto_pro
``lens``        the camera's lens: wide (strong barrel), vendor, none         wide
``echo``        the adapter echoes every byte sent                            false
``timing``      false: no wire timing (replies at once)                       true
``pace``        how many times real time the twin may run; 1 = real time      as fast as
                (for a person watching), none = as fast as the CPU allows     the CPU allows
``realtime``    the wall clock and a physics thread, as ``twin serve``        false
``controller``  the simulated controller board in front (``BoardSettings``):  (none)
                the servos behind its frames, and an arena's wheels on it
=============== ============================================================ =============

The twin runs on a simulated clock (``busarm.clock.SimClock``) unless ``realtime``: time
passes as the programs on its bus wait, so a move takes as long as the CPU needs to
simulate it and every time reported is in simulated seconds. The command line's
``twin://?seed=3&blocks=5`` and ``board://twin?family=arena`` are read into this by
``busarm.robot.port_url``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from busarm.arm.config import ArmConfig, load_arm_config
from busarm.base.config import ChassisConfig, load_chassis_config
from busarm.bus.transport import DEFAULT_BAUDRATE
from busarm.errors import ConfigError
from busarm.sim.spec import BoardSettings, check_flag, check_pace
from busarm.twin.arena import Arena, load_arena
from busarm.twin.clutter import CLUTTER_MAX_BLOCKS
from busarm.twin.scene import COLORS, MAX_BLOCKS, Scene, load_scene
from busarm.units import check_int_range, listing, short_repr

if TYPE_CHECKING:
    from busarm.twin.transport import TwinTransport
    from busarm.twin.twin import Twin

__all__ = [
    "FAMILIES",
    "TwinSpec",
]

FAMILIES = ("random", "clutter", "arena")
_SEEDED = ("family", "seed", "blocks", "colors", "board")
"""The keys that draw a seeded table (instead of ``scene``)."""
_MOBILE = ("chassis", "slip", "lidar_noise")


@dataclass(frozen=True)
class TwinSpec:
    """Which twin (the keys in the module's table); ``TwinSpec()`` is the arm on a table
    with five blocks, ``TwinSpec(family="arena", seed=3, controller=BoardSettings())``
    the mobile robot in a seeded room."""

    __repr__ = short_repr

    family: str | None = None
    seed: int | None = None
    blocks: int | None = None
    colors: tuple[str, ...] | None = None
    scene: Scene | Path | None = None
    board: str | None = None
    arena: Arena | Path | None = None
    chassis: ChassisConfig | str | Path | None = None
    slip: bool | None = None
    lidar_noise: bool | None = None
    config: ArmConfig | str | Path | None = None
    lens: str = "wide"
    echo: bool = False
    timing: bool = True
    pace: float | None = None
    realtime: bool = False
    controller: BoardSettings | None = None
    label: str = field(default="", compare=False)
    """The port in the user's own words (for messages), if given that way."""

    def __post_init__(self) -> None:
        if self.controller is not None and not isinstance(self.controller, BoardSettings):
            raise ConfigError(f"twin: controller must be a BoardSettings() (the simulated "
                              f"controller board in front), got {self.controller!r}")
        given = {k for k in (*_SEEDED, "scene", "arena", *_MOBILE)
                 if getattr(self, k) is not None}
        if self.family is not None and self.family not in FAMILIES:
            raise ConfigError(f"twin: family = {self.family!r}; allowed: {', '.join(FAMILIES)}")
        if self.scene is not None and set(_SEEDED) & given:
            raise ConfigError("twin: give either scene or family/seed/blocks/colors/board")
        if self.scene is not None and self.arena is not None:
            raise ConfigError("twin: a twin has an arena (the mobile robot) or a table "
                              "scene, not both")
        if self.arena is not None and given & {"family", "seed", "blocks", "colors", "board"}:
            raise ConfigError("twin: an arena is the whole world; give no "
                              "family/seed/blocks/colors/board with it")
        if self.family == "arena" and given & {"blocks", "colors", "board"}:
            raise ConfigError("twin: family arena takes seed only (its blocks are the "
                              "arena's): no blocks/colors/board")
        if not self.mobile and given & set(_MOBILE):
            keys = sorted(given & set(_MOBILE))
            raise ConfigError(f"twin: {listing(keys)} {'is' if len(keys) == 1 else 'are'} "
                              "for the mobile robot's arena (family arena, or an arena)")
        self._check_values()

    def _check_values(self) -> None:
        if self.seed is not None:
            check_int_range("twin: seed", self.seed, 0, 2**32 - 1)
        if self.board is not None:
            from busarm.twin.boards import BOARD_SPECS  # OpenCV: only when a board is asked

            if (self.family or "random") != "random":
                raise ConfigError(f"twin: board is for family random (a bare table), not "
                                  f"family {self.family}")
            if self.board not in BOARD_SPECS:
                raise ConfigError(f"twin: board = {self.board!r}; allowed: "
                                  f"{', '.join(BOARD_SPECS)}")
        if self.blocks is not None:
            hi = CLUTTER_MAX_BLOCKS if self.family == "clutter" else MAX_BLOCKS
            check_int_range(f"twin: blocks (family {self.family or 'random'})", self.blocks,
                            0, hi)
        if self.colors is not None:
            bad = [c for c in self.colors if c not in COLORS]
            if bad or not self.colors:
                raise ConfigError(f"twin: colors = {listing(bad or ['(none)'])}; allowed: "
                                  f"{', '.join(COLORS)}")
        if self.lens != "wide":  # the default; the lenses' table loads OpenCV
            from busarm.twin.lens import LENSES

            if self.lens not in LENSES:
                raise ConfigError(f"twin: lens = {self.lens!r}; allowed: "
                                  f"{', '.join(LENSES)}")
        for key in ("echo", "timing", "realtime"):
            check_flag(f"twin: {key}", getattr(self, key))
        check_pace("twin", self.pace, self.realtime)

    # ------------------------------------------------------------------ what it is

    @property
    def mobile(self) -> bool:
        """Whether it is the mobile robot in an arena (family arena, or an arena given)."""
        return self.family == "arena" or self.arena is not None

    @property
    def name(self) -> str:
        return self.label or ("twin behind a simulated board" if self.controller is not None
                              else "twin")

    @property
    def robot_key(self) -> str:
        return "twin"  # a twin in this process, whatever its table

    @property
    def through_board(self) -> bool:
        return self.controller is not None

    def check(self) -> None:
        """Nothing to check before opening: the twin is always there."""

    def placed(self, *, scene: Scene | None = None, arena: Arena | None = None) -> TwinSpec:
        """This twin with ``scene`` or ``arena`` as its world; ConfigError when it has
        chosen one already (a seeded table or arena, a scene, an arena)."""
        if scene is None and arena is None:
            return self
        if any(getattr(self, k) is not None for k in (*_SEEDED, "scene", "arena")):
            raise ConfigError(f"{self.name}: the world is given twice (in the port and as "
                              f"{'a scene' if scene is not None else 'an arena'})")
        return replace(self, scene=scene, arena=arena)

    def with_board(self, board: str) -> TwinSpec:
        """This twin with calibration ``board`` on its table (unless its scene is given,
        or it already has that board)."""
        if self.board is not None and self.board != board:
            raise ConfigError(f"{self.name}: this step looks for a {board} board, but the "
                              f"twin's table has a {self.board} board")
        if self.board is not None or self.scene is not None:
            return self
        return replace(self, board=board)

    # ------------------------------------------------------------------ building

    def make_arena(self) -> Arena | None:
        """The arena (loaded, or drawn from the seed), or None on a table."""
        from busarm.twin.arena_gen import random_arena

        if isinstance(self.arena, Arena):
            return self.arena
        if self.arena is not None:
            return load_arena(self.arena)
        return random_arena(self.seed or 0) if self.family == "arena" else None

    def make_scene(self) -> Scene:
        """What stands on the table: the scene given, or a seeded one of the family."""
        from busarm.twin.boards import calibration_board
        from busarm.twin.clutter import CLUTTER_DEFAULT_BLOCKS, clutter_scene
        from busarm.twin.scene import random_scene

        if isinstance(self.scene, Scene):
            return self.scene
        if self.scene is not None:
            return load_scene(self.scene)
        clutter = self.family == "clutter"
        seed = self.seed or 0
        blocks = self.blocks if self.blocks is not None else (
            CLUTTER_DEFAULT_BLOCKS if clutter else 0 if self.board else 5)
        colors = list(self.colors) if self.colors is not None else (
            list(COLORS) if clutter else ["red", "green", "blue"])
        if clutter:
            return clutter_scene(seed, blocks, colors)
        scene = random_scene(seed, blocks, colors, bins=self.board is None)
        if self.board is None:
            return scene
        return replace(scene, boards=(calibration_board(self.board),),
                       source=f"{scene.source}, {self.board}")

    def arm_config(self, given: ArmConfig | None = None) -> ArmConfig:
        """The arm it builds: ``given`` (the robot's), which must agree with this twin's
        own ``config`` if both are set; else its own; else the JetAuto Pro."""
        own = (self.config if isinstance(self.config, ArmConfig | None)
               else load_arm_config(self.config))
        if given is not None and own is not None and replace(own, source="") != replace(
                given, source=""):
            raise ConfigError(f"twin: config {own.source} is not the arm config given "
                              f"({given.source}): give one of them")
        return given or own or load_arm_config("jetauto_pro")

    def build(self, baudrate: int = DEFAULT_BAUDRATE, *,
              config: ArmConfig | None = None) -> Twin:
        """The twin (not yet behind a board): ``config`` is the arm it builds (see
        ``arm_config``)."""
        from busarm.clock import SimClock
        from busarm.sim.bus import WireTiming
        from busarm.twin.lens import lens_by_name
        from busarm.twin.lidar import LidarNoise
        from busarm.twin.mobile import SlipModel
        from busarm.twin.twin import CONTROL_PERIOD_S, Twin

        arena = self.make_arena()
        scene = None if arena is not None else self.make_scene()
        # Unpaced, the twin makes its own simulated clock.
        clock = (None if self.realtime or self.pace is None
                 else SimClock(step_s=CONTROL_PERIOD_S, pace=self.pace))
        mobile: dict[str, Any] = {}
        if arena is not None:
            chassis = (self.chassis if isinstance(self.chassis, ChassisConfig)
                       else load_chassis_config(self.chassis or "jetauto"))
            mobile = {"arena": arena, "chassis": chassis,
                      "slip": None if self.slip in (None, True) else SlipModel.none()}
        twin = Twin(self.arm_config(config), scene, lens=lens_by_name(self.lens),
                    timing=WireTiming(baudrate, enabled=self.timing), echo=self.echo,
                    realtime=self.realtime, clock=clock, **mobile)
        if self.lidar_noise is False:
            twin.lidar_noise = LidarNoise.none()
        return twin

    def open(self, baudrate: int = DEFAULT_BAUDRATE, *,
             config: ArmConfig | None = None) -> TwinTransport:
        """The twin in this process behind a transport (closing it closes the twin): its
        servo bus, or with ``controller`` the simulated board in front of it (an arena's
        wheels on that board)."""
        from busarm.twin.transport import TwinTransport

        twin = self.build(baudrate, config=config)
        if self.controller is None:
            return TwinTransport(twin, name=self.name)
        try:
            board = self.controller.build(twin.bus)
            if twin.mobile is not None:
                twin.mobile.attach(board)
            return TwinTransport(twin, name=self.name, line=board)
        except BaseException:
            twin.close()
            raise
