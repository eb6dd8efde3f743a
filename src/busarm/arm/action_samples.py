"""Sample action groups shipped with busarm (``busarm actions list``, ``actions play wave``).

The ``.d6a`` files in ``busarm/arm/samples/`` are our own, made by :func:`write_samples`
from the joint angles below through the shipped arm config's pulse maps (the vendor's
nominal pulses, as a ``.d6a`` holds them), so they can be remade and checked at any time::

    python -c "from busarm.arm.action_samples import write_samples; write_samples()"

Every sample starts with a 1.5 s frame, slow enough (at ``--speed-scale 1``) for every
joint to get there from anywhere within its speed limit, and ends in the ``home`` pose.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from busarm.arm.actions import ActionFrame, ActionGroup, read_d6a, write_d6a
from busarm.arm.config import ArmConfig, load_arm_config
from busarm.errors import ConfigError
from busarm.protocol.lx_units import POSITION_MAX_PULSES, POSITION_MIN_PULSES

SAMPLES_FOLDER = "samples"
SUFFIX = ".d6a"

_HOME = (0.0, -150.0, 120.0, -60.0, 0.0)
_UP = (0.0, -90.0, 30.0, -60.0, 0.0)
_LOOK = (0.0, -90.8, 111.2, -20.4, 0.0)
_OPEN, _HALF, _CLOSED = 200, 450, 700


@dataclass(frozen=True)
class SampleSpec:
    """A sample: what it does, and its frames as (ms, joint angles in deg, gripper pulses)."""

    description: str
    frames: tuple[tuple[int, tuple[float, ...], int], ...]


def _yaw(pose: tuple[float, ...], yaw_deg: float) -> tuple[float, ...]:
    return (yaw_deg, *pose[1:])


def _wrist(pose: tuple[float, ...], delta_deg: float) -> tuple[float, ...]:
    return (*pose[:3], pose[3] + delta_deg, pose[4])


SAMPLES: dict[str, SampleSpec] = {
    "wave": SampleSpec("raise the arm and wave the base left and right twice", (
        (1500, _UP, _HALF),
        *((600, _yaw(_UP, yaw), _HALF) for yaw in (30.0, -30.0, 30.0, -30.0)),
        (600, _UP, _HALF),
        (1200, _HOME, _HALF),
    )),
    "nod": SampleSpec("go to the look pose and nod the wrist twice", (
        (1500, _LOOK, _HALF),
        *((500, _wrist(_LOOK, d), _HALF) for d in (-20.0, 20.0, -20.0, 20.0)),
        (500, _LOOK, _HALF),
        (1200, _HOME, _HALF),
    )),
    "open-close": SampleSpec("at home, open the gripper fully, close it, open it halfway", (
        (1500, _HOME, _HALF),
        (800, _HOME, _OPEN),
        (1000, _HOME, _CLOSED),
        (800, _HOME, _HALF),
    )),
}
"""The samples by name (their frames are for the shipped ``jetauto_pro`` arm)."""


def sample_names() -> list[str]:
    """The names of the shipped samples, sorted."""
    return sorted(SAMPLES)


def build_sample(name: str, config: ArmConfig | None = None) -> ActionGroup:
    """The action group of sample ``name``, made from its joint angles for ``config``."""
    spec = _spec(name)
    cfg = config or load_arm_config()
    frames = []
    for duration_ms, joints_deg, gripper_pulses in spec.frames:
        angles = cfg.check_joints(joints_deg)
        by_id = {j.servo_id: round(j.pulses_from_angle_deg(a))
                 for j, a in zip(cfg.joints, angles, strict=True)}
        by_id[cfg.gripper.servo_id] = gripper_pulses
        pulses = tuple(min(max(by_id[c], POSITION_MIN_PULSES), POSITION_MAX_PULSES)
                       for c in cfg.action_columns)
        frames.append(ActionFrame(duration_ms, pulses))
    return ActionGroup(tuple(frames))


def read_sample(name: str) -> ActionGroup:
    """The shipped ``.d6a`` file of sample ``name``, read."""
    _spec(name)
    resource = resources.files("busarm.arm") / SAMPLES_FOLDER / f"{name}{SUFFIX}"
    with resources.as_file(resource) as path:  # SQLite needs a real file
        return read_d6a(path)


def read_group_or_sample(spec: str | Path) -> tuple[ActionGroup, str]:
    """An action group from a ``.d6a`` file, or else a sample by name; and what it was.

    A file of that name wins over a sample. Neither: ConfigError naming the samples.
    """
    path = Path(spec)
    if path.exists():
        return read_d6a(path), str(path)
    if str(spec) in SAMPLES:
        return read_sample(str(spec)), f"sample {spec}"
    raise ConfigError(
        f"no action group file {spec} (and no sample of that name; samples: "
        f"{', '.join(sample_names())}: `busarm actions list`)"
    )


def write_samples(folder: Path | None = None) -> list[Path]:
    """(Re)make every sample file in ``folder`` (default: the package's samples folder)."""
    target = folder or Path(str(resources.files("busarm.arm") / SAMPLES_FOLDER))
    target.mkdir(parents=True, exist_ok=True)
    written = []
    for name in sample_names():
        path = target / f"{name}{SUFFIX}"
        write_d6a(path, build_sample(name))
        written.append(path)
    return written


def _spec(name: str) -> SampleSpec:
    try:
        return SAMPLES[name]
    except KeyError:
        raise ConfigError(
            f"no sample action group named {name!r}; samples: {', '.join(sample_names())}"
        ) from None


__all__ = [
    "SAMPLES",
    "SampleSpec",
    "build_sample",
    "read_group_or_sample",
    "read_sample",
    "sample_names",
    "write_samples",
]
