"""The mobile twin's base: the simulated board's wheels move the chassis, as a floor would.

Every control tick, before physics steps, the wheels' actual speeds (the simulated
board's speed loops, brought up to now) become the body's twist through the chassis's
mecanum kinematics; the floor takes less than that (``SlipModel``: a share lost forward,
more sideways, where mecanum rollers scrub, and in turns, plus a slowly wandering extra
share), and the chassis's velocity actuators are set to it in the arena's frame. After
physics, the IMU's gyro reads the chassis's true yaw rate (its mean since the last
sample) plus a bias, and the encoders
count the wheels' own turns (with jitter): so odometry from them drifts as a real one
does, and the twin knows where the robot really is (``pose``, ``path``).

Without a board attached (an arena twin on a plain servo bus) the base stands still.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Any

from busarm.base.config import ChassisConfig
from busarm.base.kinematics import MecanumKinematics
from busarm.base.odometry import Pose2D, wrap_rad
from busarm.sim.board import SimBoard
from busarm.twin.arena import StartPose

__all__ = [
    "MAX_PATH_POINTS",
    "PATH_PERIOD_S",
    "MobileBase",
    "Motors",
    "SlipModel",
]


Motors = tuple[float, float, float, float]
"""The board's four motor speeds (rev/s, as mounted)."""
PATH_PERIOD_S = 0.05
"""How often the true path is sampled (for pictures and benchmarks)."""
MAX_PATH_POINTS = 200_000


@dataclass(frozen=True)
class SlipModel:
    """How the floor takes the wheels' motion, and the sensors' imperfections.

    Shares are of the motion the wheels' turning would give; the defaults are plausible
    for rubber mecanum rollers on a hard floor (grade C: not measured on a robot).
    """

    forward: float = 0.015
    sideways: float = 0.05
    turn: float = 0.03
    jitter: float = 0.01
    """Standard deviation of the extra share lost, wandering with ``jitter_time_s``."""
    jitter_time_s: float = 0.5
    encoder_noise_ticks: float = 0.5
    """A count may read one off now and then (an edge dithering); it never accumulates."""
    gyro_bias_rad_s: float = 0.003

    @classmethod
    def none(cls) -> SlipModel:
        """An ideal floor and ideal sensors."""
        return cls(0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0)


class MobileBase:
    """The chassis's planar joints in a twin's model, driven by an attached SimBoard."""

    def __init__(self, model: Any, data: Any, chassis: ChassisConfig, start: StartPose,
                 slip: SlipModel | None = None, seed: int = 0) -> None:
        self.kinematics = MecanumKinematics(chassis)
        self.slip = slip if slip is not None else SlipModel()
        self.board: SimBoard | None = None
        names = ("chassis_x", "chassis_y", "chassis_yaw")
        joints = [model.joint(name) for name in names]
        self._qpos = [int(j.qposadr[0]) for j in joints]
        self._dof = [int(j.dofadr[0]) for j in joints]
        self._act = [int(model.actuator(name).id) for name in names]
        self._rng = random.Random(seed)
        self._jitter = [0.0, 0.0, 0.0]
        self._last_s: float | None = None
        self._twist_of: tuple[Motors | None, tuple[float, float, float]] = (None, (0.0, 0.0, 0.0))
        """The last wheel speeds and the body twist they give (vx, vy, wz)."""
        self.path: list[tuple[float, float, float]] = []
        """The true path: (simulated s, x m, y m), every ``PATH_PERIOD_S``."""
        self._path_due = 0.0
        self._model = model
        self._chassis_geom = int(model.geom("chassis").id)
        self._touching: frozenset[int] = frozenset()
        self.contacts: list[tuple[float, str]] = []
        """Every time something began to touch the chassis: (simulated s, its geom's name);
        ground truth for benches (a wall, a table, a box, a block)."""
        for adr, value in zip(self._qpos, (start.x_m, start.y_m, math.radians(start.yaw_deg)),
                              strict=True):
            data.qpos[adr] = value

    def attach(self, board: SimBoard) -> None:
        """Drive the base by ``board``'s wheels; its gyro and encoders become the twin's."""
        board.imu_follows_wheels = False
        board.encoder_noise_ticks = self.slip.encoder_noise_ticks
        self.board = board

    def pose(self, data: Any) -> Pose2D:
        """Where the chassis really is (arena frame; ground truth)."""
        x, y, yaw = (float(data.qpos[a]) for a in self._qpos)
        return Pose2D(x, y, wrap_rad(yaw))

    def speed(self, data: Any) -> tuple[float, float, float]:
        """The chassis's true velocity: m/s in x, y of the arena, rad/s."""
        vx, vy, wz = (float(data.qvel[a]) for a in self._dof)
        return vx, vy, wz

    def read_wheels(self, now: float) -> Motors | None:
        """The board's motor speeds at ``now`` (None without a board). Called before the
        twin takes the servo line's lock: the board takes that lock under its own when
        it relays a servo's reply, so taking the board's under it could deadlock."""
        return None if self.board is None else self.board.motor_rev_s(now)

    def before_physics(self, data: Any, now: float, motors: Motors | None) -> None:
        """Set the chassis's velocity from the wheels' speeds (``read_wheels``)."""
        if motors is None:
            for act in self._act:
                data.ctrl[act] = 0.0
            return
        dt = 0.0 if self._last_s is None else max(0.0, now - self._last_s)
        self._last_s = now
        s = self.slip
        if s.jitter > 0 and dt > 0:
            keep = math.exp(-dt / s.jitter_time_s)
            spread = s.jitter * math.sqrt(1.0 - keep * keep)
            self._jitter = [j * keep + self._rng.gauss(0.0, spread) for j in self._jitter]
        if motors != self._twist_of[0]:  # the wheels' speeds change less often than ticks
            twist = self.kinematics.twist_from_rev_s(self.kinematics.wheels_from_motors(
                {k + 1: rev_s for k, rev_s in enumerate(motors)}))
            self._twist_of = (motors, (twist.vx_m_s, twist.vy_m_s, twist.wz_rad_s))
        tx, ty, tw = self._twist_of[1]
        jx, jy, jw = (abs(j) for j in self._jitter)
        vx = tx * max(0.0, 1.0 - s.forward - jx)
        vy = ty * max(0.0, 1.0 - s.sideways - jy)
        wz = tw * max(0.0, 1.0 - s.turn - jw)
        yaw = float(data.qpos[self._qpos[2]])
        c, sn = math.cos(yaw), math.sin(yaw)
        data.ctrl[self._act[0]] = vx * c - vy * sn
        data.ctrl[self._act[1]] = vx * sn + vy * c
        data.ctrl[self._act[2]] = wz

    def after_physics(self, data: Any) -> None:
        """Give the gyro the true heading (plus its bias's drift); sample the path."""
        if self.board is not None:
            yaw = float(data.qpos[self._qpos[2]])
            self.board.imu_heading_rad = yaw + self.slip.gyro_bias_rad_s * float(data.time)
        t = float(data.time)
        self._note_contacts(data, t)
        if t >= self._path_due and len(self.path) < MAX_PATH_POINTS:
            p = self.pose(data)
            self.path.append((t, p.x_m, p.y_m))
            self._path_due = t + PATH_PERIOD_S

    def _note_contacts(self, data: Any, t: float) -> None:
        ncon = data.ncon
        if ncon == 0 and not self._touching:
            return
        # As plain ints: a row of a MuJoCo array costs a numpy object per contact.
        pairs = data.contact.geom[:ncon].tolist()
        g = self._chassis_geom
        touching = frozenset(o for a, b in pairs if g in (a, b) for o in (a, b) if o != g)
        for other in touching - self._touching:
            self.contacts.append((t, self._model.geom(other).name or f"geom {other}"))
        self._touching = touching
