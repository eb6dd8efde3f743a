"""A leader arm: a second arm of LX servos with its torque off, moved by a person's hand;
its joints, read at the follower's rate, are the follower's action.

``LeaderArm("/dev/ttyUSB1")`` (any busarm port: ``sim``, a pty of ``busarm sim serve``)
opens it limp (``Arm.set_torque(False)``); ``read()`` gives the motors in the state's
form (``NAME.pos`` in rad, ``gripper.gap_mm``) through its own calibration, which is
what makes a leader of another build drive this one; ``line`` how its servo line is
driven (busarm.robot.ServoLine: a reply's margin, retries). Closing leaves its torque off.

With ``background=True`` a thread reads the leader over and over (at most every
``READ_PERIOD_S``) and ``read()`` returns the newest reading at once: the leader's bus
and the follower's are then read side by side, not one after the other, which is what
keeps a loop over both at 30 frames a second and more. A failed read is raised by the
next ``read()``.
"""

from __future__ import annotations

import threading
import time
from types import TracebackType

from busarm.arm.config import ArmConfig
from busarm.errors import BusTimeoutError, ConfigError
from busarm.learn.features import motor_names
from busarm.robot import ArmSpec, CameraSpec, Robot, RobotConfig, ServoLine

__all__ = [
    "READ_PERIOD_S",
    "LeaderArm",
]

READ_PERIOD_S = 0.01
"""A background reader's shortest period (a read of six servos takes about 12 ms)."""


class LeaderArm:
    """``with LeaderArm(port) as leader: action = leader.read()``."""

    def __init__(self, port: str, *, config: ArmConfig | str | None = None,
                 background: bool = False, line: ServoLine | None = None) -> None:
        self.description = RobotConfig.from_port(
            port, arm=ArmSpec(config=config, line=line or ServoLine()),
            camera=CameraSpec(calibrate=False))
        self.background = background
        self.robot: Robot | None = None
        self.motors: tuple[str, ...] = ()
        self._newest: dict[str, float] | BaseException | None = None
        self._fresh = threading.Condition()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __repr__(self) -> str:
        return f"LeaderArm({self.description.world.name})"

    def open(self) -> LeaderArm:
        if self.robot is None:
            robot = Robot.open(self.description)
            try:
                robot.arm.set_torque(False)  # limp: a person moves it
            except BaseException:
                robot.close()
                raise
            self.robot = robot
            self.motors = tuple(motor_names(robot.config))
            if self.background:
                self._stop.clear()
                self._thread = threading.Thread(target=self._keep_reading, daemon=True,
                                                name="busarm-leader")
                self._thread.start()
        return self

    def _keep_reading(self) -> None:
        while not self._stop.is_set():
            start = time.monotonic()
            try:
                values: dict[str, float] | BaseException = self._read_now()
            except BaseException as exc:  # handed to the reader, who raises it
                values = exc
            with self._fresh:
                self._newest = values
                self._fresh.notify_all()
            if isinstance(values, BaseException):
                return
            self._stop.wait(max(0.0, READ_PERIOD_S - (time.monotonic() - start)))

    def read(self, timeout_s: float = 1.0) -> dict[str, float]:
        """The leader's joints (rad) and gripper gap (mm): read now, or in the background
        the newest reading (waiting up to ``timeout_s`` for the first)."""
        if self.robot is None:
            raise ConfigError("the leader arm is not open: open() it first")
        if not self.background:
            return self._read_now()
        with self._fresh:
            if self._newest is None:
                self._fresh.wait(timeout_s)
            newest = self._newest
        if newest is None:
            raise BusTimeoutError(f"the leader arm on {self.description.world.name} gave "
                                  f"no reading in {timeout_s:g} s")
        if isinstance(newest, BaseException):
            raise newest
        return dict(newest)

    def _read_now(self) -> dict[str, float]:
        assert self.robot is not None
        flat = self.robot.get_observation(cameras=False, scan=False).as_dict()
        return {name: float(flat[name]) for name in self.motors}

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._newest = None
        if self.robot is not None:
            robot, self.robot = self.robot, None
            robot.close()

    def __enter__(self) -> LeaderArm:
        return self.open()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
