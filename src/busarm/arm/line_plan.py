"""Planning a straight tool line: waypoint times and joints, every one solved and checked.

Pure (no bus): ``Arm.plan_line`` plans with it from where the arm is, ``Arm.move_line``
streams the result. The path is sampled at ``rate_hz`` with a speed profile
(``busarm.arm.motion``); the IK at each waypoint continues from the previous one, and the
duration is stretched until no joint exceeds its speed limit between waypoints.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from busarm.arm.chain import Joints
from busarm.arm.config import ArmConfig, JointConfig
from busarm.arm.kinematics import ArmKinematics
from busarm.arm.motion import (
    LinePath,
    check_line_request,
    line_profile,
    sample_times,
)
from busarm.errors import LimitError, UnreachableError

DEFAULT_LINE_SPEED_MM_S = 80.0
DEFAULT_RATE_HZ = 50.0
MAX_RATE_HZ = 100.0
MAX_LINE_S = 600.0
"""The longest straight-line move planned."""
JUMP_DEG = 20.0
"""A joint change between two waypoints above this is a jump, not motion (at 50 Hz and
180 deg/s a joint moves 3.6 deg per waypoint)."""
MAX_TURN_SPEED_DEG_S = 90.0
"""Pitch and roll change no faster than this on a Cartesian line."""
STRETCH_TRIES = 8
"""Durations tried, each stretched by the last one's worst joint speed over its limit."""


def plan_line(
    config: ArmConfig, kin: ArmKinematics,
    target: tuple[float, float, float, float | None, float | None], *,
    start_deg: Sequence[float],
    speed_mm_s: float = DEFAULT_LINE_SPEED_MM_S,
    duration_s: float | None = None,
    profile: str = "min_jerk",
    rate_hz: float = DEFAULT_RATE_HZ,
) -> tuple[list[float], list[Joints]]:
    """``Arm.plan_line``: waypoint times and joints of a straight tool line from
    ``start_deg`` to ``target`` (x, y, z mm, pitch, roll deg; pitch and roll None keep
    the start's)."""
    check_line_request(
        target, speed_mm_s=speed_mm_s, duration_s=duration_s, profile=profile,
        rate_hz=rate_hz, max_rate_hz=MAX_RATE_HZ,
    )
    start_q = config.check_joints(start_deg)
    start = kin.fk(start_q)
    x_mm, y_mm, z_mm, pitch_deg, roll_deg = target
    pitch = start.pitch_deg if pitch_deg is None else pitch_deg
    roll = start.roll_deg if roll_deg is None else roll_deg
    end = (float(x_mm), float(y_mm), float(z_mm), float(pitch), float(roll))
    path = LinePath(tuple(start), end)  # type: ignore[arg-type]
    # The end must be reachable from the start's branch; check it first for a clear error.
    kin.ik_best(*end, current_deg=start_q)
    fn, shortest_s = line_profile(profile, path.length_mm, path.turn_deg, speed_mm_s,
                                  MAX_TURN_SPEED_DEG_S)
    if duration_s is None:
        duration_s = max(shortest_s, 1.0 / rate_hz)
    for _ in range(STRETCH_TRIES):
        times = sample_times(duration_s, rate_hz)
        joints = _waypoints(kin, path, fn, start_q, duration_s, times)
        _check_jumps(start_q, joints)
        ratio = _speed_ratio(config.joints, start_q, times, joints)
        if ratio <= 1.0:
            return times, joints
        duration_s *= ratio * 1.02
        if duration_s > MAX_LINE_S:
            break
    raise LimitError(
        f"the line would take over {MAX_LINE_S:g} s within the joints' speed limits: "
        "move there with move_to, or in shorter lines"
    )


def _waypoints(
    kin: ArmKinematics, path: LinePath, fn: Callable[[float], float],
    start_q: Sequence[float], duration_s: float, times: list[float],
) -> list[Joints]:
    """The joints at each waypoint time, each solved from the one before."""
    joints: list[Joints] = []
    previous: Sequence[float] = start_q
    for k, t in enumerate(times, start=1):
        pose = path.at(fn(t / duration_s))
        try:
            q = kin.ik_best(*pose, current_deg=previous)
        except UnreachableError as exc:
            raise UnreachableError(
                f"the line leaves the workspace at waypoint {k}/{len(times)} "
                f"({pose[0]:.1f}, {pose[1]:.1f}, {pose[2]:.1f}) mm: {exc}",
                exc.reason, exc.joint,
            ) from None
        joints.append(q)
        previous = q
    return joints


def _check_jumps(start_q: Sequence[float], joints: list[Joints]) -> None:
    steps = zip([start_q, *joints[:-1]], joints, strict=True)
    if any(abs(a - b) > JUMP_DEG for p, q in steps for a, b in zip(p, q, strict=True)):
        raise LimitError(
            "the line needs a joint to jump (it passes a singularity, such as the "
            "base axis, or switches elbow): move there with move_to instead"
        )


def _speed_ratio(
    joints_config: Sequence[JointConfig], start: Sequence[float], times: list[float],
    joints: list[Joints],
) -> float:
    """The largest joint speed between waypoints over its limit (1.0 = at the limit)."""
    worst = 0.0
    prev_t, prev_q = 0.0, start
    for t, q in zip(times, joints, strict=True):
        dt = t - prev_t
        for j, a, b in zip(joints_config, q, prev_q, strict=True):
            worst = max(worst, abs(a - b) / dt / j.max_speed_deg_s)
        prev_t, prev_q = t, q
    return worst


__all__ = [
    "DEFAULT_LINE_SPEED_MM_S",
    "DEFAULT_RATE_HZ",
    "MAX_LINE_S",
    "MAX_RATE_HZ",
    "plan_line",
]
