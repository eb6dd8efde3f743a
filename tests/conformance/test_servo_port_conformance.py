"""The servo port contract (busarm.bus.servo_port), tested alike on every backend.

As python-can runs one suite on every interface, each test here runs on every backend
of ``backends.SERVO_BACKENDS``: the LX line in this process and on a pty (the adapter
echoing and not), the LX servos behind the simulated controller board on a pty, a robot
served over a loopback Zenoh link, and the example family written from
docs/adding_a_backend.md. Each test opens the port through the table, as a user does,
and checks what reached the servos in the simulation's own truth, never only what the
port says about itself. Moves are short: on a pty or a Zenoh link they take real time.
"""

from __future__ import annotations

import time

import pytest

from busarm.arm.arm import Arm
from busarm.arm.config import load_arm_config
from busarm.bus.servo_port import ServoPort
from busarm.errors import (
    BusTimeoutError,
    ConfigError,
    HaltedError,
    LimitError,
    MotionTimeoutError,
)
from conformance.backends import Backend

TOLERANCE_DEG = 1.0
"""Whole pulses, and a servo that settles a pulse or two short."""


def settle(backend: Backend, seconds: float) -> None:
    """Let ``seconds`` of the servos' time pass."""
    backend.port.clock.sleep(seconds)


def test_it_is_a_servo_port_with_a_sane_scale(backend: Backend) -> None:
    port = backend.port
    assert isinstance(port, ServoPort)
    m = port.model
    assert m.min_pulses < m.center_pulses < m.max_pulses and m.deg_per_pulse > 0
    assert m.deg_from_pulses(m.center_pulses) == 0.0
    assert m.min_deg < 0.0 < m.max_deg
    assert m.pulses_from_deg(m.deg_from_pulses(m.min_pulses + 7)) == m.min_pulses + 7
    assert isinstance(port.name, str) and port.name
    assert not port.wrote and not port.written_ids and port.halted is None


def test_a_timed_move_reaches_the_servo(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[1]
    start = port.clock.now()
    port.move_deg(sid, 30.0, 0.4)
    assert port.move_end_s([sid]) == pytest.approx(start + 0.4, abs=0.2)
    reached = port.wait_until_reached({sid: 30.0}, tolerance_deg=TOLERANCE_DEG)
    assert reached[sid] == pytest.approx(30.0, abs=TOLERANCE_DEG)
    assert backend.truth_deg(sid) == pytest.approx(30.0, abs=TOLERANCE_DEG)
    assert port.read_position_deg(sid) == pytest.approx(backend.truth_deg(sid), abs=0.5)
    assert port.model.deg_from_pulses(port.read_position_pulses(sid)) == pytest.approx(
        backend.truth_deg(sid), abs=0.5)
    assert port.last_target_pulses(sid) == port.model.pulses_from_deg(30.0)
    assert port.wrote and sid in port.written_ids


def test_a_synchronised_move_starts_and_arrives_together(backend: Backend) -> None:
    port = backend.port
    targets = {backend.ids[0]: 40.0, backend.ids[1]: -30.0, backend.ids[2]: 20.0}
    duration = port.sync_move_deg(targets, 1.2)
    assert duration == pytest.approx(1.2, abs=0.01)
    ends = [port.move_end_s([sid]) for sid in targets]
    assert max(ends) - min(ends) < 0.01
    settle(backend, 0.4)
    share = [backend.truth_deg(sid) / target for sid, target in targets.items()]
    # Part way, each as far along its own move as the others: they started together.
    assert all(0.05 < s < 0.95 for s in share), share
    assert max(share) - min(share) < 0.3, share
    port.wait_until_reached(targets, tolerance_deg=TOLERANCE_DEG)
    for sid, target in targets.items():
        assert backend.truth_deg(sid) == pytest.approx(target, abs=TOLERANCE_DEG)


def test_a_move_at_a_speed_takes_the_largest_move_over_the_speed(backend: Backend) -> None:
    port = backend.port
    a, b = backend.ids[0], backend.ids[3]
    duration = port.sync_move_deg({a: 24.0, b: -12.0}, speed_deg_s=60.0)
    assert duration == pytest.approx(0.4, abs=0.02)
    port.wait_until_reached({a: 24.0, b: -12.0}, tolerance_deg=TOLERANCE_DEG)
    assert backend.truth_deg(a) == pytest.approx(24.0, abs=TOLERANCE_DEG)


def test_a_target_beyond_the_limits_is_refused_before_anything_is_sent(
        backend: Backend) -> None:
    port = backend.port
    a, b = backend.ids[0], backend.ids[1]
    port.set_limits_deg(b, -10.0, 10.0)
    before, where = backend.writes(), (backend.truth_deg(a), backend.truth_deg(b))
    with pytest.raises(LimitError, match=f"servo {b}"):
        port.move_deg(b, 20.0, 0.2)
    with pytest.raises(LimitError):  # one bad target: none of them goes, not even a's
        port.sync_move_deg({a: 5.0, b: -20.0}, 0.5)
    with pytest.raises(ConfigError):  # beyond the servo itself
        port.move_deg(a, port.model.max_deg + 1.0, 0.2)
    with pytest.raises(ConfigError):
        port.set_limits_deg(a, 10.0, -10.0)
    settle(backend, 0.1)  # anything sent would have arrived by now
    assert backend.writes() == before and not port.wrote
    assert (backend.truth_deg(a), backend.truth_deg(b)) == pytest.approx(where, abs=0.3)
    port.move_deg(b, 9.0, 0.2)  # within them: it goes
    port.wait_until_reached({b: 9.0}, tolerance_deg=TOLERANCE_DEG)


def test_stop_holds_the_servo_where_it_is(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[2]
    port.move_deg(sid, 60.0, 2.0)
    settle(backend, 0.5)
    port.stop([sid])
    settle(backend, 0.1)
    held = backend.truth_deg(sid)
    assert 3.0 < held < 50.0, held  # stopped part way
    settle(backend, 0.5)
    assert backend.truth_deg(sid) == pytest.approx(held, abs=TOLERANCE_DEG)
    assert backend.is_loaded(sid)  # holding there, not limp


def test_the_emergency_stop_holds_every_servo(backend: Backend) -> None:
    port = backend.port
    a, b = backend.ids[0], backend.ids[1]
    port.sync_move_deg({a: 60.0, b: -60.0}, 2.0)
    settle(backend, 0.5)
    port.emergency_stop()
    settle(backend, 0.1)
    held = (backend.truth_deg(a), backend.truth_deg(b))
    assert 3.0 < held[0] < 50.0 and -50.0 < held[1] < -3.0, held
    settle(backend, 0.5)
    assert (backend.truth_deg(a), backend.truth_deg(b)) == pytest.approx(held, abs=1.0)


def test_a_halt_refuses_every_write_but_a_stop_until_rearmed(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[1]
    port.move_deg(sid, 30.0, 1.0)
    settle(backend, 0.3)
    port.halt("conformance")
    assert port.halted == "conformance"
    settle(backend, 0.1)
    held, before = backend.truth_deg(sid), backend.writes()
    assert 1.0 < held < 28.0, held
    with pytest.raises(HaltedError):
        port.move_deg(sid, 0.0, 0.2)
    with pytest.raises(HaltedError):
        port.sync_move_deg({sid: 0.0}, 0.2)
    with pytest.raises(HaltedError):
        port.set_torque(sid, False)
    with pytest.raises(HaltedError):  # a wait for a move that was stopped
        port.wait_until_reached({sid: 30.0}, timeout_s=0.5)
    assert backend.writes() == before
    port.stop([sid])  # a stop still goes out, and reads go on
    port.read_position_pulses(sid)
    assert backend.truth_deg(sid) == pytest.approx(held, abs=TOLERANCE_DEG)
    port.rearm()
    assert port.halted is None
    port.move_deg(sid, 0.0, 0.3)
    port.wait_until_reached({sid: 0.0}, tolerance_deg=TOLERANCE_DEG)


def test_a_silent_servo_is_a_typed_timeout_not_a_hang(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[0]
    port.read_position_pulses(sid)  # it answers, until...
    backend.silence(sid)
    began = time.monotonic()
    with pytest.raises(BusTimeoutError):
        port.read_position_pulses(sid)
    with pytest.raises(BusTimeoutError):
        port.read_torque(sid)
    with pytest.raises(BusTimeoutError):  # an ID nobody has
        port.read_temp_c(42)
    assert time.monotonic() - began < 20.0
    port.read_position_pulses(backend.ids[1])  # the others still answer


def test_a_wait_names_the_servos_that_did_not_arrive(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[3]
    port.move_deg(sid, 10.0, 0.2)
    with pytest.raises(MotionTimeoutError, match=f"servo {sid}"):
        port.wait_until_reached({sid: 40.0}, timeout_s=0.5)


def test_torque_off_leaves_a_servo_limp_and_on_holds_it(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[0]
    port.move_deg(sid, 5.0, 0.1)
    port.wait_until_reached({sid: 5.0}, tolerance_deg=TOLERANCE_DEG)
    port.set_torque(sid, False)
    assert not port.read_torque(sid) and not backend.is_loaded(sid)
    port.set_torque(sid, True)
    assert port.read_torque(sid) and backend.is_loaded(sid)


def test_offsets_limits_and_readings(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[1]
    assert port.read_offset_deg(sid) == 0.0
    step = port.model.deg_per_pulse
    port.adjust_offset_deg(sid, 10 * step)
    port.save_offset(sid)
    assert port.read_offset_deg(sid) == pytest.approx(10 * step, abs=step / 2)
    lo, hi = port.read_angle_limits_deg(sid)
    assert port.model.min_deg <= lo < 0.0 < hi <= port.model.max_deg
    assert 0 < port.read_temp_c(sid) < port.read_temp_limit_c(sid) <= 100
    lo_v, hi_v = port.read_vin_limits_v(sid)
    assert lo_v <= port.read_vin_v(sid) <= hi_v
    states = port.read_states(backend.ids[:2])
    assert [s.servo_id for s in states] == list(backend.ids[:2])
    assert states[0].position_deg == pytest.approx(backend.truth_deg(backend.ids[0]), abs=0.5)


def test_leaving_the_port_by_an_exception_stops_and_holds(backend: Backend) -> None:
    port, sid = backend.port, backend.ids[2]
    with pytest.raises(RuntimeError, match="the program failed"), port:
        port.move_deg(sid, 60.0, 2.0)
        settle(backend, 0.4)
        raise RuntimeError("the program failed")
    backend.closed = True  # the block's exit closed it
    settle(backend, 0.1)
    held = backend.truth_deg(sid)
    assert 2.0 < held < 50.0, held
    settle(backend, 0.5)
    assert backend.truth_deg(sid) == pytest.approx(held, abs=TOLERANCE_DEG)


def test_an_arm_runs_on_the_port(backend: Backend) -> None:
    """``Arm`` knows only the contract: on any backend it checks its servos, moves in
    joint degrees and refuses what is beyond its joints, sending nothing."""
    port = backend.port
    arm = Arm(port, load_arm_config())  # not closed here: the port is the fixture's
    start = arm.read_joints_deg()
    target = (start[0] + 15.0, start[1], start[2] - 10.0, start[3], start[4])
    arm.move_joints(target, duration_s=0.6)
    truth = arm.joints_from_pulses({j.servo_id: port.model.pulses_exact(
        backend.truth_deg(j.servo_id)) for j in arm.config.joints})
    assert truth == pytest.approx(target, abs=1.5)
    before = backend.writes()
    with pytest.raises(LimitError):
        arm.move_joints((target[0] + 500.0, *target[1:]), duration_s=1.0)
    assert backend.writes() == before
