"""The bus driver end to end: ServoBus against the simulated arm.

Every test that takes ``arm`` runs five ways (see conftest): in-process and through a
real pseudo-terminal, each with the simulated adapter echoing and not, and through the
simulated controller board on a pty (``board:///dev/pts/N``) in front of the same
servos. Tests of the LX wire itself, or of LX commands the board cannot pass on, say so
and run the four LX ways. Nothing of busarm is mocked; what a call did is checked on the
simulator's servos.

Time is the simulator's clock (``arm.sim.clock``): simulated in-process, where every
time a test reads is exact whatever else the computer does; the wall clock through a
pty, where a busy computer may serve the bytes late. The motion model is exact, so
instead of sleeping to see where a servo is at some moment, a test asks a copy of the
servo's model (``predicted``, ``MoveWatch.predicted``): the real servo is left alone.
The moment a move starts is bracketed (``MoveWatch.start_bounds``): not before the call
was made, not after the servos heard it plus its bytes' time on the line. In-process the
bracket is exactly that line time; through a pty it also holds what the computer took
to pass the bytes on, so a loaded machine widens it rather than failing the test.
"""

from __future__ import annotations

import copy
import dataclasses
import re
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from busarm.bus.driver import ServoBus
from busarm.bus.id_scan import SCAN_MARGIN_S
from busarm.errors import (
    BusConflictError,
    BusTimeoutError,
    ConfigError,
    LimitError,
    MotionTimeoutError,
    TransportError,
    UnsupportedError,
)
from busarm.protocol import BROADCAST_ID, SPECS, AlarmFlag, Command, Request, ServoMode
from busarm.protocol.board import BoardFrameParser, ServoRead, ServoSub
from busarm.protocol.board import decode_request as decode_board_request
from busarm.sim.bus import ARM_SERVO_IDS
from busarm.sim.pty import PtyServer
from busarm.sim.servo import SimServo
from busarm.sim.servo_params import FULL_TURN_PULSES, ServoParams
from conftest import (
    BOARD_WAY,
    LX_WAYS,
    PTY_MARGIN_S,
    WAYS,
    SimArm,
    lx_commands_only,
    make_sim_arm_way,
    wait_for,
)

ArmFactory = Callable[..., SimArm]
"""``arm_with(ids, **bus_kwargs)``: a simulated bus with these servo IDs, the ``way`` given."""

WALL_SLACK_S = 0.005
"""What a read may take beyond its budget on the wall clock on an idle computer: the
work around its waits. A busy computer adds its wake-ups (``WakeUps``)."""
WAKE_UP_STEP_S = 0.002

BUSY_MARGIN_S = 0.5
"""The reply margin through a pty for a test of many reads whose deadline it does not
check (``PTY_MARGIN_S`` is enough for a few)."""

WAIT_S = 10.0
"""The timeout of a wait for a move whose deadline is not what the test checks: only a
failing test waits it out (in-process, in simulated seconds)."""

MOVE_FRAMES = (Command.MOVE_TIME_WRITE, Command.MOVE_TIME_WAIT_WRITE)
STARTS = (Command.MOVE_TIME_WRITE, Command.MOVE_START)
"""What starts a servo's move: a move frame of its own, or the MOVE_START broadcast."""
MOVE_FRAME_BYTES = 10
MOVE_START_BYTES = 6
SYNC_BYTES = 6
"""The request of ``sync``'s read (a pty may pass it on with the moves' last bytes)."""


def now(arm: SimArm) -> float:
    """The simulator's time (simulated in-process, the wall clock's through a pty)."""
    return arm.sim.clock.now()


def sync(arm: SimArm, servo_id: int = 1) -> None:
    """A read: once it is answered, the simulator has handled every byte sent before it."""
    arm.bus.read_temp_c(servo_id)


def predicted(arm: SimArm, servo_id: int, at: float) -> SimServo:
    """A copy of a servo's model advanced to time ``at`` of the simulator's clock (the
    servo is untouched)."""
    servo = copy.deepcopy(arm.sim.servo(servo_id))
    servo.advance(at)
    return servo


def position_now(arm: SimArm, servo_id: int) -> float:
    arm.sim.advance()
    return arm.sim.servo(servo_id).position_pulses


def place(arm: SimArm, positions: dict[int, float]) -> None:
    """Turn unloaded horns by hand (power-on servos are unloaded)."""
    at = now(arm)
    for sid, pulses in positions.items():
        arm.sim.servo(sid).move_by_hand(pulses, at)


def scan_margin_s(arm: SimArm) -> float:
    """The margin of a scan's deadlines: the scan's own tight one on a simulated clock;
    through a pty the bus's own (``PTY_MARGIN_S``), as a busy computer may pass a reply on
    in the next ID's window, and which window a garbled reply lands in is what tells
    two servos on one ID (what these tests check, not the scan's deadline)."""
    return SCAN_MARGIN_S if arm.sim.clock.is_simulated else PTY_MARGIN_S


def hear(arm: SimArm) -> list[tuple[Command, int]]:
    """Every request the servos hear from now on, as (command, ID), but ``sync``'s reads
    (through a pty, a busy computer may have the driver ask one of those twice)."""
    heard: list[tuple[Command, int]] = []

    def tap(request: Request) -> None:
        if (request.command, request.servo_id) != (Command.TEMP_READ, 1):
            heard.append((request.command, request.servo_id))

    arm.sim.taps.append(tap)
    return heard


class MoveWatch:
    """What the servos hear of the moves sent from now on (a tap on the simulator): the
    move frames, when each move was started, and the servos' models as the moves left
    them. Made just before the call that moves."""

    def __init__(self, arm: SimArm) -> None:
        self.arm = arm
        self.t0 = now(arm)
        """Before the call: no move it sends can start earlier."""
        self.moves: list[tuple[Command, int, int, int]] = []
        """The move frames heard: (command, ID, pulses, ms)."""
        self.started: dict[int, float] = {}
        """When the servos heard what starts each servo's move (254: MOVE_START)."""
        self.models: dict[int, SimServo] = {}
        """Copies of the servos' models taken when the first frame after the moves came
        (the sync read): nothing later has moved them on, however late a busy computer
        served that read."""
        self._copy_next = False
        arm.sim.taps.append(self._tap)

    def _tap(self, request: Request) -> None:  # in the simulator, under its lock
        command = request.command
        if command in MOVE_FRAMES:
            self.moves.append((command, request.servo_id, *request.args[:2]))
        if command in STARTS:
            self.started[request.servo_id] = now(self.arm)
            self._copy_next = True
        elif self._copy_next and command not in MOVE_FRAMES:
            self.models = {s.servo_id: copy.deepcopy(s) for s in self.arm.sim.servos}
            self._copy_next = False

    def start_bounds(self, servo_id: int) -> tuple[float, float]:
        """The earliest and the latest the servo's move can have started: not before the
        watch was made, and not after the servos heard what starts it plus the line time
        of everything sent since (the move frames, a MOVE_START and the sync read): the
        simulator takes in the bytes the host passed on together, and a frame takes
        effect once the last of them is in."""
        heard = self.started.get(servo_id, self.started.get(BROADCAST_ID))
        assert heard is not None, f"nothing started servo {servo_id}: {self.moves}"
        line_bytes = MOVE_FRAME_BYTES * len(self.moves) + MOVE_START_BYTES + SYNC_BYTES
        return self.t0, heard + line_bytes * self.arm.sim.timing.byte_s

    def predicted(self, servo_id: int, at: float) -> SimServo:
        """A copy of the servo's model as the moves left it, advanced to ``at``."""
        assert self.models, "no frame came after the moves: sync first"
        servo = copy.deepcopy(self.models[servo_id])
        servo.advance(at)
        return servo


class WakeUps:
    """How late a waiting thread of this process wakes up, at worst, while the ``with``
    block runs (a thread sleeping in short steps beside it): on the wall clock the
    driver's waits end that late too, tens of ms on a busy computer."""

    def __init__(self) -> None:
        self.worst_s = 0.0
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._watch, name="wake-ups", daemon=True)

    def _watch(self) -> None:
        while not self._done.is_set():
            t = time.monotonic()
            time.sleep(WAKE_UP_STEP_S)
            self.worst_s = max(self.worst_s, time.monotonic() - t - WAKE_UP_STEP_S)

    def __enter__(self) -> WakeUps:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join()


def read_budget_s(bus: ServoBus, command: Command, wake_ups: int, worst_wake_up_s: float
                  ) -> float:
    """How long a read of ``command`` may take: exactly the driver's budget on a simulated
    clock; on the wall clock, that and the work around it and ``wake_ups`` waits each
    ending as late as the worst wake-up seen meanwhile."""
    if bus.clock.is_simulated:
        return bus.read_budget_s(command)
    return bus.read_budget_s(command) + WALL_SLACK_S + wake_ups * worst_wake_up_s


# ---------------------------------------------------------------------- scan


def test_scan_finds_exactly_the_arm(arm: SimArm) -> None:
    result = arm.bus.scan()
    assert result.found == [1, 2, 3, 4, 5, 10]
    assert result.conflicts == []


def test_scan_of_a_subset(arm: SimArm) -> None:
    result = arm.bus.scan([200, 10, 7, 2, 0], margin_s=scan_margin_s(arm))
    assert result.found == [2, 10]
    assert result.conflicts == []


# Two servos' replies colliding on the LX wire: the board hands back a value or -1, never
# the line's bytes, so it cannot tell a shared ID from an absent one.
@pytest.mark.parametrize("way", LX_WAYS)
def test_scan_reports_two_servos_on_one_id(way: str, arm_with: ArmFactory) -> None:
    arm = arm_with((1, 3, 3))
    result = arm.bus.scan(range(6), margin_s=scan_margin_s(arm))
    assert 1 in result.found
    assert result.conflicts == [3]


# ---------------------------------------------------------------------- readings


def test_readings_match_the_simulator(arm: SimArm) -> None:
    positions = {1: 120.0, 2: 260.0, 3: 500.0, 4: 737.0, 5: 905.0, 10: 33.0}
    place(arm, positions)
    for sid in ARM_SERVO_IDS:
        servo = arm.sim.servo(sid)
        servo.supply_mv = 10000 + 37 * sid
        # At its surroundings' temperature an idle servo stays there: the reading does
        # not depend on how long the test takes.
        servo.params = dataclasses.replace(servo.params, ambient_c=30.5 + sid)
        servo.temperature_c = 30.5 + sid
    for sid in ARM_SERVO_IDS:
        assert arm.bus.read_position_pulses(sid) == positions[sid]
        assert arm.bus.read_position_pulses(sid) == round(position_now(arm, sid))
        assert arm.bus.read_position_deg(sid) == pytest.approx((positions[sid] - 500) * 0.24)
        assert arm.bus.read_vin_v(sid) == pytest.approx((10000 + 37 * sid) / 1000)
        assert arm.bus.read_vin_v(sid) == arm.sim.servo(sid).supply_mv / 1000
        assert arm.bus.read_temp_c(sid) == 30 + sid
    states = arm.bus.read_states([10, 1])
    assert [s.servo_id for s in states] == [10, 1]
    assert states[0].position_deg == pytest.approx((33 - 500) * 0.24)
    assert states[0].temp_c == 40
    assert states[0].vin_v == pytest.approx(10.37)
    assert states[1].position_deg == pytest.approx((120 - 500) * 0.24)


def test_negative_position_near_the_end_stop(arm: SimArm) -> None:
    # Below 0 pulses the potentiometer still reads (signed 16-bit on the wire, and in the
    # board's reply).
    place(arm, {2: -40.0})
    assert arm.bus.read_position_pulses(2) == -40
    assert arm.bus.read_position_deg(2) == pytest.approx(-540 * 0.24)


# ---------------------------------------------------------------------- motion


def test_move_deg_and_wait_until_reached(arm: SimArm) -> None:
    watch = MoveWatch(arm)
    arm.bus.move_deg(1, 30.0, 0.2)
    sync(arm)
    assert watch.moves == [(Command.MOVE_TIME_WRITE, 1, 625, 200)]
    earliest, _ = watch.start_bounds(1)
    halfway = watch.predicted(1, earliest + 0.1).position_pulses
    assert abs(halfway - 625) > 10, "a 0.2 s move must not arrive at once"
    positions = arm.bus.wait_until_reached({1: 30.0}, tolerance_deg=0.3, timeout_s=WAIT_S)
    assert positions[1] == pytest.approx(30.0, abs=0.3)
    # Within the tolerance now (on a pty the last 0.3 deg may still be under way), and
    # exactly there once the move's time is over.
    assert position_now(arm, 1) == pytest.approx(625, abs=0.3 / 0.24)
    _, latest = watch.start_bounds(1)
    assert watch.predicted(1, latest + 0.2).position_pulses == pytest.approx(625, abs=1e-6)
    assert arm.sim.servo(1).is_loaded


def test_wait_until_reached_times_out_naming_the_servo(arm: SimArm) -> None:
    arm.bus.move_deg(4, -24.0, 0.0)
    with pytest.raises(MotionTimeoutError, match="servo 4"):
        arm.bus.wait_until_reached({4: 24.0, 1: 0.0}, timeout_s=0.05)


def test_sync_move_starts_and_arrives_together(arm: SimArm) -> None:
    targets = {1: 24.0, 2: -36.0, 3: 48.0, 4: -12.0, 5: 60.0, 10: 12.0}
    watch = MoveWatch(arm)
    duration = arm.bus.sync_move_deg(targets, 0.4)
    assert duration == pytest.approx(0.4)
    sync(arm)
    # Every servo started within the same bracket (in-process: the frames' time on the
    # line); halfway through it, each is halfway, give or take half the bracket.
    bounds = [watch.start_bounds(sid) for sid in targets]
    earliest = min(lo for lo, _ in bounds)
    latest = max(hi for _, hi in bounds)
    halfway_at = (earliest + latest) / 2 + duration / 2
    halfway = {}
    for sid, deg in targets.items():
        target = 500 + deg / 0.24
        servo = watch.predicted(sid, halfway_at)
        halfway[sid] = (servo.position_pulses - 500) / (target - 500)
        assert watch.predicted(sid, latest + duration).position_pulses == pytest.approx(target)
    spread = (latest - earliest) / duration
    assert all(abs(f - 0.5) <= spread / 2 + 1e-9 for f in halfway.values()), halfway
    # The same start for all: on the LX line the one MOVE_START starts every servo at
    # the same instant. (Behind the board, each servo starts once its own
    # MOVE_TIME_WRITE, 10 bytes, has crossed the servo line after those of the servos
    # before it: within the bracket.)
    skew = 0.0 if arm.board is None else spread
    assert max(halfway.values()) - min(halfway.values()) <= skew + 1e-9, halfway
    reached = arm.bus.wait_until_reached(targets, tolerance_deg=0.3, timeout_s=WAIT_S)
    assert reached == pytest.approx(targets, abs=0.3)


def test_sync_move_without_start_uses_move_time_write(arm: SimArm) -> None:
    watch = MoveWatch(arm)
    arm.bus.sync_move_deg({2: 12.0, 3: -12.0}, 0.1, use_start=False)
    sync(arm)
    assert watch.moves == [(Command.MOVE_TIME_WRITE, 2, 550, 100),
                           (Command.MOVE_TIME_WRITE, 3, 450, 100)]
    arm.bus.wait_until_reached({2: 12.0, 3: -12.0}, tolerance_deg=0.3, timeout_s=WAIT_S)


def test_speed_limited_move_takes_largest_delta_over_speed(arm: SimArm) -> None:
    watch = MoveWatch(arm)
    duration = arm.bus.move_at_speed_deg(1, 36.0, 120.0)
    assert duration == pytest.approx(36.0 / 120.0)
    sync(arm)
    assert watch.moves == [(Command.MOVE_TIME_WRITE, 1, 650, 300)]
    earliest, latest = watch.start_bounds(1)
    assert watch.predicted(1, earliest + duration - 0.02).position_pulses < 650 - 5
    assert watch.predicted(1, latest + duration).position_pulses == pytest.approx(650)

    # Several servos: the largest move (servo 2, 48 deg) sets the time for all.
    watch = MoveWatch(arm)
    duration = arm.bus.sync_move_deg({2: -48.0, 3: 12.0}, speed_deg_s=160.0)
    assert duration == pytest.approx(48.0 / 160.0)
    sync(arm)
    for sid, target in ((2, 300), (3, 550)):
        earliest, latest = watch.start_bounds(sid)
        before = watch.predicted(sid, earliest + duration - 0.02).position_pulses
        assert before != pytest.approx(target)
        assert watch.predicted(sid, latest + duration).position_pulses == pytest.approx(target)


def test_stop_holds_position_with_torque_on(arm: SimArm) -> None:
    # 2 s moves: through a pty, a busy computer may take a while to pass the stop on.
    arm.bus.move_deg(1, 96.0, 2.0)
    arm.bus.move_deg(2, -96.0, 2.0)
    assert wait_for(lambda: arm.bus.read_position_deg(1) > 20.0, clock=arm.sim.clock)
    arm.bus.stop([1])
    sync(arm)
    held = position_now(arm, 1)
    assert 500 + 20 / 0.24 < held < 900, "servo 1 stopped mid-way"
    assert predicted(arm, 1, now(arm) + 2.0).position_pulses == pytest.approx(held)
    assert arm.bus.read_position_pulses(1) == round(held)
    assert arm.bus.read_torque(1) is True
    assert arm.sim.servo(1).is_loaded
    # Servo 2 was not addressed: it is still on its way.
    assert predicted(arm, 2, now(arm) + 2.0).position_pulses == pytest.approx(100)

    arm.bus.stop()  # broadcast
    sync(arm)
    held2 = position_now(arm, 2)
    assert 100 < held2 < 500
    assert predicted(arm, 2, now(arm) + 2.0).position_pulses == pytest.approx(held2)
    assert arm.bus.read_torque(2) is True


def test_torque_on_and_off(arm: SimArm) -> None:
    assert arm.bus.read_torque(2) is False  # power-on: unloaded
    arm.bus.set_torque(2, True)
    assert arm.bus.read_torque(2) is True
    assert arm.sim.servo(2).is_loaded
    arm.bus.set_torque(2, False)
    assert arm.bus.read_torque(2) is False
    assert not arm.sim.servo(2).is_loaded


# ---------------------------------------------------------------------- settings


def test_offset_adjust_read_save(arm: SimArm) -> None:
    arm.bus.adjust_offset_deg(3, 4.8)
    assert arm.bus.read_offset_deg(3) == pytest.approx(4.8)
    assert arm.sim.servo(3).stored_fields()["offset_pulses"] == 0, "not saved yet"
    arm.bus.save_offset(3)
    sync(arm)
    assert arm.sim.servo(3).stored_fields()["offset_pulses"] == 20
    arm.bus.adjust_offset_deg(3, -7.2)
    assert arm.bus.read_offset_deg(3) == pytest.approx(-7.2)
    assert arm.sim.servo(3).stored_fields()["offset_pulses"] == 20
    with pytest.raises(ConfigError):
        arm.bus.adjust_offset_deg(3, 31.0)


def test_angle_limits_write_read_and_clamp(arm: SimArm) -> None:
    arm.bus.write_angle_limits_deg(4, -12.0, 24.0)
    assert arm.bus.read_angle_limits_deg(4) == pytest.approx((-12.0, 24.0))
    stored = arm.sim.servo(4).stored_fields()
    assert (stored["min_pulses"], stored["max_pulses"]) == (450, 600)
    arm.bus.move_deg(4, 60.0)  # the servo clamps the target to its own limit
    arm.bus.wait_until_reached({4: 24.0}, tolerance_deg=0.3, timeout_s=WAIT_S)
    assert predicted(arm, 4, now(arm) + 0.5).position_pulses == pytest.approx(600)
    arm.bus.move_deg(4, -60.0)
    arm.bus.wait_until_reached({4: -12.0}, tolerance_deg=0.3, timeout_s=WAIT_S)
    assert predicted(arm, 4, now(arm) + 0.5).position_pulses == pytest.approx(450)
    with pytest.raises(ConfigError):
        arm.bus.write_angle_limits_deg(4, 24.0, -12.0)


def test_vin_and_temperature_limits(arm: SimArm) -> None:
    arm.bus.write_vin_limits_v(5, 7.2, 11.4)
    assert arm.bus.read_vin_limits_v(5) == pytest.approx((7.2, 11.4))
    arm.bus.write_temp_limit_c(5, 70)
    assert arm.bus.read_temp_limit_c(5) == 70
    stored = arm.sim.servo(5).stored_fields()
    assert (stored["min_mv"], stored["max_mv"], stored["temp_max_c"]) == (7200, 11400, 70)
    assert arm.bus.read_vin_limits_v(1) == pytest.approx((6.5, 12.0))  # others untouched
    assert arm.bus.read_temp_limit_c(1) == 85
    with pytest.raises(ConfigError):
        arm.bus.write_temp_limit_c(5, 101)
    with pytest.raises(ConfigError):
        arm.bus.write_vin_limits_v(5, 4.0, 11.0)


@lx_commands_only  # the board has no sub-command for the servos' LEDs
def test_led_on_and_off(arm: SimArm) -> None:
    assert arm.bus.read_led(10) is True
    arm.bus.set_led(10, False)
    assert arm.bus.read_led(10) is False
    assert arm.sim.servo(10).stored_fields()["is_led_off"] == 1
    assert arm.bus.read_led(1) is True
    arm.bus.set_led(10, True)
    assert arm.bus.read_led(10) is True


@lx_commands_only  # the board has no sub-command for the alarm masks
def test_alarm_mask(arm: SimArm) -> None:
    assert arm.bus.read_alarm_mask(2) == AlarmFlag(7)
    mask = AlarmFlag.OVER_TEMPERATURE | AlarmFlag.STALLED
    arm.bus.write_alarm_mask(2, mask)
    assert arm.bus.read_alarm_mask(2) == mask
    arm.bus.write_alarm_mask(2, AlarmFlag.NONE)
    assert arm.bus.read_alarm_mask(2) == AlarmFlag.NONE
    assert arm.bus.read_alarm_mask(3) == AlarmFlag(7)
    with pytest.raises(ConfigError):
        arm.bus.write_alarm_mask(2, 8)  # type: ignore[arg-type]


# ---------------------------------------------------------------------- motor mode


def _turned(arm: SimArm, servo_id: int, dt: float) -> float:
    """Pulses the model says the horn turns in the next ``dt`` seconds (mod one turn)."""
    at = now(arm)
    a = predicted(arm, servo_id, at).position_pulses
    b = predicted(arm, servo_id, at + dt).position_pulses
    d = (b - a) % FULL_TURN_PULSES
    return d - FULL_TURN_PULSES if d > FULL_TURN_PULSES / 2 else d


@lx_commands_only  # the board has no sub-command for motor mode
def test_motor_mode_turns_until_speed_zero(arm: SimArm) -> None:
    arm.bus.set_motor_speed(1, 500)
    mode = arm.bus.read_mode(1)
    assert (mode.mode, mode.motor_speed) == (ServoMode.MOTOR, 500)
    # 500/1000 of 300 deg/s = 625 pulses/s.
    assert _turned(arm, 1, 0.1) == pytest.approx(62.5)
    first = arm.bus.read_position_pulses(1)
    assert wait_for(lambda: (arm.bus.read_position_pulses(1) - first) % FULL_TURN_PULSES > 30,
                    clock=arm.sim.clock)

    arm.bus.stop([1])  # MOVE_STOP does not stop a motor
    sync(arm)
    assert _turned(arm, 1, 0.1) == pytest.approx(62.5)
    assert arm.bus.read_mode(1).motor_speed == 500

    arm.bus.stop_motor(1)
    sync(arm)
    assert _turned(arm, 1, 0.5) == 0.0
    mode = arm.bus.read_mode(1)
    assert (mode.mode, mode.motor_speed) == (ServoMode.MOTOR, 0)
    assert arm.bus.read_position_pulses(1) == arm.bus.read_position_pulses(1)

    arm.bus.set_motor_speed(1, -1000)
    sync(arm)
    assert _turned(arm, 1, 0.1) == pytest.approx(-125.0)
    arm.bus.set_position_mode(1)
    sync(arm)
    assert _turned(arm, 1, 0.5) == 0.0
    assert arm.bus.read_mode(1).mode is ServoMode.POSITION


# ---------------------------------------------------------------------- faults


def test_read_faults_supply_out_of_limits(arm: SimArm) -> None:
    servo = arm.sim.servo(3)
    arm.bus.set_torque(3, True)
    assert arm.bus.read_faults(3) == AlarmFlag.NONE
    servo.supply_mv = 12500
    assert arm.bus.read_faults(3) == AlarmFlag.OVER_VOLTAGE
    assert arm.bus.read_vin_v(3) == pytest.approx(12.5)
    assert arm.bus.read_torque(3) is False, "the fault unloads the motor"
    servo.supply_mv = 6200
    assert arm.bus.read_faults(3) == AlarmFlag.OVER_VOLTAGE
    assert servo.active_faults == AlarmFlag.OVER_VOLTAGE
    servo.supply_mv = 11100
    assert arm.bus.read_faults(3) == AlarmFlag.NONE
    assert arm.bus.read_torque(3) is True, "recovered: torque was asked for"
    # Narrower limits put the present supply out of them.
    arm.bus.write_vin_limits_v(3, 6.5, 11.0)
    assert arm.bus.read_faults(3) == AlarmFlag.OVER_VOLTAGE
    assert arm.bus.read_faults(2) == AlarmFlag.NONE


def test_read_faults_overheated(arm: SimArm) -> None:
    servo = arm.sim.servo(5)
    servo.temperature_c = 90.5
    assert arm.bus.read_faults(5) == AlarmFlag.OVER_TEMPERATURE
    assert arm.bus.read_temp_c(5) >= 85
    assert servo.active_faults == AlarmFlag.OVER_TEMPERATURE
    servo.supply_mv = 12600
    assert arm.bus.read_faults(5) == AlarmFlag.OVER_TEMPERATURE | AlarmFlag.OVER_VOLTAGE
    servo.supply_mv = 11100
    servo.temperature_c = 60.5
    assert arm.bus.read_faults(5) == AlarmFlag.NONE
    arm.bus.write_temp_limit_c(5, 55)  # now 60 C is too hot
    assert arm.bus.read_faults(5) == AlarmFlag.OVER_TEMPERATURE
    assert arm.bus.read_faults(4) == AlarmFlag.NONE


# ---------------------------------------------------------------------- move-time reads


@lx_commands_only  # the board can neither queue a move nor read one back
def test_read_move_time_and_move_time_wait(arm: SimArm) -> None:
    arm.bus.move_deg(2, 12.0, 0.25)
    r = arm.bus.read_move_time(2)
    assert (r.position_pulses, r.time_ms) == (550, 250)
    assert r.position_deg == pytest.approx(12.0)

    arm.bus.send(3, Command.MOVE_TIME_WAIT_WRITE, 400, 700)
    w = arm.bus.read_move_time_wait(3)
    assert (w.position_pulses, w.time_ms) == (400, 700)
    assert predicted(arm, 3, now(arm) + 1.0).position_pulses == pytest.approx(500)
    arm.bus.send(254, Command.MOVE_START)
    r = arm.bus.read_move_time(3)
    assert (r.position_pulses, r.time_ms) == (400, 700)
    sync(arm)
    assert predicted(arm, 3, now(arm) + 1.0).position_pulses == pytest.approx(400)


@lx_commands_only  # the board cannot read a queued move back
@pytest.mark.usefixtures("no_gc_pauses")  # through a pty it times a read in wall time
def test_servo_that_never_answers_wait_read_gives_typed_timeout(arm: SimArm) -> None:
    silent = SimServo(3, params=ServoParams(answers_wait_read=False), now=now(arm))
    index = next(i for i, s in enumerate(arm.sim.servos) if s.servo_id == 3)
    arm.sim.servos[index] = silent
    asked: list[int] = []

    def tap(request: Request) -> None:
        if request.command is Command.MOVE_TIME_WAIT_READ:
            asked.append(request.servo_id)

    arm.sim.taps.append(tap)
    clock = arm.bus.clock
    with WakeUps() as wake_ups, pytest.raises(BusTimeoutError) as info:
        t0 = clock.now()
        try:
            arm.bus.read_move_time_wait(3)
        finally:
            elapsed = clock.now() - t0
    sync(arm)  # every attempt has reached the servos
    # Each attempt waited out its whole deadline, and all of them together no longer
    # than the budget the driver states: on a simulated clock exactly; on the wall clock
    # give or take the computer's wake-ups meanwhile (one per attempt, and the return).
    spec = SPECS[Command.MOVE_TIME_WAIT_READ]
    assert spec.reply_length is not None
    attempt_s = arm.bus.timeout_s(spec.request_length + 3, spec.reply_length + 3)
    assert asked == [3] * (arm.bus.retries + 1)
    assert elapsed >= len(asked) * attempt_s - 1e-9, f"{elapsed * 1e3:.1f} ms"
    budget_s = read_budget_s(arm.bus, Command.MOVE_TIME_WAIT_READ, len(asked) + 1,
                             wake_ups.worst_s)
    assert elapsed <= budget_s, (
        f"{elapsed * 1e3:.1f} ms, budget {budget_s * 1e3:.1f} ms "
        f"(worst wake-up meanwhile {wake_ups.worst_s * 1e3:.1f} ms)")
    assert info.value.servo_id == 3
    assert info.value.command == Command.MOVE_TIME_WAIT_READ
    # The bus is fine afterwards, for that servo's other reads and for the others.
    assert arm.bus.read_position_pulses(3) == 500
    assert arm.bus.read_move_time_wait(2).position_pulses == 500


# ---------------------------------------------------------------------- the board's limits


@pytest.mark.parametrize("arm", [BOARD_WAY], indirect=True)
def test_the_board_refuses_what_it_cannot_pass_on(arm: SimArm) -> None:
    """What the ``lx_commands_only`` tests use, the board has no sub-command for: each call
    says so (UnsupportedError) and not a byte of it reaches the board or the servos."""
    assert arm.board is not None
    bus, to_board = arm.bus, bytearray()
    receive = arm.board.receive

    def record(data: bytes) -> None:  # instrumentation: what crosses the host's link
        to_board.extend(data)
        receive(data)

    arm.board.receive = record  # type: ignore[method-assign]
    heard: list[Command] = []
    arm.sim.taps.append(lambda r: heard.append(r.command))
    refused: list[tuple[Callable[[], object], str]] = [
        (lambda: bus.set_motor_speed(1, 500), "motor (continuous rotation) mode"),
        (lambda: bus.stop_motor(1), "motor (continuous rotation) mode"),
        (lambda: bus.set_position_mode(1), "motor (continuous rotation) mode"),
        (lambda: bus.read_mode(1), "reading the servo's mode"),
        (lambda: bus.set_led(10, False), "the servos' LEDs"),
        (lambda: bus.read_led(10), "the servos' LEDs"),
        (lambda: bus.write_alarm_mask(2, AlarmFlag.NONE), "the servos' alarm masks"),
        (lambda: bus.read_alarm_mask(2), "the servos' alarm masks"),
        (lambda: bus.send(3, Command.MOVE_TIME_WAIT_WRITE, 400, 700), "queued moves"),
        (lambda: bus.send(254, Command.MOVE_START), "MOVE_START"),
        (lambda: bus.read_move_time(2), "reading back the last move command"),
        (lambda: bus.read_move_time_wait(3), "reading back a queued move"),
    ]
    for call, what in refused:
        with pytest.raises(UnsupportedError, match=re.escape(f"cannot do {what}") + ".*"
                           + re.escape("(use a plain LX bus adapter for this)")):
            call()
    sync(arm)
    # The sync read is all that went to the board, and to the servos (asked again if a
    # busy computer passed its answer on late: this is a pty).
    sent = [decode_board_request(f) for f in BoardFrameParser().feed(bytes(to_board))]
    assert sent and set(sent) == {ServoRead(ServoSub.READ_TEMPERATURE, 1)}
    assert heard and set(heard) == {Command.TEMP_READ}
    assert not bus.wrote
    assert arm.sim.servo(1).is_loaded is False  # power-on state: nothing changed it


# ---------------------------------------------------------------------- software limits


def test_limit_error_before_anything_is_sent(arm: SimArm) -> None:
    arm.bus.set_limits_deg(1, -10.0, 10.0)
    sync(arm)
    heard = hear(arm)
    with pytest.raises(LimitError):
        arm.bus.move_deg(1, 20.0)
    with pytest.raises(LimitError):
        arm.bus.move_pulses(1, 100)
    with pytest.raises(LimitError):
        arm.bus.move_at_speed_deg(1, -12.0, 50.0)
    with pytest.raises(LimitError):  # one bad target: nothing goes to any servo
        arm.bus.sync_move_deg({2: 5.0, 3: 5.0, 1: -20.0}, 0.2)
    with pytest.raises(LimitError):
        arm.bus.sync_move_deg({2: 5.0, 1: 11.0}, speed_deg_s=100.0)
    sync(arm)
    assert heard == []
    for sid in (1, 2, 3):
        assert predicted(arm, sid, now(arm) + 1.0).position_pulses == 500
    arm.bus.move_deg(1, 9.6)  # inside: sent
    sync(arm)
    assert heard == [(Command.MOVE_TIME_WRITE, 1)]
    with pytest.raises(ConfigError):
        arm.bus.set_limits_deg(1, 10.0, -10.0)


def test_limits_given_at_construction(way: str, arm_with: ArmFactory) -> None:
    arm = arm_with(ARM_SERVO_IDS, limits_deg={2: (-5.0, 5.0)})
    sync(arm)
    heard = hear(arm)
    with pytest.raises(LimitError):
        arm.bus.move_deg(2, 6.0)
    sync(arm)
    assert heard == []


# ---------------------------------------------------------------------- IDs


# Through the board a servo is renumbered only when it is alone on the bus (a shared ID
# cannot be seen through it): tests/integration/test_board_link.py::test_set_id_through_*.
@pytest.mark.parametrize("arm", LX_WAYS, indirect=True)
def test_set_id_renumbers_the_one_servo(arm: SimArm) -> None:
    arm.bus.set_id(5, 7)
    assert arm.bus.scan([4, 5, 6, 7], margin_s=scan_margin_s(arm)).found == [4, 7]
    assert arm.sim.servo(7).stored_fields()["id"] == 7
    assert arm.bus.read_id(7) == 7
    with pytest.raises(BusTimeoutError):
        arm.bus.read_position_pulses(5)


def test_set_id_refuses_when_new_id_is_taken(arm: SimArm) -> None:
    with pytest.raises(BusConflictError):
        arm.bus.set_id(1, 2)
    assert sorted(s.servo_id for s in arm.sim.servos) == [1, 2, 3, 4, 5, 10]


@pytest.mark.parametrize("arm", LX_WAYS, indirect=True)  # the board: as above
def test_set_id_refuses_when_old_id_is_absent(arm: SimArm) -> None:
    with pytest.raises(BusTimeoutError):
        arm.bus.set_id(6, 7)
    assert sorted(s.servo_id for s in arm.sim.servos) == [1, 2, 3, 4, 5, 10]


# Two servos on one ID, told apart by their colliding LX replies: behind the board they
# look like no servo at all (the board answers -1), see test_scan_reports_two_servos...
@pytest.mark.parametrize("way", LX_WAYS)
def test_set_id_refuses_two_servos_on_the_old_id(way: str, arm_with: ArmFactory) -> None:
    arm = arm_with((1, 3, 3))
    with pytest.raises(BusConflictError):
        arm.bus.set_id(3, 7)
    assert [s.servo_id for s in arm.sim.servos] == [1, 3, 3]


@pytest.mark.parametrize("way", LX_WAYS)  # colliding LX replies, as above
def test_set_id_refuses_a_new_id_held_by_two_servos(way: str, arm_with: ArmFactory) -> None:
    # Two servos on 3 garble each other's ID reply, so 3 is not "found": it is still taken.
    arm = arm_with((1, 3, 3))
    with pytest.raises(BusConflictError):
        arm.bus.set_id(1, 3)
    assert [s.servo_id for s in arm.sim.servos] == [1, 3, 3]


def test_id_write_to_broadcast_is_refused(arm: SimArm) -> None:
    sync(arm)
    heard = hear(arm)
    with pytest.raises(ConfigError, match="broadcast"):
        arm.bus.send(254, Command.ID_WRITE, 7)
    sync(arm)
    assert heard == []
    assert sorted(s.servo_id for s in arm.sim.servos) == [1, 2, 3, 4, 5, 10]


def test_read_id_broadcast_with_one_servo(way: str, arm_with: ArmFactory) -> None:
    arm = arm_with((42,))
    assert arm.bus.read_id() == 42


# ---------------------------------------------------------------------- threads


def test_threads_get_their_own_servos_values(way: str, arm_with: ArmFactory) -> None:
    # 800 reads from four threads: through a pty, a busy computer may pass one reply on
    # later than PTY_MARGIN_S three times over; the deadline is not what this checks.
    arm = arm_with(ARM_SERVO_IDS, **({} if way.startswith("inproc") else
                                     {"timeout_margin_s": BUSY_MARGIN_S}))
    positions = {1: 111.0, 2: 222.0, 3: 333.0, 4: 444.0}
    place(arm, positions)
    wrong: list[tuple[int, int]] = []
    errors: list[BaseException] = []
    counts = dict.fromkeys(positions, 0)

    def reader(sid: int) -> None:
        try:
            for _ in range(200):
                value = arm.bus.read_position_pulses(sid)
                counts[sid] += 1
                if value != positions[sid]:
                    wrong.append((sid, value))
        except BaseException as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=reader, args=(sid,), name=f"reader-{sid}")
               for sid in positions]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=30)
    assert not any(t.is_alive() for t in threads)
    assert not errors, errors
    assert not wrong, wrong[:10]
    assert counts == dict.fromkeys(positions, 200)


# ---------------------------------------------------------------------- context manager


def test_exception_in_with_block_stops_the_servos(arm: SimArm) -> None:
    heard: list[tuple[Command, int]] = []
    with pytest.raises(RuntimeError, match="operator"), arm.bus as bus:
        bus.move_deg(1, 96.0, 2.0)  # 2 s: a busy computer may pass the stops on late
        assert wait_for(lambda: bus.read_position_deg(1) > 20.0, clock=arm.sim.clock)
        sync(arm)
        heard = hear(arm)
        raise RuntimeError("operator pressed stop")
    # Two broadcast MOVE_STOPs, then the port is closed.
    assert wait_for(lambda: len(heard) >= 2, clock=arm.sim.clock)
    assert heard == [(Command.MOVE_STOP, 254)] * 2
    held = position_now(arm, 1)
    assert 500 + 20 / 0.24 < held < 900
    assert predicted(arm, 1, now(arm) + 1.0).position_pulses == pytest.approx(held)
    assert arm.sim.servo(1).is_loaded
    with pytest.raises(TransportError):  # the port was closed on the way out
        arm.bus.read_position_pulses(1)


def test_clean_exit_from_with_block_sends_nothing(arm: SimArm) -> None:
    with arm.bus as bus:
        bus.move_deg(1, 12.0, 0.05)
        sync(arm)
        heard = hear(arm)
    arm.sim.advance()
    assert heard == []
    assert predicted(arm, 1, now(arm) + 0.5).position_pulses == pytest.approx(550)


# ---------------------------------------------------------------------- fixtures


@pytest.fixture(params=WAYS)
def way(request: pytest.FixtureRequest) -> str:
    """The five ways of the ``arm`` fixture, for tests that need other servos."""
    return str(request.param)


@pytest.fixture
def arm_with(way: str) -> Iterator[ArmFactory]:
    """Build a simulated bus with other IDs (or driver options), the ``way`` given."""
    made: list[tuple[SimArm, PtyServer | None]] = []

    def make(ids: tuple[int, ...], **bus_kwargs: object) -> SimArm:
        sim_arm, server = make_sim_arm_way(way, ids=ids, **bus_kwargs)
        made.append((sim_arm, server))
        return sim_arm

    yield make
    for sim_arm, server in made:
        sim_arm.bus.close()
        if server is not None:
            server.stop()
