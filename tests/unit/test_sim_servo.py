"""SimServo, driven directly with typed requests and explicit times (no sleeping)."""

from __future__ import annotations

import math
from itertools import pairwise

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from busarm.errors import ConfigError
from busarm.protocol import (
    BROADCAST_ID,
    REPLY_TYPES,
    SPECS,
    AlarmFlag,
    AngleLimitReply,
    AngleOffsetReply,
    Command,
    IdReply,
    LedCtrlReply,
    LedErrorReply,
    LoadReply,
    ModeReply,
    MoveTimeReply,
    MoveTimeWaitReply,
    PositionReply,
    Reply,
    Request,
    ServoMode,
    TempMaxLimitReply,
    TempReply,
    VinLimitReply,
    VinReply,
)
from busarm.sim.servo import STORED_FIELDS, SimServo
from busarm.sim.servo_params import FULL_TURN_PULSES, PARAMS_20KG, ServoParams

C = Command
MAX_SPEED = ServoParams().max_speed_pulses_per_s  # 1250 pulses/s for the 35 kg servo
MOTOR_FULL = ServoParams().motor_pulses_per_s_at_full_speed  # 1250 pulses/s at speed 1000


def req(command: Command, *args: int, servo_id: int = 1) -> Request:
    return Request(servo_id, command, args)


def do(servo: SimServo, command: Command, *args: int, now: float) -> Reply | None:
    return servo.handle(req(command, *args, servo_id=servo.servo_id), now)


def pos(servo: SimServo, now: float) -> int:
    reply = do(servo, C.POS_READ, now=now)
    assert isinstance(reply, PositionReply)
    return reply.position_pulses


def loaded(servo: SimServo, now: float) -> bool:
    reply = do(servo, C.LOAD_OR_UNLOAD_READ, now=now)
    assert isinstance(reply, LoadReply)
    return reply.is_loaded


def faults(servo: SimServo) -> AlarmFlag:
    """The servo's active faults (a call, so type checkers do not narrow it between steps)."""
    return servo.active_faults


def blinking(servo: SimServo) -> bool:
    return servo.is_led_blinking


def temp_read(servo: SimServo, now: float) -> int:
    reply = do(servo, C.TEMP_READ, now=now)
    assert isinstance(reply, TempReply)
    return reply.temp_c


# ---------------------------------------------------------------------------- reads


POWER_ON_READS: dict[Command, Reply] = {
    C.MOVE_TIME_READ: MoveTimeReply(500, 0),
    C.MOVE_TIME_WAIT_READ: MoveTimeWaitReply(500, 0),
    C.ID_READ: IdReply(1),
    C.ANGLE_OFFSET_READ: AngleOffsetReply(0),
    C.ANGLE_LIMIT_READ: AngleLimitReply(0, 1000),
    C.VIN_LIMIT_READ: VinLimitReply(6500, 12000),
    C.TEMP_MAX_LIMIT_READ: TempMaxLimitReply(85),
    C.TEMP_READ: TempReply(25),
    C.VIN_READ: VinReply(11100),
    C.POS_READ: PositionReply(500),
    C.OR_MOTOR_MODE_READ: ModeReply(ServoMode.POSITION, 0),
    C.LOAD_OR_UNLOAD_READ: LoadReply(False),
    C.LED_CTRL_READ: LedCtrlReply(False),
    C.LED_ERROR_READ: LedErrorReply(AlarmFlag(7)),
}


def test_power_on_reads_cover_every_read_command() -> None:
    assert set(POWER_ON_READS) == {c for c, spec in SPECS.items() if spec.is_read}


@pytest.mark.parametrize("command", sorted(POWER_ON_READS))
def test_power_on_read_reply_type_and_value(command: Command) -> None:
    reply = SimServo(1).handle(req(command), 0.0)
    assert type(reply) is REPLY_TYPES[command]
    assert reply == POWER_ON_READS[command]


@pytest.mark.parametrize(
    ("command", "args"),
    [
        (C.MOVE_TIME_WRITE, (500, 0)), (C.MOVE_TIME_WAIT_WRITE, (600, 100)),
        (C.MOVE_START, ()), (C.MOVE_STOP, ()), (C.ID_WRITE, (2,)),
        (C.ANGLE_OFFSET_ADJUST, (10,)), (C.ANGLE_OFFSET_WRITE, ()),
        (C.ANGLE_LIMIT_WRITE, (10, 990)), (C.VIN_LIMIT_WRITE, (6000, 12000)),
        (C.TEMP_MAX_LIMIT_WRITE, (80,)), (C.OR_MOTOR_MODE_WRITE, (1, 0, 100)),
        (C.LOAD_OR_UNLOAD_WRITE, (1,)), (C.LED_CTRL_WRITE, (1,)), (C.LED_ERROR_WRITE, (3,)),
    ],
)
def test_write_commands_return_no_reply(command: Command, args: tuple[int, ...]) -> None:
    assert not SPECS[command].is_read
    assert SimServo(1).handle(req(command, *args), 0.0) is None


def test_settings_writes_are_read_back() -> None:
    s = SimServo(1)
    do(s, C.ANGLE_LIMIT_WRITE, 100, 900, now=0.0)
    do(s, C.VIN_LIMIT_WRITE, 7000, 11500, now=0.0)
    do(s, C.TEMP_MAX_LIMIT_WRITE, 70, now=0.0)
    do(s, C.LED_CTRL_WRITE, 1, now=0.0)
    do(s, C.LED_ERROR_WRITE, 3, now=0.0)
    assert do(s, C.ANGLE_LIMIT_READ, now=0.1) == AngleLimitReply(100, 900)
    assert do(s, C.VIN_LIMIT_READ, now=0.1) == VinLimitReply(7000, 11500)
    assert do(s, C.TEMP_MAX_LIMIT_READ, now=0.1) == TempMaxLimitReply(70)
    assert do(s, C.LED_CTRL_READ, now=0.1) == LedCtrlReply(True)
    reply = do(s, C.LED_ERROR_READ, now=0.1)
    assert reply == LedErrorReply(AlarmFlag.OVER_TEMPERATURE | AlarmFlag.OVER_VOLTAGE)
    assert s.stored_fields() == {
        "id": 1, "offset_pulses": 0, "min_pulses": 100, "max_pulses": 900,
        "min_mv": 7000, "max_mv": 11500, "temp_max_c": 70, "is_led_off": 1,
    }
    assert tuple(s.stored_fields()) == STORED_FIELDS


def test_id_write_changes_the_id_and_is_stored() -> None:
    s = SimServo(1)
    do(s, C.ID_WRITE, 7, now=0.0)
    assert s.servo_id == 7
    assert do(s, C.ID_READ, now=0.0) == IdReply(7)
    assert s.stored_fields()["id"] == 7


def test_vin_and_temp_reads_follow_the_model() -> None:
    s = SimServo(1)
    s.supply_mv = 9870
    s.temperature_c = 41.7
    assert do(s, C.VIN_READ, now=0.0) == VinReply(9870)
    assert do(s, C.TEMP_READ, now=0.0) == TempReply(41)  # whole degrees, truncated


# ---------------------------------------------------------------------------- position moves


def test_move_at_uniform_speed_over_the_given_time() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=10.0)
    for k in range(11):
        t = 10.0 + k * 0.1
        assert pos(s, t) == round(500 + 300 * k * 0.1)
    assert pos(s, 12.0) == 800
    assert do(s, C.MOVE_TIME_READ, now=12.0) == MoveTimeReply(800, 1000)


def test_move_backwards_and_fractional_positions() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 400, 2000, now=0.0)
    assert s.position_pulses == pytest.approx(500.0)
    s.advance(0.5)
    assert s.position_pulses == pytest.approx(475.0)
    s.advance(1.5)
    assert s.position_pulses == pytest.approx(425.0)


@pytest.mark.parametrize("time_ms", [0, 1, 100, 400])
def test_move_never_faster_than_max_speed(time_ms: int) -> None:
    s = SimServo(1, position_pulses=0.0)
    do(s, C.MOVE_TIME_WRITE, 1000, time_ms, now=0.0)
    full_s = 1000 / MAX_SPEED  # 0.8 s
    assert full_s == pytest.approx(0.8)
    assert pos(s, full_s / 2) == 500
    assert pos(s, full_s * 0.9) == 900
    assert pos(s, full_s) == 1000


def test_gripper_is_faster_than_the_joint_servo() -> None:
    assert ServoParams.gripper() == PARAMS_20KG
    assert PARAMS_20KG.max_speed_pulses_per_s > MAX_SPEED
    g = SimServo(10, params=PARAMS_20KG, position_pulses=0.0)
    do(g, C.MOVE_TIME_WRITE, 1000, 0, now=0.0)
    assert pos(g, 0.5) == round(0.5 * 60 / 0.24 / 0.18)


def test_move_target_is_clamped_to_the_angle_limits() -> None:
    s = SimServo(1)
    do(s, C.ANGLE_LIMIT_WRITE, 200, 700, now=0.0)
    do(s, C.MOVE_TIME_WRITE, 900, 1000, now=0.0)
    assert pos(s, 0.5) == 600  # 200 pulses in 1 s: the clamped distance sets the speed
    assert pos(s, 5.0) == 700
    assert do(s, C.MOVE_TIME_READ, now=5.0) == MoveTimeReply(900, 1000)  # as written
    do(s, C.MOVE_TIME_WRITE, 0, 0, now=5.0)
    assert pos(s, 10.0) == 200


def test_a_move_loads_the_motor() -> None:
    s = SimServo(1)
    assert not loaded(s, 0.0)
    do(s, C.MOVE_TIME_WRITE, 600, 0, now=0.0)
    assert loaded(s, 0.0)
    assert s.is_loaded


def test_unloading_freezes_the_horn_and_a_move_reloads() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    do(s, C.LOAD_OR_UNLOAD_WRITE, 0, now=0.5)
    assert not loaded(s, 0.5)
    assert pos(s, 3.0) == 650
    do(s, C.MOVE_TIME_WRITE, 450, 1000, now=3.0)
    assert loaded(s, 3.0)
    assert pos(s, 3.5) == 550
    assert pos(s, 4.0) == 450


def test_load_write_does_not_interrupt_a_move() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    do(s, C.LOAD_OR_UNLOAD_WRITE, 1, now=0.5)
    assert pos(s, 1.0) == 800


def test_stop_holds_the_present_position_and_stays_loaded() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    do(s, C.MOVE_STOP, now=0.5)
    assert pos(s, 0.5) == 650
    assert pos(s, 2.0) == 650
    assert loaded(s, 2.0)
    assert do(s, C.MOVE_TIME_READ, now=2.0) == MoveTimeReply(800, 1000)


def test_wait_write_stores_and_start_moves_from_where_the_servo_is_then() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WAIT_WRITE, 700, 1000, now=0.0)
    assert pos(s, 1.0) == 500
    assert not loaded(s, 1.0)
    assert do(s, C.MOVE_TIME_WAIT_READ, now=1.0) == MoveTimeWaitReply(700, 1000)
    assert do(s, C.MOVE_TIME_READ, now=1.0) == MoveTimeReply(500, 0)
    do(s, C.MOVE_START, now=2.0)
    assert pos(s, 2.5) == 600
    assert pos(s, 3.0) == 700
    assert do(s, C.MOVE_TIME_READ, now=3.0) == MoveTimeReply(700, 1000)
    # The pending move is used up; the wait values can still be read.
    do(s, C.MOVE_TIME_WRITE, 300, 0, now=3.0)
    do(s, C.MOVE_START, now=4.0)
    assert pos(s, 5.0) == 300
    assert do(s, C.MOVE_TIME_WAIT_READ, now=5.0) == MoveTimeWaitReply(700, 1000)


def test_move_start_without_a_pending_move_does_nothing() -> None:
    s = SimServo(1)
    do(s, C.MOVE_START, now=0.0)
    assert pos(s, 1.0) == 500
    assert not loaded(s, 1.0)


def test_wait_read_can_go_unanswered() -> None:
    s = SimServo(1, params=ServoParams(answers_wait_read=False))
    do(s, C.MOVE_TIME_WAIT_WRITE, 700, 1000, now=0.0)
    assert do(s, C.MOVE_TIME_WAIT_READ, now=0.0) is None
    do(s, C.MOVE_START, now=0.0)  # the wait move itself still works
    assert pos(s, 1.0) == 700


def test_earlier_times_are_taken_as_the_latest() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    assert pos(s, 0.5) == 650
    assert pos(s, 0.2) == 650
    s.advance(0.1)
    assert s.position_pulses == pytest.approx(650.0)


def test_positions_read_near_zero_can_be_negative() -> None:
    s = SimServo(1, position_pulses=10.0)
    do(s, C.ANGLE_OFFSET_ADJUST, 40, now=0.0)  # unloaded: the horn stays, the reading shifts
    assert pos(s, 0.0) == -30


# ---------------------------------------------------------------------------- offsets


def test_offset_adjust_turns_a_loaded_horn_and_keeps_the_logical_position() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 500, 0, now=0.0)
    do(s, C.ANGLE_OFFSET_ADJUST, 50, now=1.0)
    assert do(s, C.ANGLE_OFFSET_READ, now=1.0) == AngleOffsetReply(50)
    assert pos(s, 1.0) == 450  # the horn has not turned yet
    assert pos(s, 1.0 + 50 / MAX_SPEED) == 500
    assert s.physical_pulses == pytest.approx(550.0)
    assert s.stored_fields()["offset_pulses"] == 0  # adjusted, not saved
    do(s, C.ANGLE_OFFSET_WRITE, now=2.0)
    assert s.stored_fields()["offset_pulses"] == 50


def test_offset_adjust_during_a_move_keeps_the_logical_target() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    do(s, C.ANGLE_OFFSET_ADJUST, -20, now=0.5)
    assert pos(s, 1.0) == 800
    assert s.physical_pulses == pytest.approx(780.0)


def test_offset_adjust_on_an_unloaded_servo_shifts_the_reading() -> None:
    s = SimServo(1)
    do(s, C.ANGLE_OFFSET_ADJUST, -30, now=0.0)
    assert pos(s, 1.0) == 530
    assert s.physical_pulses == pytest.approx(500.0)
    # Moves are logical: the horn goes to 600 - 30 physically.
    do(s, C.MOVE_TIME_WRITE, 600, 0, now=1.0)
    assert pos(s, 2.0) == 600
    assert s.physical_pulses == pytest.approx(570.0)


# ---------------------------------------------------------------------------- voltage and heat


def test_supply_outside_the_vin_limits_unloads_and_recovers() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    s.advance(0.5)
    s.supply_mv = 12500
    assert faults(s) == AlarmFlag.OVER_VOLTAGE
    assert blinking(s)
    assert not loaded(s, 0.5)
    assert pos(s, 2.0) == 650
    do(s, C.MOVE_TIME_WRITE, 200, 0, now=2.0)  # recorded, but no torque
    assert pos(s, 3.0) == 650
    assert do(s, C.MOVE_TIME_READ, now=3.0) == MoveTimeReply(200, 0)
    s.supply_mv = 11100
    assert faults(s) == AlarmFlag.NONE
    assert not blinking(s)
    assert loaded(s, 3.0)
    assert pos(s, 5.0) == 650  # reloaded, holding where it was


def test_vin_limit_write_can_put_the_supply_out_of_range() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 500, 0, now=0.0)
    do(s, C.VIN_LIMIT_WRITE, 11500, 12000, now=1.0)
    assert faults(s) == AlarmFlag.OVER_VOLTAGE
    assert not loaded(s, 1.0)
    do(s, C.VIN_LIMIT_WRITE, 6500, 12000, now=2.0)
    assert loaded(s, 2.0)


def test_under_voltage_is_flagged_but_the_servo_still_answers_above_6v() -> None:
    s = SimServo(1)
    s.supply_mv = 6200
    assert faults(s) == AlarmFlag.OVER_VOLTAGE
    assert s.is_responsive(0.0)


def test_alarm_mask_selects_what_blinks() -> None:
    s = SimServo(1)
    do(s, C.LED_ERROR_WRITE, int(AlarmFlag.STALLED), now=0.0)
    s.supply_mv = 12500
    assert faults(s) == AlarmFlag.OVER_VOLTAGE
    assert not blinking(s)


@pytest.mark.parametrize(("supply_mv", "responsive"), [(5000, False), (5999, False), (6000, True)])
def test_unresponsive_under_6v_and_blinking(supply_mv: int, responsive: bool) -> None:
    s = SimServo(1)
    do(s, C.VIN_LIMIT_WRITE, 4500, 12000, now=0.0)  # no voltage fault: the blink is brown-out
    s.supply_mv = supply_mv
    assert s.is_responsive(1.0) is responsive
    assert blinking(s) is (not responsive)


def test_over_temperature_unloads_until_cooled_below_the_limit() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 500, 0, now=0.0)
    s.temperature_c = 90.0
    assert faults(s) == AlarmFlag.OVER_TEMPERATURE
    assert not loaded(s, 0.0)
    assert temp_read(s, 0.0) == 90
    # Unloaded it cools toward 25 C: T = 25 + 65 exp(-t / 40) reaches 84 at 3.87 s.
    tau = ServoParams().thermal_time_constant_s
    recover_s = tau * math.log(65 / 59)
    assert s.handle(req(C.LOAD_OR_UNLOAD_READ), recover_s - 0.05) == LoadReply(False)
    assert s.handle(req(C.LOAD_OR_UNLOAD_READ), recover_s + 0.05) == LoadReply(True)
    assert faults(s) == AlarmFlag.NONE
    assert temp_read(s, recover_s + 0.05) == 83


def test_temp_limit_write_below_the_temperature_trips_at_once() -> None:
    s = SimServo(1)
    do(s, C.MOVE_TIME_WRITE, 500, 0, now=0.0)
    s.temperature_c = 60.0
    do(s, C.TEMP_MAX_LIMIT_WRITE, 55, now=0.0)
    assert faults(s) == AlarmFlag.OVER_TEMPERATURE
    assert not s.is_loaded
    do(s, C.TEMP_MAX_LIMIT_WRITE, 85, now=0.1)
    assert s.is_loaded


def test_an_unloaded_servo_stays_unloaded_after_a_heat_fault() -> None:
    s = SimServo(1)
    s.temperature_c = 95.0
    s.advance(1000.0)
    assert faults(s) == AlarmFlag.NONE
    assert not s.is_loaded


def _stall_scenario(params: ServoParams) -> SimServo:
    s = SimServo(1, params=params)
    s.set_obstacle(max_pulses=600)
    do(s, C.MOVE_TIME_WRITE, 900, 0, now=0.0)
    return s


FAST_HEAT = ServoParams(thermal_time_constant_s=4.0)
"""Ten times faster heating, as a test may want."""


def test_stall_heats_to_the_limit_unloads_cools_and_reloads() -> None:
    s = _stall_scenario(FAST_HEAT)
    contact_s = 100 / MAX_SPEED
    assert pos(s, contact_s) == 600
    s.advance(contact_s + 0.45)
    assert faults(s) == AlarmFlag.NONE  # pushing, not yet long enough
    s.advance(contact_s + 0.55)
    assert faults(s) == AlarmFlag.STALLED
    assert blinking(s)
    # Step through time; record when each state first appears.
    history: list[tuple[float, AlarmFlag, bool, float]] = []
    for k in range(1, 2001):
        t = contact_s + 0.55 + k * 0.005
        s.advance(t)
        history.append((t, faults(s), s.is_loaded, s.temperature_c))
    over = next(h for h in history if h[1] & AlarmFlag.OVER_TEMPERATURE)
    back = next(h for h in history if h[0] > over[0] and not h[1])
    # Pushing (effort 1) the temperature heads for 125 C: 85 C after tau * ln(100 / 40).
    expected = contact_s + 4.0 * math.log(100 / 40)
    assert over[0] == pytest.approx(expected, abs=0.05)
    before = [h for h in history if h[0] < over[0]]
    assert before[-1][3] < 85.0
    assert over[2] is False and 84.9 < over[3] <= 85.0  # tripped at 85, cooling since
    assert all(h[1] == AlarmFlag.STALLED and h[2] for h in before)
    assert all(a[3] < b[3] for a, b in pairwise(before))  # heating all along
    # Unloaded it cools; 1 C below the limit it reloads and holds where it is, not pushing.
    assert back[2] is True and back[3] <= 84.0
    assert back[0] - over[0] == pytest.approx(4.0 * math.log(60 / 59), abs=0.01)
    assert pos(s, history[-1][0]) == 600
    assert faults(s) == AlarmFlag.NONE
    assert s.temperature_c < back[3]


def test_stall_with_default_params_trips_in_tens_of_seconds() -> None:
    s = _stall_scenario(ServoParams())
    s.advance(20.0)
    assert faults(s) == AlarmFlag.STALLED
    assert 60 < temp_read(s, 20.0) < 85
    s.advance(37.0)
    assert faults(s) == AlarmFlag.OVER_TEMPERATURE
    assert not s.is_loaded


def test_one_large_step_equals_many_small_ones() -> None:
    coarse = _stall_scenario(FAST_HEAT)
    fine = _stall_scenario(FAST_HEAT)
    coarse.advance(30.0)
    for k in range(1, 30001):
        fine.advance(k * 0.001)
    assert coarse.temperature_c == pytest.approx(fine.temperature_c, abs=1e-6)
    assert faults(coarse) == faults(fine) == AlarmFlag.NONE
    assert coarse.is_loaded and fine.is_loaded
    assert coarse.position_pulses == fine.position_pulses == 600.0


def test_external_effort_heats_a_holding_servo() -> None:
    s = SimServo(1, params=FAST_HEAT)
    do(s, C.MOVE_TIME_WRITE, 500, 0, now=0.0)
    s.external_effort = 0.9
    s.advance(100.0)
    # Trips, cools, reloads, trips again: it cycles just under the limit.
    assert 83.0 <= s.temperature_c <= 85.0
    s.external_effort = 0.0
    s.advance(200.0)
    assert s.temperature_c == pytest.approx(27.0, abs=0.01)  # holding effort 0.02
    assert s.is_loaded


# ---------------------------------------------------------------------------- obstacles, hands


def test_obstacle_stops_the_horn_and_removing_it_lets_the_move_finish() -> None:
    s = SimServo(1)
    s.set_obstacle(min_pulses=100, max_pulses=650)
    do(s, C.MOVE_TIME_WRITE, 800, 1000, now=0.0)
    assert pos(s, 0.4) == 620
    assert pos(s, 2.0) == 650
    s.set_obstacle()
    assert pos(s, 2.0) == 650  # no jump
    assert pos(s, 2.0 + 150 / MAX_SPEED) == 800
    assert faults(s) == AlarmFlag.NONE


def test_obstacle_placed_on_the_horn_pushes_it() -> None:
    s = SimServo(1)
    s.set_obstacle(min_pulses=550)
    assert s.position_pulses == 550.0
    with pytest.raises(ConfigError):
        s.set_obstacle(min_pulses=600, max_pulses=400)


def test_move_by_hand_only_when_unloaded() -> None:
    s = SimServo(1)
    s.move_by_hand(321.0, now=1.0)
    assert pos(s, 1.0) == 321
    do(s, C.MOVE_TIME_WRITE, 500, 0, now=2.0)
    with pytest.raises(ConfigError, match="loaded"):
        s.move_by_hand(400.0, now=3.0)
    do(s, C.LOAD_OR_UNLOAD_WRITE, 0, now=3.0)
    s.set_obstacle(max_pulses=700)
    s.move_by_hand(900.0, now=4.0)  # the obstacle stops the hand too
    assert pos(s, 4.0) == 700
    assert not s.is_loaded


def test_move_by_hand_counts_the_offset() -> None:
    s = SimServo(1)
    do(s, C.ANGLE_OFFSET_ADJUST, 25, now=0.0)
    s.move_by_hand(400.0, now=0.0)
    assert pos(s, 0.0) == 400
    assert s.physical_pulses == pytest.approx(425.0)


# ---------------------------------------------------------------------------- motor mode


def test_motor_mode_turns_continuously_and_reads_wrap() -> None:
    s = SimServo(1)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 1000, now=0.0)
    assert do(s, C.OR_MOTOR_MODE_READ, now=0.0) == ModeReply(ServoMode.MOTOR, 1000)
    assert loaded(s, 0.0)
    assert pos(s, 0.2) == round(500 + 0.2 * MOTOR_FULL)
    # 500 + 1250 = 1750 pulses: one turn (1500) past 250.
    assert pos(s, 1.0) == 250
    assert FULL_TURN_PULSES == 1500
    # Readings wrap into -250 .. 1249.
    readings = [pos(s, 1.0 + k * 0.01) for k in range(300)]
    assert min(readings) >= -250 and max(readings) <= 1249
    assert min(readings) < 0 and max(readings) > 1000


def test_motor_speed_sets_the_rate_and_sign() -> None:
    s = SimServo(1)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, -400, now=0.0)
    assert pos(s, 0.5) == round(500 - 0.4 * MOTOR_FULL * 0.5)


def test_move_stop_does_not_stop_motor_mode_but_speed_zero_does() -> None:
    s = SimServo(1)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 200, now=0.0)
    do(s, C.MOVE_STOP, now=0.4)
    assert pos(s, 0.8) == round(500 + 0.2 * MOTOR_FULL * 0.8)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 0, now=0.8)
    assert pos(s, 5.0) == 700
    assert do(s, C.OR_MOTOR_MODE_READ, now=5.0) == ModeReply(ServoMode.MOTOR, 0)


def test_moves_are_ignored_in_motor_mode() -> None:
    s = SimServo(1)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 0, now=0.0)
    do(s, C.MOVE_TIME_WRITE, 900, 0, now=0.0)
    assert pos(s, 1.0) == 500
    assert do(s, C.MOVE_TIME_READ, now=1.0) == MoveTimeReply(900, 0)


def test_back_to_position_mode_holds_the_wrapped_position() -> None:
    s = SimServo(1)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 1000, now=0.0)
    do(s, C.OR_MOTOR_MODE_WRITE, 0, 0, 0, now=1.0)
    assert do(s, C.OR_MOTOR_MODE_READ, now=1.0) == ModeReply(ServoMode.POSITION, 0)
    assert pos(s, 3.0) == 250
    assert loaded(s, 3.0)
    do(s, C.MOVE_TIME_WRITE, 500, 1000, now=3.0)
    assert pos(s, 3.5) == 375


def test_motor_mode_stalls_against_an_obstacle() -> None:
    s = SimServo(1)
    s.set_obstacle(max_pulses=600)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 500, now=0.0)
    contact_s = 100 / (0.5 * MOTOR_FULL)
    assert pos(s, contact_s + 0.1) == 600
    assert faults(s) == AlarmFlag.NONE
    s.advance(contact_s + 0.6)
    assert faults(s) == AlarmFlag.STALLED


def test_motor_mode_meets_a_single_stop_the_long_way_round() -> None:
    s = SimServo(1)
    s.set_obstacle(max_pulses=600)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, -1000, now=0.0)
    # Down from 500, through the wrap at -250, and down to 600 from above: 1400 pulses.
    assert pos(s, 1.0) == round(500 - MOTOR_FULL) + 1500
    assert pos(s, 2.0) == 600
    do(s, C.OR_MOTOR_MODE_WRITE, 0, 0, 0, now=2.0)
    do(s, C.MOVE_TIME_WRITE, 900, 0, now=2.0)  # above the stop, going up is free
    assert pos(s, 3.0) == 900


# ---------------------------------------------------------------------------- broadcast, storage


def test_broadcast_frames_apply_like_addressed_ones() -> None:
    a, b = SimServo(1), SimServo(2)
    for s in (a, b):
        s.handle(Request(BROADCAST_ID, C.MOVE_TIME_WRITE, (700, 1000)), 0.0)
    assert pos(a, 1.0) == pos(b, 1.0) == 700
    for s in (a, b):
        s.handle(Request(BROADCAST_ID, C.ID_WRITE, (9,)), 1.0)
    assert a.servo_id == b.servo_id == 9  # the costly mistake the field notes warn of
    # handle() answers reads whatever the ID; the bus decides what goes on the wire.
    assert a.handle(Request(BROADCAST_ID, C.ID_READ), 1.0) == IdReply(9)


def test_from_stored_restores_saved_fields_only() -> None:
    s = SimServo(3)
    do(s, C.ANGLE_LIMIT_WRITE, 50, 950, now=0.0)
    do(s, C.ANGLE_OFFSET_ADJUST, 20, now=0.0)
    do(s, C.ANGLE_OFFSET_WRITE, now=0.0)
    do(s, C.ANGLE_OFFSET_ADJUST, -40, now=0.0)
    do(s, C.LED_ERROR_WRITE, 1, now=0.0)
    do(s, C.OR_MOTOR_MODE_WRITE, 1, 0, 300, now=0.0)
    t = SimServo.from_stored(s.stored_fields(), position_pulses=520.0, now=5.0)
    assert t.servo_id == 3
    assert t.stored_fields() == s.stored_fields()
    assert do(t, C.ANGLE_OFFSET_READ, now=5.0) == AngleOffsetReply(20)
    assert pos(t, 5.0) == 500  # physical 520 minus the saved offset
    assert do(t, C.LED_ERROR_READ, now=5.0) == LedErrorReply(AlarmFlag(7))
    assert do(t, C.OR_MOTOR_MODE_READ, now=5.0) == ModeReply(ServoMode.POSITION, 0)
    assert not loaded(t, 5.0)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"id": 254}, "id"),
        ({"offset_pulses": 1.5}, "offset_pulses"),
        ({"min_pulses": 900, "max_pulses": 100}, "min_pulses"),
        ({"temp_max_c": True}, "temp_max_c"),
        ({"colour": 1}, "unknown"),
    ],
)
def test_from_stored_rejects_bad_fields(change: dict[str, float], match: str) -> None:
    stored: dict[str, float] = {**SimServo(1).stored_fields(), **change}
    with pytest.raises(ConfigError, match=match):
        SimServo.from_stored(stored)


def test_from_stored_rejects_missing_fields() -> None:
    stored = SimServo(1).stored_fields()
    del stored["max_mv"]
    with pytest.raises(ConfigError, match="max_mv"):
        SimServo.from_stored(stored)


def test_bad_construction_is_a_config_error() -> None:
    with pytest.raises(ConfigError):
        SimServo(254)
    with pytest.raises(ConfigError):
        SimServo(1, position_pulses=float("nan"))
    with pytest.raises(ConfigError):
        ServoParams(max_speed_s_per_60deg=0.0)
    with pytest.raises(ConfigError):
        ServoParams(effort_moving=1.5)
    with pytest.raises(ConfigError):
        ServoParams(over_temp_hysteresis_c=0.0)
    s = SimServo(1)
    with pytest.raises(ConfigError):
        s.supply_mv = -1
    with pytest.raises(ConfigError):
        s.external_effort = 2.0


# ---------------------------------------------------------------------------- property


_move_requests: st.SearchStrategy[tuple[Command, tuple[int, ...]]] = st.one_of(
    st.tuples(
        st.sampled_from([C.MOVE_TIME_WRITE, C.MOVE_TIME_WAIT_WRITE]),
        st.tuples(st.integers(0, 1000), st.integers(0, 30000)),
    ),
    st.tuples(st.sampled_from([C.MOVE_START, C.MOVE_STOP]), st.just(())),
)


@settings(max_examples=200, deadline=None)
@given(
    limits=st.tuples(st.integers(0, 1000), st.integers(0, 1000)).filter(lambda p: p[0] < p[1]),
    start=st.floats(0.0, 1.0),
    steps=st.lists(
        st.tuples(_move_requests, st.floats(0.0, 3.0), st.integers(1, 4)), max_size=25
    ),
    broadcast=st.booleans(),
)
def test_position_stays_within_the_angle_limits(
    limits: tuple[int, int],
    start: float,
    steps: list[tuple[tuple[Command, tuple[int, ...]], float, int]],
    broadcast: bool,
) -> None:
    lo, hi = limits
    s = SimServo(1, position_pulses=lo + start * (hi - lo))
    sid = BROADCAST_ID if broadcast else 1
    s.handle(Request(sid, C.ANGLE_LIMIT_WRITE, (lo, hi)), 0.0)
    now = 0.0
    for (command, args), dt, reads in steps:
        s.handle(Request(sid, command, args), now)
        # Read a few times while the move runs, not only at its end.
        for _ in range(reads):
            now += dt / reads
            p = pos(s, now)
            assert lo <= p <= hi
            assert 0 <= p <= 1000
            assert lo - 1e-6 <= s.position_pulses <= hi + 1e-6
