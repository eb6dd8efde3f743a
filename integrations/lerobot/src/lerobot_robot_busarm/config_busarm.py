"""The LeRobot configurations of busarm's robot, teleoperators and twin environment
(``--robot.type=busarm``, ``--teleop.type=busarm_leader`` / ``busarm_keyboard``,
``--env.type=busarm``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.configs.types import FeatureType, PolicyFeature
from lerobot.envs.configs import EnvConfig
from lerobot.robots.config import RobotConfig
from lerobot.teleoperators.config import TeleoperatorConfig
from lerobot.utils.constants import ACTION, OBS_ENV_STATE, OBS_IMAGES, OBS_STATE

from busarm.bus.driver import DEFAULT_TIMEOUT_MARGIN_S
from busarm.learn.features import DEFAULT_FPS, TASK_STATE_NAMES

__all__ = [
    "GYM_PACKAGE",
    "BusarmConfig",
    "BusarmEnv",
    "BusarmGamepadConfig",
    "BusarmKeyboardConfig",
    "BusarmLeaderConfig",
]

GYM_PACKAGE = "lerobot_robot_busarm"
"""The gymnasium namespace of busarm's environments (``lerobot_robot_busarm/OneBlock-v0``)."""
MOTORS = 6


@RobotConfig.register_subclass("busarm")
@dataclass(kw_only=True)
class BusarmConfig(RobotConfig):
    """busarm's robot: ``port`` is any busarm port (``twin``, ``twin://?seed=3``,
    ``/dev/ttyUSB0``, ``board:///dev/ttyACM0``, ``board://twin?family=arena``...), or
    ``robot_file`` a busarm robot file (``busarm robot init``). A twin follows the wall
    clock here (``realtime``), as LeRobot's loops pace themselves on it."""

    port: str = "twin"
    robot_file: str | None = None
    camera_roles: list[str] = field(default_factory=lambda: ["wrist"])
    camera_width: int = 640
    camera_height: int = 480
    fps: int = DEFAULT_FPS
    realtime: bool = True
    timeout_margin_s: float | None = None
    """Added to each servo reply's deadline (None: the robot description's)."""


@TeleoperatorConfig.register_subclass("busarm_leader")
@dataclass(kw_only=True)
class BusarmLeaderConfig(TeleoperatorConfig):
    """A second arm of LX servos, its torque off, moved by hand: ``port`` its bus (a
    serial device, or a busarm port); ``timeout_margin_s`` added to each reply's deadline
    (a slow adapter, or a simulated leader on a busy computer)."""

    port: str
    arm_config: str | None = None
    timeout_margin_s: float = DEFAULT_TIMEOUT_MARGIN_S


@TeleoperatorConfig.register_subclass("busarm_keyboard")
@dataclass(kw_only=True)
class BusarmKeyboardConfig(TeleoperatorConfig):
    """The keyboard of the terminal LeRobot runs in (``tty``: another terminal's device):
    each joint and the gripper jogged by a pair of keys (busarm.learn.keyboard)."""

    tty: str | None = None
    step_deg: float = 2.0
    gripper_step_mm: float = 3.0
    arm_config: str | None = None


@EnvConfig.register_subclass("busarm")
@dataclass
class BusarmEnv(EnvConfig):
    """busarm's twin as LeRobot's environment: ``task`` OneBlock-v0 (one block to its
    colour's bin) or Table-v0 (sort a table); ``obs_type`` state or pixels_agent_pos."""

    task: str | None = "OneBlock-v0"
    fps: int = DEFAULT_FPS
    episode_length: int = 300
    obs_type: str = "state"
    render_mode: str = "rgb_array"
    features: dict[str, PolicyFeature] = field(default_factory=lambda: {
        ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(MOTORS,)),
        "agent_pos": PolicyFeature(type=FeatureType.STATE, shape=(MOTORS,)),
        "environment_state": PolicyFeature(type=FeatureType.ENV,
                                           shape=(len(TASK_STATE_NAMES),)),
    })
    features_map: dict[str, str] = field(default_factory=lambda: {
        ACTION: ACTION, "agent_pos": OBS_STATE, "environment_state": OBS_ENV_STATE,
        "pixels/wrist": f"{OBS_IMAGES}.wrist",
    })

    def __post_init__(self) -> None:
        if self.obs_type == "pixels_agent_pos":
            self.features["pixels/wrist"] = PolicyFeature(type=FeatureType.VISUAL,
                                                          shape=(480, 640, 3))

    @property
    def package_name(self) -> str:
        return GYM_PACKAGE

    @property
    def gym_kwargs(self) -> dict[str, object]:
        return {"obs_type": self.obs_type, "render_mode": self.render_mode,
                "fps": self.fps, "max_episode_steps": self.episode_length}


@TeleoperatorConfig.register_subclass("busarm_gamepad")
@dataclass(kw_only=True)
class BusarmGamepadConfig(TeleoperatorConfig):
    """A gamepad through Linux's joystick device (busarm.learn.gamepad): the sticks and
    the d-pad turn the joints at up to ``speed_deg_s``, A and B close and open."""

    device: str = "/dev/input/js0"
    speed_deg_s: float = 45.0
    arm_config: str | None = None
