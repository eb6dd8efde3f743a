"""The dashboard's base teleop on its own, on a hand-turned clock and a recording base:
the held twist is repeated, a silence of BASE_HOLD_S stops the wheels (heartbeats do not
count), a stop is sent even when not driving, a base that refuses ends the drive, a twist
beyond the limits is refused before anything is sent."""

from __future__ import annotations

import pytest

from busarm.base.config import load_chassis_config
from busarm.base.kinematics import MecanumKinematics, Twist
from busarm.dashboard.protocol import BaseDrive, RequestError
from busarm.dashboard.teleop import BASE_HOLD_S, DRIVE_PERIOD_S, BaseTeleop
from busarm.errors import HaltedError


class RecordingBase:
    """What a Base is asked: drive(vx, vy, wz) and stop(), in order."""

    def __init__(self) -> None:
        self.config = load_chassis_config()
        self.kinematics = MecanumKinematics(self.config)
        self.sent: list[tuple[float, float, float] | str] = []
        self.refuse = False

    def drive(self, vx_m_s: float, vy_m_s: float, wz_rad_s: float) -> Twist:
        if self.refuse:
            raise HaltedError("wheel speeds refused: the robot is halted")
        self.sent.append((vx_m_s, vy_m_s, wz_rad_s))
        return Twist(vx_m_s, vy_m_s, wz_rad_s)

    def stop(self) -> None:
        self.sent.append("stop")


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def teleop() -> tuple[BaseTeleop, RecordingBase, Clock, list[str]]:
    base, clock, said = RecordingBase(), Clock(), list[str]()
    return (BaseTeleop(base, lambda text, level: said.append(text), now=clock),  # type: ignore[arg-type]
            base, clock, said)


def test_a_held_twist_is_repeated_and_stops_when_not_asked_again() -> None:
    t, base, clock, said = teleop()
    t.start(t.check(BaseDrive("base_drive", 0.2, 0.0, 0.0)))
    assert base.sent == [(0.2, 0.0, 0.0)]
    t.tick()  # not due yet
    clock.t += DRIVE_PERIOD_S + 0.001
    t.tick()
    assert base.sent == [(0.2, 0.0, 0.0)] * 2
    clock.t += BASE_HOLD_S - DRIVE_PERIOD_S - 0.01  # asked again just in time
    t.start(t.check(BaseDrive("base_drive", 0.2, 0.0, 0.0)))
    clock.t += BASE_HOLD_S + 0.001  # then silence (heartbeats are not asked of it)
    t.tick()
    assert base.sent[-1] == "stop" and t.twist is None
    assert said == ["base: driving at +0.20 m/s forward, +0.00 m/s left, +0 deg/s",
                    "base stopped (no drive from the driver for 250 ms)"]
    t.tick()
    assert base.sent[-1] == "stop" and said[-1].startswith("base stopped")  # nothing more


def test_a_stop_always_goes_out_and_a_refusing_base_ends_the_drive() -> None:
    t, base, clock, said = teleop()
    t.stop("released")
    assert base.sent == ["stop"] and said == []  # sent; nothing was driving to say
    t.start(Twist(0.0, 0.1, 0.0))
    base.refuse = True
    clock.t += DRIVE_PERIOD_S + 0.001
    t.tick()
    assert t.twist is None and base.sent[-1] == "stop"
    assert said[-1] == ("base stopped (the base refused: wheel speeds refused: the robot is "
                        "halted)")
    with pytest.raises(HaltedError):
        t.start(Twist(0.1, 0.0, 0.0))
    assert t.twist is None


@pytest.mark.parametrize(("vx", "vy", "wz", "said"), [
    (0.5, 0.0, 0.0, "base_drive: vx = 0.5 m/s is beyond the chassis's limit"),
    (0.0, 0.0, -2.2, "base_drive: wz = -126.051 deg/s is beyond the chassis's limit"),
    (0.3, 0.3, 0.0, "base_drive: vx 0.3 m/s, vy 0.3 m/s and wz 0 deg/s together need a "
                    "wheel at"),
])
def test_a_twist_beyond_the_limits_is_refused_before_anything_is_sent(
        vx: float, vy: float, wz: float, said: str) -> None:
    t, base, _, _ = teleop()
    with pytest.raises(RequestError, match="^" + said.replace("(", r"\(").replace(")", r"\)")):
        t.check(BaseDrive("base_drive", vx, vy, wz))
    assert base.sent == []
