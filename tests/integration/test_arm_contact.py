"""Guarded lines (``Arm.move_line_guarded``) on the servo simulator: refusals that send
nothing, a joint stopped by an obstacle, and a way back that is blocked too.

The simulator's servos follow their commands exactly (no physics): an obstacle on a
servo (``SimServo.set_obstacle``) is what stops a joint short. Arm and simulator share a
simulated clock, so these run in a fraction of the time the moves take.
"""

from __future__ import annotations

import math
import pickle
from collections.abc import Iterator
from dataclasses import dataclass, field

import pytest

from busarm.arm.arm import Arm
from busarm.arm.config import load_arm_config
from busarm.arm.guard import GuardSettings
from busarm.bus.driver import ServoBus
from busarm.clock import SimClock
from busarm.errors import ConfigError, ContactError, MotionError, UnreachableError
from busarm.protocol import BROADCAST_ID, Command, FrameParser, Request, decode_request
from busarm.sim.bus import SimBus, WireTiming
from busarm.sim.transport import SimTransport

ABOVE = (200.0, 0.0, 60.0, -90.0, 0.0)
DOWN = (200.0, 0.0, 15.0, -90.0, 0.0)
SHOULDER = 2


@dataclass
class Rig:
    """An Arm on an in-process SimBus sharing a simulated clock, with every frame written."""

    arm: Arm
    sim: SimBus
    clock: SimClock
    writes: list[bytes] = field(default_factory=list)

    def requests(self, start: int = 0) -> list[Request]:
        parser = FrameParser()
        return [decode_request(f) for data in self.writes[start:] for f in parser.feed(data)]

    def moves(self, start: int = 0) -> list[Request]:
        return [r for r in self.requests(start)
                if r.command in (Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE)]

    def tool_mm(self) -> tuple[float, float, float]:
        p = self.arm.read_pose()
        return p.x_mm, p.y_mm, p.z_mm


@pytest.fixture
def rig() -> Iterator[Rig]:
    clock = SimClock(step_s=0.002)
    sim = SimBus.with_ids(timing=WireTiming(enabled=False), clock=clock)
    transport = SimTransport(sim)
    writes: list[bytes] = []
    original = transport.write

    def write(data: bytes) -> None:
        writes.append(bytes(data))
        original(data)

    transport.write = write  # type: ignore[method-assign]
    bus = ServoBus(transport)
    r = Rig(Arm(bus, load_arm_config()), sim, clock, writes)
    r.arm.move_to(*ABOVE, speed_deg_s=180.0)
    yield r
    bus.close()


def _shoulder_pulses(rig: Rig, pose: tuple[float, ...]) -> int:
    q = rig.arm.kin.ik_best(*pose, current_deg=rig.arm.read_joints_deg())
    return rig.arm.servo_pulses(q)[SHOULDER]


def _block_shoulder_halfway(rig: Rig) -> float:
    """An obstacle on the shoulder halfway down the descent; the pulses it stops at."""
    a, b = _shoulder_pulses(rig, ABOVE), _shoulder_pulses(rig, DOWN)
    stop = (a + b) / 2
    servo = rig.sim.servo(SHOULDER)
    servo.set_obstacle(min_pulses=stop) if b < a else servo.set_obstacle(max_pulses=stop)
    return stop


@pytest.mark.parametrize("bad", [
    {"x_mm": math.nan}, {"z_mm": math.inf}, {"pitch_deg": "down"}, {"speed_mm_s": 0.0},
    {"speed_mm_s": -50.0}, {"rate_hz": 500.0}, {"profile": "bogus"}, {"duration_s": 0.001},
    {"guard": "careful"},
])
def test_bad_arguments_are_refused_with_nothing_sent(rig: Rig, bad: dict[str, object]) -> None:
    args = {"x_mm": DOWN[0], "y_mm": DOWN[1], "z_mm": DOWN[2], "pitch_deg": -90.0} | bad
    start = len(rig.writes)
    with pytest.raises(ConfigError):
        rig.arm.move_line_guarded(**args)  # type: ignore[arg-type]
    assert rig.writes[start:] == []


@pytest.mark.parametrize("bad", [
    {"max_lag_deg": 0.0}, {"max_lag_deg": math.nan}, {"lag_time_s": -0.01},
    {"sample_every": 0}, {"sample_every": 1.5}, {"confirm_samples": 0},
    {"backoff_speed_mm_s": 1000.0},
])
def test_bad_guard_settings_are_refused(bad: dict[str, object]) -> None:
    with pytest.raises(ConfigError):
        GuardSettings(**bad)  # type: ignore[arg-type]


def test_an_unreachable_line_moves_nothing(rig: Rig) -> None:
    start = len(rig.writes)
    with pytest.raises(UnreachableError):
        rig.arm.move_line_guarded(600.0, 0.0, 15.0, -90.0)
    assert rig.moves(start) == []


def test_a_free_line_arrives_on_schedule(rig: Rig) -> None:
    move = rig.arm.move_line_guarded(*DOWN, speed_mm_s=200.0)
    assert move.samples and move.worst_lag_fraction < 0.5
    assert move.late_s < 1e-6  # the readings never delayed a waypoint
    assert math.dist(rig.tool_mm(), DOWN[:3]) < 2.0


def test_a_blocked_joint_stops_the_arm_which_backs_off(rig: Rig) -> None:
    start = rig.tool_mm()
    _block_shoulder_halfway(rig)
    with pytest.raises(ContactError) as caught:
        rig.arm.move_line_guarded(*DOWN, speed_mm_s=120.0)
    e = caught.value
    assert isinstance(e, MotionError)
    assert e.joint == "shoulder_pitch" and e.backed_off
    assert "shoulder_pitch" in str(e) and "backed off" in str(e)
    assert 10.0 < e.along_mm < 40.0, e.along_mm
    assert abs(e.tool_mm[2] - (start[2] - e.along_mm)) < 2.0
    assert math.dist(rig.tool_mm(), start) < 2.0
    assert all(rig.arm.bus.read_torque(j.servo_id) for j in rig.arm.config.joints)
    # It crosses process boundaries (bench workers) whole.
    copy = pickle.loads(pickle.dumps(e))
    assert (str(copy), copy.joint, copy.tool_mm, copy.backed_off) == (
        str(e), e.joint, e.tool_mm, e.backed_off)


def test_a_way_back_that_is_blocked_too_leaves_the_arm_stopped_and_holding(rig: Rig) -> None:
    stop = _block_shoulder_halfway(rig)
    servo = rig.sim.servo(SHOULDER)
    trapped: list[float] = []

    def trap() -> None:
        # Once the shoulder sits on the obstacle, something holds it there both ways.
        servo.advance(rig.clock.now())
        if not trapped and abs(servo.position_pulses - stop) < 0.5:
            trapped.append(rig.clock.now())
            servo.set_obstacle(stop - 0.5, stop + 0.5)

    rig.clock.attach(trap)
    start = len(rig.writes)
    try:
        with pytest.raises(ContactError) as caught:
            rig.arm.move_line_guarded(*DOWN, speed_mm_s=120.0)
    finally:
        rig.clock.detach(trap)
    e = caught.value
    assert trapped and not e.backed_off and e.joint == "shoulder_pitch"
    assert "backing off failed" in str(e) and "stopped and holding" in str(e)
    assert isinstance(e.__cause__, MotionError)
    requests = rig.requests(start)
    stops = [i for i, r in enumerate(requests)
             if r.command is Command.MOVE_STOP and r.servo_id == BROADCAST_ID]
    assert len(stops) >= 2  # on the contact, and again when the way back failed
    moving = (Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE, Command.MOVE_START,
              Command.LOAD_OR_UNLOAD_WRITE)
    assert any(r.command in moving for r in requests[stops[0]:stops[-1]])  # it tried ...
    assert not [r for r in requests[stops[-1]:] if r.command in moving]  # ... then stopped
    assert all(rig.arm.bus.read_torque(j.servo_id) for j in rig.arm.config.joints)

