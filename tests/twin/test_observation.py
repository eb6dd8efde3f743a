"""One observation and one action (busarm.robot.observation), judged by the twin's ground
truth (``robot.twin``), not by what the code reports of itself; on the simulated clock."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from busarm import Action, CameraSpec, ConfigError, Observation, Robot, RobotConfig, Twist
from busarm.base.odometry import Pose2D
from busarm.protocol import Command

ARENA = "board://twin?family=arena&seed=3"
TABLE = "twin://?blocks=0"
WRITES = {c for c in Command if c.name.endswith("_WRITE")}


def _open(port: str) -> Robot:
    """The robot on ``port`` without a camera calibration: made in the twin it costs
    seconds, and nothing here looks for blocks."""
    return Robot.open(RobotConfig.from_port(port, camera=CameraSpec(calibrate=False)))


@pytest.fixture
def arena() -> Iterator[Robot]:
    with _open(ARENA) as robot:
        yield robot


@pytest.fixture
def table() -> Iterator[Robot]:
    with _open(TABLE) as robot:
        yield robot


def _true_pose(robot: Robot) -> Pose2D:
    twin = robot.twin
    assert twin is not None and twin.mobile is not None
    with twin.lock:
        return twin.mobile.pose(twin.data)


def _rad(joints_deg: tuple[float, ...] | list[float], robot: Robot) -> dict[str, float]:
    return {j.name: math.radians(a) for j, a in zip(robot.config.joints, joints_deg,
                                                     strict=True)}


def test_an_observation_has_every_part_each_stamped_on_the_robots_clock(
        arena: Robot) -> None:
    twin = arena.twin
    assert twin is not None
    first = arena.get_observation()
    assert list(first.joints_rad) == [j.name for j in arena.config.joints]
    np.testing.assert_allclose(np.degrees(list(first.joints_rad.values())),
                               twin.joints_deg(), atol=0.5)  # the servos' whole pulses
    assert first.gripper_gap_mm == pytest.approx(twin.finger_gap_mm(), abs=1.0)
    assert first.base is not None and first.scan is not None and len(first.scan) > 100
    assert sorted(first.frames) == ["overview", "wrist"]
    assert first.frames["wrist"].image.shape == (480, 640, 3)
    # Each part's stamp is the robot's clock as it was read: the scan's revolution began
    # at most one revolution (0.2 s at the A1's slowest) before the reading.
    after = arena.clock.now()
    stamps = first.stamps
    assert set(stamps) == {"arm", "base", "scan", "camera.wrist", "camera.overview"}
    assert all(first.t_s <= t <= after for k, t in stamps.items() if k != "scan")
    assert first.t_s - 0.2 <= stamps["scan"] <= after
    arena.clock.sleep(0.5)
    second = arena.get_observation()
    assert all(second.stamps[k] - stamps[k] >= 0.4 for k in stamps), (stamps, second.stamps)
    assert second.frames["wrist"].sequence == first.frames["wrist"].sequence + 1
    text = repr(second)
    assert text.startswith(f"Observation(t={second.t_s:.3f} s, 5 joints, gripper ")
    assert "scan " in text and "cameras ['overview', 'wrist']" in text
    assert len(text) < 140 and "array" not in text


def test_the_caller_chooses_the_parts(arena: Robot) -> None:
    wrist = arena.cameras["wrist"]
    before = wrist.read().sequence
    start = arena.clock.now()
    light = arena.get_observation(cameras=False, scan=False)
    assert light.frames == {} and light.scan is None and light.base is not None
    assert wrist.read().sequence == before + 1  # not read by the observation
    assert arena.clock.now() - start < 0.05  # no revolution waited for
    assert sorted(arena.get_observation(cameras=["wrist"], scan=False).frames) == ["wrist"]
    assert sorted(arena.get_observation(cameras="overview", scan=False).frames) == [
        "overview"]
    with pytest.raises(ConfigError, match="no camera front on this robot; its cameras: "
                                          "wrist, overview"):
        arena.get_observation(cameras=["front"])


def test_a_table_twin_has_no_base_or_scan(table: Robot) -> None:
    seen = table.get_observation(cameras=False)
    assert seen.base is None and seen.scan is None
    assert set(seen.stamps) == {"arm"}
    assert "base" not in repr(seen) and "base.x" not in seen.as_dict()


def test_joint_targets_and_a_gripper_gap_move_the_twin(table: Robot) -> None:
    twin = table.twin
    assert twin is not None
    target = [20.0, -60.0, 70.0, -80.0, 30.0]
    sent = table.send_action(Action(joints_rad=_rad(target, table), gripper_gap_mm=40.0,
                                    duration_s=1.2))
    assert sent.duration_s == 1.2 and sent.gripper_gap_mm == 40.0
    table.clock.sleep(0.3)
    # On its way, not there: the move takes the time it was given.
    assert abs(twin.joints_deg()[0] - target[0]) > 5.0
    table.clock.sleep(1.2)
    np.testing.assert_allclose(twin.joints_deg(), target, atol=1.0)
    assert twin.finger_gap_mm() == pytest.approx(40.0, abs=1.5)
    seen = table.get_observation(cameras=False)
    np.testing.assert_allclose(list(seen.joints_rad.values()),
                               list(_rad(target, table).values()), atol=math.radians(1.0))


def test_a_base_twist_drives_the_twin_and_the_odometry_agrees(arena: Robot) -> None:
    start_truth = _true_pose(arena)
    start = arena.get_observation(cameras=False, scan=False)
    assert start.base is not None
    for _ in range(40):  # a velocity command, repeated as its watchdog asks: 1 s
        arena.send_action({"base.vx": 0.2})
        arena.clock.sleep(0.025)
    arena.send_action(Action(base=Twist()))
    arena.clock.sleep(0.5)
    truth = _true_pose(arena)
    moved = math.hypot(truth.x_m - start_truth.x_m, truth.y_m - start_truth.y_m)
    heading = math.atan2(truth.y_m - start_truth.y_m, truth.x_m - start_truth.x_m)
    assert 0.15 < moved < 0.3, moved
    assert abs(math.remainder(heading - start_truth.yaw_rad, math.tau)) < 0.1  # forward
    end = arena.get_observation(cameras=False, scan=False)
    assert end.base is not None
    odometry = end.base.pose.relative_to(start.base.pose)
    assert odometry.x_m == pytest.approx(moved, abs=0.02)


def _bad_actions(robot: Robot) -> list[tuple[str, dict[str, float]]]:
    """(what the error says, as a pattern; an action with one value beyond its limit and
    the rest valid): the arm, the gripper and the base would all move if any were sent."""
    shoulder = robot.config.joint("shoulder_pitch")
    here = robot.get_observation(cameras=False, scan=False)
    good: dict[str, float] = {f"{n}.pos": r for n, r in here.joints_rad.items()}
    good["base_yaw.pos"] += 0.3
    good.update({"gripper.gap_mm": 20.0, "duration_s": 1.0, "base.vx": 0.2})
    cases = [
        (r"shoulder_pitch\.pos = [0-9.]+ rad is out of range -3\.14159[0-9]*\.\.0\.5235[0-9]* "
         r"rad \(-180\.\.30 deg\)", {"shoulder_pitch.pos": math.radians(shoulder.max_deg)
                                       + 0.01}),
        (r"wrist_roll\.pos = -2\.2 rad is out of range", {"wrist_roll.pos": -2.2}),
        (r"gripper\.gap_mm = 94\.0 mm is out of range 0\.\.93\.75 mm",
         {"gripper.gap_mm": 94.0}),
        (r"gripper\.gap_mm = -1\.0 mm is out of range", {"gripper.gap_mm": -1.0}),
        (r"duration_s = 31\.0 s is out of range 0\.\.30 s", {"duration_s": 31.0}),
        (r"base\.vx = 0\.41 m/s is out of range -0\.4\.\.0\.4 m/s", {"base.vx": 0.41}),
        (r"base\.vy = -0\.5 m/s is out of range", {"base.vy": -0.5}),
        (r"base\.wz = 2\.2 rad/s is out of range .* \(120 deg/s either way\)",
         {"base.wz": 2.2}),
        (r"base\.wz must be a number, got nan", {"base.wz": math.nan}),
        (r"base\.vx, base\.vy, base\.wz: .* together need a wheel at",
         {"base.vx": 0.3, "base.vy": 0.3}),
        # Too fast from where the arm is: found before the arm's move, the first sent.
        (r"base_yaw would turn 17\.2 deg in 0\.01 s, faster than its 180 deg/s limit",
         {"duration_s": 0.01}),
    ]
    return [(words, {**good, **change}) for words, change in cases]


def test_every_value_beyond_its_limit_is_refused_and_nothing_moves(arena: Robot) -> None:
    twin, base = arena.twin, arena.base
    assert twin is not None and base is not None
    writes: list[Command] = []
    twin.bus.taps.append(lambda r: writes.append(r.command) if r.command in WRITES else None)
    joints, gap, pose = twin.joints_deg(), twin.finger_gap_mm(), _true_pose(arena)
    for words, action in _bad_actions(arena):
        with pytest.raises(ConfigError, match=words):
            arena.send_action(action)
        assert base.command == Twist(), words
    arena.clock.sleep(0.5)
    assert writes == []
    np.testing.assert_allclose(twin.joints_deg(), joints, atol=0.2)
    assert twin.finger_gap_mm() == pytest.approx(gap, abs=0.2)
    after = _true_pose(arena)
    assert math.hypot(after.x_m - pose.x_m, after.y_m - pose.y_m) < 0.002
    assert set(base.link.wheel_targets_rev_s.values()) <= {0.0}
    # The same action with that one value within its limit is sent, all of it.
    _, action = _bad_actions(arena)[0]
    action["shoulder_pitch.pos"] = arena.get_observation(cameras=False).joints_rad[
        "shoulder_pitch"]
    arena.send_action(action)
    assert Command.MOVE_TIME_WRITE in writes
    assert base.command.vx_m_s > 0


@pytest.mark.parametrize("action, words", [
    ({"shoulder_pich.pos": 0.1}, "shoulder_pich.pos: JetAuto Pro arm has no such joint; "
                                 "its joints: base_yaw, shoulder_pitch"),
    ({"shoulder_pitch.pos": -1.0}, "every joint or none: base_yaw.pos, elbow_pitch.pos, "
                                   "wrist_pitch.pos, wrist_roll.pos missing"),
    ({"speed": 1.0}, "action keys 'speed' are not known; allowed: JOINT.pos"),
    ({}, "the action has nothing to do"),
    ({"duration_s": 1.0, "gripper.gap_mm": 10.0}, "duration_s is the joints' move time"),
])
def test_a_malformed_action_is_one_clear_error(table: Robot, action: dict[str, float],
                                                 words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        table.send_action(action)


def test_base_keys_on_a_robot_without_a_base_are_refused(table: Robot) -> None:
    with pytest.raises(ConfigError, match="base.vx, base.vy, base.wz: this robot has no "
                                          "base"):
        table.send_action({"base.vx": 0.1})


def test_the_flat_form_round_trips(arena: Robot) -> None:
    seen = arena.get_observation()
    flat = seen.as_dict()
    assert flat["shoulder_pitch.pos"] == seen.joints_rad["shoulder_pitch"]
    assert seen.base is not None and seen.scan is not None
    assert (flat["base.x"], flat["base.y"], flat["base.yaw"]) == (
        seen.base.pose.x_m, seen.base.pose.y_m, seen.base.pose.yaw_rad)
    assert flat["base.wz"] == seen.base.twist.wz_rad_s
    assert flat["lidar.ranges"] is seen.scan.ranges_m
    assert flat["wrist"] is seen.frames["wrist"].image
    rgb = seen.as_dict(rgb=True)["wrist"]
    assert isinstance(rgb, np.ndarray)
    np.testing.assert_array_equal(rgb[..., 0], seen.frames["wrist"].image[..., 2])
    # An observation's arm keys are an action's: hold still where it is.
    keys = [k for k in flat if k.endswith(".pos") or k == "gripper.gap_mm"]
    hold = Action.from_dict({k: float(flat[k]) for k in keys})
    assert hold.joints_rad == seen.joints_rad and hold.gripper_gap_mm == seen.gripper_gap_mm
    sent = arena.send_action(hold)
    assert Action.from_dict(sent.as_dict()) == sent
    full = Action(dict(seen.joints_rad), 12.5, 2.0, Twist(0.1, -0.05, 0.3))
    assert Action.from_dict(full.as_dict()) == full
    assert full.as_dict()["base.wz"] == 0.3 and full.as_dict()["duration_s"] == 2.0
    assert Action.from_dict({"base.vy": 0.1}).base == Twist(0.0, 0.1, 0.0)


def test_the_robot_moves_to_a_named_pose(table: Robot) -> None:
    twin = table.twin
    assert twin is not None
    took_s = table.move_to_pose("home")
    assert took_s > 0
    np.testing.assert_allclose(twin.joints_deg(), table.config.pose("home"), atol=1.5)
    with pytest.raises(ConfigError, match="no pose named 'dance'"):
        table.move_to_pose("dance")


def test_observing_in_a_loop_moves_the_clock_only_by_what_it_waits_for(
        arena: Robot) -> None:
    reads: list[Callable[[], Observation]] = [
        lambda: arena.get_observation(cameras=False, scan=False),
        lambda: arena.get_observation(cameras=False)]
    for read, most_s in zip(reads, (0.05, 0.25), strict=True):
        start = arena.clock.now()
        for _ in range(5):
            read()
        # Servo reads take their wire time; a scan waits for the next revolution.
        assert arena.clock.now() - start < 5 * most_s
